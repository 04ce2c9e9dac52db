#include <mgcloth/core/file_io.hpp>
#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/mesh/pattern.hpp>
#include <mgcloth/sim/gltf_skin.hpp>
#include <mgcloth/sim/scene.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth::sim {

namespace fs = std::filesystem;

namespace {

using geometry::euler_xyz_deg;

physics::Material parse_material(JsonReader r, std::string& preset) {
  preset = r.choice("preset", "cotton", material_presets());
  physics::Material m = material_preset(preset);
  m.youngs_modulus = r.number("youngs_modulus", m.youngs_modulus, 1.0, 1e12);
  m.poisson_ratio = r.number("poisson_ratio", m.poisson_ratio, 0.0, 0.499);
  m.thickness = r.number("thickness", m.thickness, 1e-6, 0.1);
  m.density = r.number("density", m.density, 1e-3, 1e5);
  m.bending_stiffness = r.number("bending_stiffness", m.bending_stiffness, 0.0, 1e3);
  const auto membrane = r.choice("membrane", physics::to_string(m.membrane), {"stvk", "mass_spring"});
  m.membrane = membrane == "stvk" ? physics::MembraneModel::StVK : physics::MembraneModel::MassSpring;
  const auto bending =
      r.choice("bending", physics::to_string(m.bending), {"hinge", "quadratic", "quadratic-bergou", "none"});
  m.bending = bending == "hinge"              ? physics::BendingModel::Hinge
              : bending == "quadratic"        ? physics::BendingModel::Quadratic
              : bending == "quadratic-bergou" ? physics::BendingModel::QuadraticBergou
                                              : physics::BendingModel::None;
  m.pd_strain_min = r.number("pd_strain_min", m.pd_strain_min, 0.0, 1.0);
  m.pd_strain_max = r.number("pd_strain_max", m.pd_strain_max, 1.0, 100.0);
  r.finish();
  return m;
}

/// cloth_contact.friction_pairs: per unordered pair of the scene's cloths (a cloth with itself too), its own μ.
std::vector<physics::ClothFrictionPair> parse_friction_pairs(JsonReader& contact,
                                                             const std::vector<ClothSpec>& cloths) {
  std::vector<physics::ClothFrictionPair> out;
  const auto entries = contact.objects("friction_pairs");
  for (size_t i = 0; i < entries.size(); ++i) {
    JsonReader r = entries[i];
    const Json& names = r.raw("cloths");
    if (!names.is_array() || names.size() != 2 || !names[0].is_string() || !names[1].is_string())
      r.fail("cloths", fmt::format("expected two cloth names, got {}", names.dump()));
    physics::ClothFrictionPair p;
    p.a = names[0].get<std::string>();
    p.b = names[1].get<std::string>();
    for (int k = 0; k < 2; ++k) {
      const std::string& n = k == 0 ? p.a : p.b;
      if (std::none_of(cloths.begin(), cloths.end(), [&](const ClothSpec& c) { return c.name == n; })) {
        std::vector<std::string> known;
        for (const auto& c : cloths) known.push_back(fmt::format("\"{}\"", c.name));
        r.fail(fmt::format("cloths[{}]", k),
               known.empty() ? fmt::format("no cloth is named \"{}\" (the scene has no cloths)", n)
                             : fmt::format("no cloth is named \"{}\" (the cloths: {})", n, fmt::join(known, ", ")));
      }
    }
    p.friction = r.required_number("friction", 0.0, 10.0);
    for (size_t j = 0; j < out.size(); ++j)
      if ((out[j].a == p.a && out[j].b == p.b) || (out[j].a == p.b && out[j].b == p.a))
        r.fail("cloths", fmt::format("the pair \"{}\", \"{}\" is given twice (also friction_pairs[{}])", p.a, p.b, j));
    r.finish();
    out.push_back(std::move(p));
  }
  return out;
}

MeshSource parse_mesh(JsonReader r, const fs::path& base) {
  MeshSource s;
  if (r.has("file")) {
    const std::string f = r.required_string("file");
    // Absolute, so that the resolved scene and a --resume work from any working directory.
    s.file = fs::absolute(fs::path(f).is_absolute() ? fs::path(f) : base / f).lexically_normal().string();
    s.material_scale = r.number("material_scale", 1.0, 1e-9, 1e9);
  } else if (r.has("pattern")) {
    const std::string f = r.required_string("pattern");
    s.pattern = fs::absolute(fs::path(f).is_absolute() ? fs::path(f) : base / f).lexically_normal().string();
    s.pattern_resolution = r.number("resolution", s.pattern_resolution, 1e-3, 1.0);
    try {
      mesh::read_pattern(s.pattern);  // its errors now, naming the key; the mesh is made with the body
    } catch (const InputError& e) {
      r.fail("pattern", e.what());
    }
  } else {
    s.generator = r.choice("generator", "rectangle", {"rectangle", "tube"});
    if (s.generator == "tube") {
      auto& tube = s.tube;
      tube.circumference = r.number("circumference", tube.circumference, 1e-4, 1e3);
      tube.height = r.number("height", tube.height, 1e-4, 1e3);
      tube.target_vertices = r.integer("vertices", tube.target_vertices, 8, mesh::kMaxGeneratedVertices);
      tube.unstructured = r.boolean("unstructured", tube.unstructured);
      tube.seed = static_cast<std::uint64_t>(r.integer("seed", static_cast<int>(tube.seed), 0));
      r.finish();
      return s;
    }
    auto& rect = s.rectangle;
    rect.width = r.number("width", rect.width, 1e-4, 1e3);
    rect.height = r.number("height", rect.height, 1e-4, 1e3);
    rect.target_vertices = r.integer("vertices", rect.target_vertices, 4, mesh::kMaxGeneratedVertices);
    rect.unstructured = r.boolean("unstructured", rect.unstructured);
    rect.seed = static_cast<std::uint64_t>(r.integer("seed", static_cast<int>(rect.seed), 0));
    for (auto h : r.objects("holes")) {
      mesh::CircleHole hole;
      hole.center = h.vec2("center", hole.center);
      hole.radius = h.required_number("radius", 1e-6, 1e3);
      h.finish();
      rect.holes.push_back(hole);
    }
    if (!rect.holes.empty() && !rect.unstructured) r.fail("holes", "holes need \"unstructured\": true");
  }
  r.finish();
  return s;
}

/// The "keys" of a keyframe motion: their times (at least one, strictly increasing), and each key's own fields
/// read by `read_key`.
template <class ReadKey>
std::vector<double> parse_keys(JsonReader& motion, ReadKey&& read_key) {
  std::vector<double> times;
  for (auto& k : motion.objects("keys")) {
    times.push_back(k.required_number("time", 0.0));
    read_key(k);
    k.finish();
  }
  if (times.empty()) motion.fail("keys", "keyframe motion needs at least one key");
  for (size_t i = 1; i < times.size(); ++i)
    if (!(times[i] > times[i - 1])) motion.fail(fmt::format("keys[{}].time", i), "key times must increase");
  return times;
}

PinSpec parse_pin(JsonReader r) {
  PinSpec p;
  if (r.has("vertices")) {
    for (int v : r.integers("vertices")) p.vertices.push_back(v);
  }
  if (r.has("points")) {
    const Json& pts = r.raw("points");
    if (!pts.is_array()) r.fail("points", "expected an array of [u, v] material coordinates");
    for (size_t i = 0; i < pts.size(); ++i) {
      if (!pts[i].is_array() || pts[i].size() != 2 || !pts[i][0].is_number() || !pts[i][1].is_number())
        r.fail(fmt::format("points[{}]", i), "expected [u, v] (two numbers)");
      p.points.emplace_back(pts[i][0].get<double>(), pts[i][1].get<double>());
    }
  }
  if (auto box = r.optional_object("region")) {
    const Vec2 lo = box->vec2("min", Vec2::Zero()), hi = box->vec2("max", Vec2::Zero());
    if (!(lo.array() <= hi.array()).all()) box->fail("max", "must be >= min in both coordinates");
    box->finish();
    p.region = std::make_pair(lo, hi);
  }
  if (p.vertices.empty() && p.points.empty() && !p.region)
    r.fail("vertices", "a pin needs \"vertices\", \"points\" or \"region\"");
  p.stiffness = r.number("stiffness", p.stiffness, 1e-6, 1e12);
  if (auto m = r.optional_object("motion")) {
    p.motion = m->choice("type", "none", {"none", "constant_velocity", "keyframes", "rotation"});
    if (p.motion == "constant_velocity" || p.motion == "rotation") p.velocity = m->vec3("velocity", Vec3::Zero());
    if (p.motion == "rotation") {
      p.axis = m->vec3("axis", p.axis);
      if (!(p.axis.norm() > 0.0)) m->fail("axis", "must not be zero");
      p.center = m->vec3("center", p.center);
      p.angular_velocity = m->number("angular_velocity", 0.0, -1e4, 1e4);
      p.duration = m->number("duration", 1e30, 0.0);
    }
    if (p.motion == "keyframes") {
      p.key_times = parse_keys(*m, [&](JsonReader& k) { p.key_offsets.push_back(k.vec3("offset", Vec3::Zero())); });
    }
    m->finish();
  }
  r.finish();
  return p;
}

ClothSpec parse_cloth(JsonReader r, const fs::path& base, size_t index) {
  ClothSpec c;
  c.name = r.name("name", fmt::format("cloth{}", index));
  c.mesh = parse_mesh(r.object("mesh"), base);
  if (auto t = r.optional_object("transform")) {
    c.transform.translation = t->vec3("translation", Vec3::Zero());
    c.transform.rotation_deg = t->vec3("rotation_deg", Vec3::Zero());
    t->finish();
  }
  if (auto m = r.optional_object("material")) {
    c.material = parse_material(*m, c.preset);
  } else {
    c.material = material_preset(c.preset);
  }
  for (auto& p : r.objects("pins")) c.pins.push_back(parse_pin(p));
  c.initial_velocity = r.vec3("initial_velocity", Vec3::Zero());
  c.seam_stiffness = r.number("seam_stiffness", 100.0 * c.material.youngs_modulus * c.material.thickness, 1e-6, 1e12);
  c.contact_thickness = r.number("contact_thickness", 0.0, 0.0, 1.0);
  r.finish();
  return c;
}

/// The file names of a mesh sequence: a pattern with one printf-style integer field, %d or %0Nd (N < 10).
struct SequencePattern {
  std::string before, after;
  int width = 0;  ///< zero-padded to this many digits
  std::string file(long k) const {
    std::string digits = std::to_string(k);
    if (static_cast<int>(digits.size()) < width) digits.insert(0, static_cast<size_t>(width) - digits.size(), '0');
    return before + digits + after;
  }
};

/// The pattern of `name`, nullopt for a plain file name; an error message where a '%' is not such a field.
std::optional<SequencePattern> sequence_pattern(const std::string& name, std::string& error) {
  const size_t p = name.find('%');
  if (p == std::string::npos) return std::nullopt;
  SequencePattern out;
  out.before = name.substr(0, p);
  size_t q = p + 1;
  if (q < name.size() && name[q] == '0' && q + 2 < name.size() && name[q + 1] >= '1' && name[q + 1] <= '9') {
    out.width = name[q + 1] - '0';
    q += 2;
  }
  if (q >= name.size() || name[q] != 'd' || name.find('%', q) != std::string::npos) {
    error = fmt::format("\"{}\": a sequence of files names its frame number with one %d or %0Nd (as frame_%04d.obj)",
                        name);
    return std::nullopt;
  }
  out.after = name.substr(q + 1);
  return out;
}

/// A mesh obstacle's surface: one OBJ, or a sequence of them with one topology (frames from `first` up to the first
/// number without a file).
std::shared_ptr<const geometry::TriangleSurface> read_obstacle_mesh(JsonReader& r, ObstacleSpec& o) {
  const std::string ext = fs::path(o.mesh).extension().string();
  if (ext == ".glb" || ext == ".gltf") {
    o.gltf_mesh = r.string("gltf_mesh", "");
    o.gltf_animation = r.string("gltf_animation", "");
    o.gltf_y_up = r.boolean("gltf_y_up", true);
    o.mesh_loop = r.boolean("mesh_loop", false);
    auto surface = std::make_shared<geometry::TriangleSurface>();
    try {
      SkinReadOptions opt;
      opt.mesh = o.gltf_mesh;
      opt.animation = o.gltf_animation;
      opt.y_up = o.gltf_y_up;
      auto skin = std::make_shared<geometry::SkinnedMesh>(read_skinned_gltf(o.mesh, opt));
      surface->vertices = skin->at(0.0);
      surface->tris = skin->tris;
      surface->skin = std::move(skin);
      surface->loop = o.mesh_loop;
    } catch (const Error& e) {
      r.fail("mesh", e.what());
    }
    return surface;
  }
  std::string error;
  const auto pattern = sequence_pattern(o.mesh, error);
  if (!error.empty()) r.fail("mesh", error);
  auto surface = std::make_shared<geometry::TriangleSurface>();
  if (pattern) {
    o.mesh_rate = r.required_number("mesh_rate", 1e-6, 1e6);
    o.mesh_loop = r.boolean("mesh_loop", false);
    o.mesh_first = r.integer("mesh_first", fs::exists(pattern->file(0)) ? 0 : 1, 0, 1'000'000'000);
  }
  try {
    if (!pattern) {
      mesh::Surface read = mesh::read_obj_surface(o.mesh);
      surface->vertices = std::move(read.x);
      surface->tris = std::move(read.tris);
      return surface;
    }
    for (long k = o.mesh_first; fs::exists(pattern->file(k)); ++k) {
      const std::string file = pattern->file(k);
      mesh::Surface read = mesh::read_obj_surface(file);
      if (surface->frames.empty()) {
        surface->vertices = read.x;
        surface->tris = read.tris;
      } else if (read.x.cols() != surface->vertices.cols() || read.tris != surface->tris) {
        throw InputError(fmt::format("{}: {} vertices and {} faces, the sequence's first frame ({}) has {} and {} in "
                                     "another order or number: a sequence keeps one topology (faces of zero area "
                                     "in one frame are dropped and change it too)",
                                     file, read.x.cols(), read.tris.size(), pattern->file(o.mesh_first),
                                     surface->vertices.cols(), surface->tris.size()));
      }
      surface->frames.push_back(std::move(read.x));
    }
    if (surface->frames.empty())
      throw InputError(fmt::format("{}: cannot open file (the sequence's first frame, mesh_first = {})",
                                   pattern->file(o.mesh_first), o.mesh_first));
    surface->rate = o.mesh_rate;
    surface->loop = o.mesh_loop;
  } catch (const InputError& e) {
    r.fail("mesh", e.what());
  }
  return surface;
}

/// The generated mannequin of an obstacle's "body" object (geometry/mannequin.hpp): it walks with "walk", else it
/// stands in its bind pose.
std::shared_ptr<const geometry::TriangleSurface> make_body(JsonReader b, ObstacleSpec& o) {
  auto& m = o.body;
  m.height = b.number("height", m.height, 1.2, 2.2);
  m.build = b.number("build", m.build, 0.7, 1.5);
  m.resolution = b.number("resolution", m.resolution, 0.003, 0.05);
  m.arm_abduction = b.number("arm_abduction", m.arm_abduction, 5.0, 60.0);
  auto& w = o.walk;
  if (auto wr = b.optional_object("walk")) {
    w.period = wr->number("period", w.period, 0.5, 3.0);
    w.stand = wr->number("stand", w.stand, 0.0, 1e4);
    w.ramp = wr->number("ramp", w.ramp, 0.0, 1e4);
    w.duration = wr->number("duration", w.duration, 0.0, 1e4);
    w.key_rate = wr->number("key_rate", w.key_rate, 1.0, 1000.0);
    w.forward = wr->boolean("forward", w.forward);
    w.arm_swing = wr->number("arm_swing", w.arm_swing, 0.0, 3.0);
    wr->finish();
  } else {
    w.duration = 0.0;  // no "walk": it stands
  }
  b.finish();
  auto surface = std::make_shared<geometry::TriangleSurface>();
  try {
    auto skin = std::make_shared<geometry::SkinnedMesh>(geometry::make_mannequin(m, w));
    surface->vertices = skin->at(0.0);
    surface->tris = skin->tris;
    surface->skin = std::move(skin);
  } catch (const Error& e) {
    b.fail("resolution", e.what());
  }
  return surface;
}

ObstacleSpec parse_obstacle(JsonReader r, const fs::path& base, size_t index) {
  ObstacleSpec o;
  o.name = r.name("name", fmt::format("obstacle{}", index));
  if (r.has("body")) {
    for (const char* other : {"shape", "mesh"})
      if (r.has(other)) r.fail(other, "an obstacle has one of \"shape\", \"mesh\" and \"body\"");
    o.shape = "body";
    o.contact_thickness = r.number("contact_thickness", 0.0, 0.0, 1.0);
    o.surface = make_body(r.object("body"), o);
  } else if (r.has("mesh")) {
    if (r.has("shape")) r.fail("shape", "an obstacle has a \"shape\" or a \"mesh\", not both");
    const std::string f = r.required_string("mesh");
    o.shape = "mesh";
    o.mesh = fs::absolute(fs::path(f).is_absolute() ? fs::path(f) : base / f).lexically_normal().string();
    o.contact_thickness = r.number("contact_thickness", 0.0, 0.0, 1.0);
    o.surface = read_obstacle_mesh(r, o);
  } else {
    JsonReader s = r.object("shape");
    o.shape = s.choice("type", "sphere", {"plane", "sphere", "box", "capsule"});
    if (o.shape == "sphere" || o.shape == "capsule") o.radius = s.required_number("radius", 1e-6, 1e4);
    if (o.shape == "capsule") o.half_length = s.number("half_length", o.half_length, 0.0, 1e4);
    if (o.shape == "box") {
      o.half_extents = s.vec3("half_extents", o.half_extents);
      if ((o.half_extents.array() <= 0.0).any()) s.fail("half_extents", "every half extent must be > 0");
    }
    s.finish();
  }
  o.position = r.vec3("position", Vec3::Zero());
  o.rotation_deg = r.vec3("rotation_deg", Vec3::Zero());
  o.friction = r.number("friction", 0.0, 0.0, 10.0);
  if (auto m = r.optional_object("motion")) {
    o.motion = m->choice("type", "static", {"static", "constant_velocity", "keyframes"});
    if (o.motion == "constant_velocity") {
      o.linear_velocity = m->vec3("linear_velocity", Vec3::Zero());
      o.angular_velocity = m->vec3("angular_velocity", Vec3::Zero());
    }
    if (o.motion == "keyframes") {
      o.key_times = parse_keys(*m, [&](JsonReader& k) {
        o.key_positions.push_back(k.vec3("position", o.position));
        o.key_rotations_deg.push_back(k.vec3("rotation_deg", o.rotation_deg));
      });
    }
    m->finish();
  }
  r.finish();
  return o;
}

}  // namespace

geometry::Obstacle ObstacleSpec::build() const {
  geometry::Obstacle ob;
  ob.name = name;
  ob.friction = friction;
  ob.mesh = surface;
  ob.contact_thickness = contact_thickness;
  if (shape == "plane") ob.shape = std::make_shared<geometry::Plane>();
  if (shape == "sphere") ob.shape = std::make_shared<geometry::Sphere>(radius);
  if (shape == "box") ob.shape = std::make_shared<geometry::Box>(half_extents);
  if (shape == "capsule") ob.shape = std::make_shared<geometry::Capsule>(radius, half_length);
  const geometry::Pose start{euler_xyz_deg(rotation_deg), position};
  if (motion == "keyframes") {
    std::vector<geometry::Keyframe> keys;
    for (size_t k = 0; k < key_times.size(); ++k)
      keys.push_back({key_times[k], geometry::Pose{euler_xyz_deg(key_rotations_deg[k]), key_positions[k]}});
    ob.motion = std::make_shared<geometry::KeyframedMotion>(std::move(keys));
  } else {
    const bool moving = motion == "constant_velocity";
    ob.motion = std::make_shared<geometry::ConstantVelocityMotion>(start, moving ? linear_velocity : Vec3::Zero(),
                                                                   moving ? angular_velocity : Vec3::Zero());
  }
  return ob;
}

std::vector<std::string> material_presets() { return {"cotton", "silk", "denim", "leather"}; }

physics::Material material_preset(const std::string& name) {
  physics::Material m;  // cotton: the documented defaults
  if (name == "silk") {
    m.youngs_modulus = 5.0e5;
    m.thickness = 2.0e-4;
    m.density = 400.0;  // 80 g/m²
    m.bending_stiffness = 5e-7;
  } else if (name == "denim") {
    m.youngs_modulus = 4.0e6;
    m.thickness = 8.0e-4;
    m.density = 500.0;  // 400 g/m²
    m.bending_stiffness = 5e-5;
  } else if (name == "leather") {
    m.youngs_modulus = 2.0e7;
    m.thickness = 1.2e-3;
    m.density = 800.0;
    m.bending_stiffness = 1e-3;
    m.poisson_ratio = 0.4;
  }
  return m;
}

Scene parse_scene(const Json& json, const std::string& file, const fs::path& base) {
  JsonReader r(json, file);
  Scene s;
  s.file = file;
  s.gravity = r.vec3("gravity", s.gravity);
  s.frame_time = r.number("time_step", s.frame_time, 1e-6, 10.0);
  s.substeps = r.integer("substeps", s.substeps, 1, 10000);
  s.frames = r.integer("frames", s.frames, 0, 10'000'000);
  s.threads = r.integer("threads", s.threads, 0, 1024);
  const std::string form = r.choice("energy_form", physics::energy_form_name(s.energy_form), physics::energy_form_names());
  s.energy_form = physics::energy_form_of(form);
  s.solve_jointly = r.choice("solve_bodies", "jointly", {"jointly", "separately"}) == "jointly";
  const auto cloths = r.objects("cloths");
  const auto shells = r.objects("shells");
  for (size_t i = 0; i < shells.size(); ++i) {
    s.shells.push_back(parse_shell(shells[i], base, i));
    for (size_t j = 0; j < i; ++j)
      if (s.shells[j].name == s.shells[i].name)
        shells[i].fail("name", fmt::format("duplicate shell name \"{}\" (also shells[{}])", s.shells[i].name, j));
  }
  // Shells minimize indefinite, badly conditioned energies: their default is the trust-region method.
  if (cloths.empty()) s.solver.name = "tr-dogleg";
  for (size_t i = 0; i < cloths.size(); ++i) {
    s.cloths.push_back(parse_cloth(cloths[i], base, i));
    for (size_t j = 0; j < i; ++j)
      if (s.cloths[j].name == s.cloths[i].name)
        cloths[i].fail("name", fmt::format("duplicate cloth name \"{}\" (also cloths[{}])", s.cloths[i].name, j));
  }
  const auto obstacles = r.objects("obstacles");
  for (size_t i = 0; i < obstacles.size(); ++i) {
    s.obstacles.push_back(parse_obstacle(obstacles[i], base, i));
    // Mesh obstacles are named in the cloth-contact term beside the cloths (friction looks them up by name).
    for (size_t j = 0; j < i; ++j)
      if (s.obstacles[j].name == s.obstacles[i].name)
        obstacles[i].fail("name", fmt::format("duplicate obstacle name \"{}\" (also obstacles[{}])", s.obstacles[i].name, j));
    if (s.obstacles[i].surface)
      for (size_t j = 0; j < s.cloths.size(); ++j)
        if (s.cloths[j].name == s.obstacles[i].name)
          obstacles[i].fail("name", fmt::format("obstacle \"{}\" has the name of cloths[{}]", s.obstacles[i].name, j));
  }
  if (auto c = r.optional_object("contact")) {
    s.contact.thickness = c->number("thickness", s.contact.thickness, 0.0, 1.0);
    s.contact.stiffness = c->number("stiffness", s.contact.stiffness, 0.0, 1e15);
    c->finish();
  }
  if (auto c = r.optional_object("cloth_contact")) {
    auto& cc = s.cloth_contact;
    cc.enabled = c->boolean("enabled", true);
    cc.thickness = c->number("thickness", cc.thickness, 1e-6, 1.0);
    cc.params.stiffness = c->number("stiffness", cc.params.stiffness, 1e-6, 1e15);
    cc.params.barrier_fraction = c->number("barrier_fraction", cc.params.barrier_fraction, 1e-3, 1.0);
    cc.params.ccd_separation = c->number("ccd_separation", cc.params.ccd_separation, 1e-3, 0.9);
    cc.check_intersections = c->boolean("check_intersections", cc.check_intersections);
    cc.friction.friction = c->number("friction", cc.friction.friction, 0.0, 10.0);
    cc.friction.static_velocity = c->number("static_friction_velocity", cc.friction.static_velocity, 1e-9, 10.0);
    cc.friction.pairs = parse_friction_pairs(*c, s.cloths);
    c->finish();
  }
  for (size_t i = 0; i < s.obstacles.size(); ++i)
    if (s.obstacles[i].surface && !s.cloth_contact.enabled)
      obstacles[i].fail(s.obstacles[i].shape == "body" ? "body" : "mesh", "a mesh obstacle touches the cloths through cloth contact, which is off in this scene: "
                                "add \"cloth_contact\": {} (every cloth then also collides with itself and the others)");
  if (auto so = r.optional_object("solver")) {
    s.solver.name = so->choice("name", s.solver.name, solvers::solver_names());
    s.solver.stop.rel_grad = so->number("rel_grad", s.solver.stop.rel_grad, 0.0, 1.0);
    s.solver.stop.abs_grad = so->number("abs_grad", s.solver.stop.abs_grad, 0.0);
    s.solver.velocity_tol = so->number("velocity_tol", s.solver.velocity_tol, 0.0);
    s.solver.velocity_rms_tol = so->number("velocity_rms_tol", s.solver.velocity_rms_tol, 0.0);
    s.solver.stop.max_iters = so->integer("max_iters", s.solver.stop.max_iters, 1, 1'000'000);
    s.solver.stop.max_seconds = so->number("max_seconds", 1e30, 0.0);
    if (so->has("params")) {
      s.solver.params = so->raw("params");
      if (!s.solver.params.is_object()) so->fail("params", "expected an object");
    }
    so->finish();
  }
  (void)solvers::resolved_params(s.solver, file, "solver.params");  // rejects unknown solver parameters now
  if (s.energy_form == physics::EnergyForm::Projective && !s.shells.empty())
    r.fail("energy_form", "shells have no projective form (the PD form is the cloths'); use \"elastic\"");
  {
    const auto solver = solvers::make_solver(s.solver, file, "solver.params");
    solvers::check_energy_form(*solver, s.energy_form, file);
    if (s.cloth_contact.enabled && !s.cloths.empty()) {
      if (!solver->supports_step_limits())
        r.fail("solver.name", fmt::format("solver \"{}\" does not keep its trial points intersection-free, which "
                                          "\"cloth_contact\" needs; choose one that does: {}",
                                          s.solver.name, fmt::join(solvers::step_limiting_solvers(), ", ")));
      if (!s.solve_jointly && s.cloths.size() > 1)
        r.fail("solve_bodies", "\"cloth_contact\" between cloths needs them solved together: \"solve_bodies\": \"jointly\"");
    }
  }
  if (auto h = r.optional_object("hierarchy")) {
    auto& p = s.hierarchy;
    p.ratio = h->number("ratio", p.ratio, 1.5, 16.0);
    p.min_coarse_vertices = h->integer("min_coarse_vertices", p.min_coarse_vertices, 3, 1'000'000);
    p.max_coarse_vertices = h->integer("max_coarse_vertices", p.max_coarse_vertices, 3, 1'000'000);
    if (p.max_coarse_vertices < p.min_coarse_vertices)
      h->fail("max_coarse_vertices", fmt::format("must be at least min_coarse_vertices ({})", p.min_coarse_vertices));
    p.seed = static_cast<std::uint64_t>(h->integer("seed", static_cast<int>(p.seed), 0));
    h->finish();
  }
  if (auto o = r.optional_object("output")) {
    s.output.dir = o->string("dir", s.output.dir);
    if (s.output.dir.empty()) o->fail("dir", "must not be empty (leave it out for the default \"out\")");
    s.output.every = o->integer("every", s.output.every, 1, 1'000'000);
    if (o->has("format")) {
      s.output.formats.clear();
      const Json& f = o->raw("format");
      if (f.is_string()) s.output.formats.push_back(f.get<std::string>());
      else if (f.is_array())
        for (const auto& x : f) s.output.formats.push_back(x.is_string() ? x.get<std::string>() : x.dump());
      else
        o->fail("format", "expected a format name or a list of them (available: obj, glb)");
      if (s.output.formats.empty()) o->fail("format", "needs at least one format (available: obj, glb)");
      for (size_t i = 0; i < s.output.formats.size(); ++i) {
        const auto& fm = s.output.formats[i];
        if (fm != "obj" && fm != "glb") o->fail("format", fmt::format("unknown format \"{}\" (available: obj, glb)", fm));
        if (std::find(s.output.formats.begin(), s.output.formats.begin() + i, fm) != s.output.formats.begin() + i)
          o->fail("format", fmt::format("format \"{}\" listed twice", fm));
      }
    }
    o->finish();
  }
  // After the unknown keys: with "cloths" misspelled, the misspelling is the error to report.
  r.finish();
  if (cloths.empty() && shells.empty()) r.fail("cloths", "a scene needs at least one cloth or shell");
  return s;
}

bodies::ClothEnvironment cloth_environment(const Scene& scene) {
  bodies::ClothEnvironment env;
  for (const auto& o : scene.obstacles) env.obstacles.push_back(o.build());
  env.contact = scene.contact;
  env.gravity = scene.gravity;
  env.energy_form = scene.energy_form;
  env.hierarchy = scene.hierarchy;
  return env;
}

Scene load_scene(const fs::path& path) {
  if (!fs::exists(path)) throw InputError(fmt::format("{}: no such scene file", path.string()));
  const Json j = load_json(path.string());
  return parse_scene(j, path.string(), path.has_parent_path() ? path.parent_path() : fs::path("."));
}

Json to_json(const Scene& s) {
  Json j;
  j["gravity"] = vec_json(s.gravity);
  j["time_step"] = s.frame_time;
  j["substeps"] = s.substeps;
  j["frames"] = s.frames;
  j["threads"] = s.threads;
  j["energy_form"] = physics::energy_form_name(s.energy_form);
  j["solve_bodies"] = s.solve_jointly ? "jointly" : "separately";
  j["cloths"] = Json::array();
  for (const auto& c : s.cloths) {
    Json cj;
    cj["name"] = c.name;
    if (!c.mesh.file.empty()) {
      cj["mesh"] = {{"file", c.mesh.file}, {"material_scale", c.mesh.material_scale}};
    } else if (!c.mesh.pattern.empty()) {
      cj["mesh"] = {{"pattern", c.mesh.pattern}, {"resolution", c.mesh.pattern_resolution}};
    } else if (c.mesh.generator == "tube") {
      const auto& t = c.mesh.tube;
      cj["mesh"] = {{"generator", "tube"}, {"circumference", t.circumference}, {"height", t.height},
                    {"vertices", t.target_vertices}, {"unstructured", t.unstructured}, {"seed", t.seed}};
    } else {
      const auto& r = c.mesh.rectangle;
      cj["mesh"] = {{"generator", "rectangle"}, {"width", r.width},      {"height", r.height},
                    {"vertices", r.target_vertices}, {"unstructured", r.unstructured}, {"seed", r.seed}};
      if (!r.holes.empty()) {
        cj["mesh"]["holes"] = Json::array();
        for (const auto& h : r.holes) cj["mesh"]["holes"].push_back({{"center", vec_json(h.center)}, {"radius", h.radius}});
      }
    }
    cj["transform"] = {{"translation", vec_json(c.transform.translation)}, {"rotation_deg", vec_json(c.transform.rotation_deg)}};
    const auto& m = c.material;
    cj["material"] = {{"preset", c.preset},
                      {"youngs_modulus", m.youngs_modulus},
                      {"poisson_ratio", m.poisson_ratio},
                      {"thickness", m.thickness},
                      {"density", m.density},
                      {"bending_stiffness", m.bending_stiffness},
                      {"membrane", physics::to_string(m.membrane)},
                      {"bending", physics::to_string(m.bending)},
                      {"pd_strain_min", m.pd_strain_min},
                      {"pd_strain_max", m.pd_strain_max}};
    cj["pins"] = Json::array();
    for (const auto& p : c.pins) {
      Json pj;
      if (!p.vertices.empty()) pj["vertices"] = p.vertices;
      if (!p.points.empty()) {
        pj["points"] = Json::array();
        for (const auto& pt : p.points) pj["points"].push_back(vec_json(pt));
      }
      if (p.region) pj["region"] = {{"min", vec_json(p.region->first)}, {"max", vec_json(p.region->second)}};
      pj["stiffness"] = p.stiffness;
      pj["motion"] = {{"type", p.motion}};
      if (p.motion == "constant_velocity" || p.motion == "rotation") pj["motion"]["velocity"] = vec_json(p.velocity);
      if (p.motion == "rotation") {
        pj["motion"]["axis"] = vec_json(p.axis);
        pj["motion"]["center"] = vec_json(p.center);
        pj["motion"]["angular_velocity"] = p.angular_velocity;
        pj["motion"]["duration"] = std::isfinite(p.duration) ? p.duration : 1e30;
      }
      if (p.motion == "keyframes") {
        pj["motion"]["keys"] = Json::array();
        for (size_t k = 0; k < p.key_times.size(); ++k)
          pj["motion"]["keys"].push_back({{"time", p.key_times[k]}, {"offset", vec_json(p.key_offsets[k])}});
      }
      cj["pins"].push_back(pj);
    }
    cj["initial_velocity"] = vec_json(c.initial_velocity);
    cj["seam_stiffness"] = c.seam_stiffness;
    if (s.cloth_contact.enabled || c.contact_thickness > 0.0) cj["contact_thickness"] = c.contact_thickness;
    j["cloths"].push_back(cj);
  }
  j["shells"] = Json::array();
  for (const auto& sh : s.shells) j["shells"].push_back(to_json(sh));
  j["obstacles"] = Json::array();
  for (const auto& o : s.obstacles) {
    Json oj;
    oj["name"] = o.name;
    if (o.shape == "body") {
      const auto& m = o.body;
      const auto& w = o.walk;
      oj["body"] = {{"height", m.height}, {"build", m.build}, {"resolution", m.resolution}, {"arm_abduction", m.arm_abduction}};
      if (w.duration > 0.0) {
        oj["body"]["walk"] = {{"period", w.period},     {"stand", w.stand},       {"ramp", w.ramp},
                              {"duration", w.duration}, {"key_rate", w.key_rate}, {"forward", w.forward},
                              {"arm_swing", w.arm_swing}};
      }
      if (o.contact_thickness > 0.0) oj["contact_thickness"] = o.contact_thickness;
    } else if (o.shape == "mesh") {
      oj["mesh"] = o.mesh;
      if (o.contact_thickness > 0.0) oj["contact_thickness"] = o.contact_thickness;
      if (o.surface && o.surface->skin) {
        if (!o.gltf_mesh.empty()) oj["gltf_mesh"] = o.gltf_mesh;
        if (!o.gltf_animation.empty()) oj["gltf_animation"] = o.gltf_animation;
        oj["gltf_y_up"] = o.gltf_y_up;
        oj["mesh_loop"] = o.mesh_loop;
      }
      if (o.mesh_rate > 0.0) {
        oj["mesh_rate"] = o.mesh_rate;
        oj["mesh_first"] = o.mesh_first;
        oj["mesh_loop"] = o.mesh_loop;
      }
    } else {
      oj["shape"] = {{"type", o.shape}};
    }
    if (o.shape == "sphere" || o.shape == "capsule") oj["shape"]["radius"] = o.radius;
    if (o.shape == "capsule") oj["shape"]["half_length"] = o.half_length;
    if (o.shape == "box") oj["shape"]["half_extents"] = vec_json(o.half_extents);
    oj["position"] = vec_json(o.position);
    oj["rotation_deg"] = vec_json(o.rotation_deg);
    oj["friction"] = o.friction;
    oj["motion"] = {{"type", o.motion}};
    if (o.motion == "constant_velocity") {
      oj["motion"]["linear_velocity"] = vec_json(o.linear_velocity);
      oj["motion"]["angular_velocity"] = vec_json(o.angular_velocity);
    }
    if (o.motion == "keyframes") {
      oj["motion"]["keys"] = Json::array();
      for (size_t k = 0; k < o.key_times.size(); ++k)
        oj["motion"]["keys"].push_back({{"time", o.key_times[k]},
                                        {"position", vec_json(o.key_positions[k])},
                                        {"rotation_deg", vec_json(o.key_rotations_deg[k])}});
    }
    j["obstacles"].push_back(oj);
  }
  j["contact"] = {{"thickness", s.contact.thickness}, {"stiffness", s.contact.stiffness}};
  if (s.cloth_contact.enabled) {
    const auto& cc = s.cloth_contact;
    j["cloth_contact"] = {{"thickness", cc.thickness},
                          {"stiffness", cc.params.stiffness},
                          {"barrier_fraction", cc.params.barrier_fraction},
                          {"ccd_separation", cc.params.ccd_separation},
                          {"check_intersections", cc.check_intersections},
                          {"friction", cc.friction.friction},
                          {"static_friction_velocity", cc.friction.static_velocity},
                          {"friction_pairs", Json::array()}};
    for (const auto& p : cc.friction.pairs)
      j["cloth_contact"]["friction_pairs"].push_back({{"cloths", {p.a, p.b}}, {"friction", p.friction}});
  }
  j["solver"] = {{"name", s.solver.name},
                 {"rel_grad", s.solver.stop.rel_grad},
                 {"abs_grad", s.solver.stop.abs_grad},
                 {"velocity_tol", s.solver.velocity_tol},
                 {"velocity_rms_tol", s.solver.velocity_rms_tol},
                 {"max_iters", s.solver.stop.max_iters},
                 {"max_seconds", std::isfinite(s.solver.stop.max_seconds) ? s.solver.stop.max_seconds : 1e30},
                 {"params", solvers::resolved_params(s.solver, s.file, "solver.params")}};
  j["hierarchy"] = {{"ratio", s.hierarchy.ratio},
                    {"min_coarse_vertices", s.hierarchy.min_coarse_vertices},
                    {"max_coarse_vertices", s.hierarchy.max_coarse_vertices},
                    {"seed", s.hierarchy.seed}};
  j["output"] = {{"dir", s.output.dir}, {"every", s.output.every}, {"format", s.output.formats}};
  return j;
}

}  // namespace mgcloth::sim
