#include <mgcloth/sim/shell_scene.hpp>

#include <cmath>

namespace mgcloth::sim {

namespace fs = std::filesystem;

namespace {

const std::vector<std::string> kSides{"left", "right", "bottom", "top", "all"};

ShellSelection parse_selection(JsonReader& r, bool allow_control_points) {
  ShellSelection s;
  if (r.has("sides")) {
    const Json& j = r.raw("sides");
    const auto add = [&](const Json& v, const std::string& path) {
      if (!v.is_string() || std::find(kSides.begin(), kSides.end(), v.get<std::string>()) == kSides.end())
        r.fail(path, fmt::format("expected a side name: left, right, bottom, top or all (got {})", v.dump()));
      s.sides.push_back(v.get<std::string>());
    };
    if (j.is_array()) {
      for (size_t i = 0; i < j.size(); ++i) add(j[i], fmt::format("sides[{}]", i));
    } else {
      add(j, "sides");
    }
  }
  if (auto box = r.optional_object("region")) {
    const Vec2 lo = box->vec2("min", Vec2::Zero()), hi = box->vec2("max", Vec2::Zero());
    if (!(lo.array() <= hi.array()).all()) box->fail("max", "must be >= min in both coordinates");
    box->finish();
    s.region = std::make_pair(lo, hi);
  }
  s.points = r.vec2s("points");
  if (allow_control_points && r.has("control_points"))
    for (int v : r.integers("control_points")) s.control_points.push_back(v);
  return s;
}

bool empty(const ShellSelection& s) { return s.sides.empty() && !s.region && s.points.empty() && s.control_points.empty(); }

double ramp(JsonReader& r) { return r.number("ramp_time", 0.0, 0.0, 1e9); }

physics::ShellMaterial parse_material(JsonReader& r, std::string& preset) {
  preset = r.choice("preset", "denim", {"denim", "stvk"});
  physics::ShellMaterial m = preset == "denim" ? physics::denim_material() : physics::ShellMaterial{};
  if (preset == "denim") {
    // The woven model (eq. 3.3) with the denim values as defaults: k in Pa, each response φ_j as its μ and α.
    if (r.has("k")) {
      const auto k = r.numbers("k");
      if (k.size() != 4) r.fail("k", fmt::format("expected 4 numbers (Pa), got {}", k.size()));
      for (int i = 0; i < 4; ++i) m.k[i] = k[i];
    }
    m.woven_energy_floor = r.number("energy_floor", m.woven_energy_floor, 0.0, 0.999);
    if (r.has("responses")) {
      auto responses = r.objects("responses");
      if (responses.size() != 4) r.fail("responses", fmt::format("expected 4 responses (phi1..phi4), got {}", responses.size()));
      for (int i = 0; i < 4; ++i) {
        m.phi[i].mu = responses[i].numbers("mu");
        m.phi[i].alpha = responses[i].numbers("alpha");
        responses[i].finish();
      }
    }
  }
  if (preset == "stvk") {
    m.young = r.number("young", m.young, 0.0);
    m.poisson = r.number("poisson", m.poisson, -0.999, 0.499);
  }
  m.thickness = r.number("thickness", m.thickness, 1e-7, 1.0);
  m.density = r.number("density", m.density, 1e-9, 1e4);
  m.warp_angle_deg = r.number("warp_angle_deg", m.warp_angle_deg, -360.0, 360.0);
  m.thickness_points = r.integer("thickness_points", m.thickness_points, 2, 5);
  m.integration = r.choice("thickness_integration", m.integration == physics::ShellMaterial::Integration::split ? "split" : "gauss",
                           {"gauss", "split"}) == "split"
                      ? physics::ShellMaterial::Integration::split
                      : physics::ShellMaterial::Integration::gauss;
  if (preset == "stvk" && !(m.young > 0.0)) r.fail("young", "must be positive");
  try {
    m.validate();
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}: {}", r.file(), r.path(), e.what()));
  }
  return m;
}

}  // namespace

ShellSpec parse_shell(JsonReader r, const fs::path& base, size_t index) {
  ShellSpec s;
  s.name = r.name("name", fmt::format("shell{}", index));
  {
    JsonReader m = r.object("control_mesh");
    auto& ms = s.mesh;
    if (m.has("file")) {
      const fs::path file = m.required_string("file");
      ms.file = (file.is_absolute() ? file : base / file).lexically_normal().string();
      ms.generator.clear();
      ms.material_scale = m.number("material_scale", ms.material_scale, 1e-9, 1e9);
    } else {
      ms.generator = m.choice("generator", ms.generator, {"rectangle", "notched_square"});
      if (ms.generator == "rectangle") {
        ms.width = m.number("width", ms.width, 1e-4, 1e3);
        ms.height = m.number("height", ms.height, 1e-4, 1e3);
        ms.cells_u = m.integer("cells_u", ms.cells_u, 1, 100000);
        ms.cells_v = m.integer("cells_v", ms.cells_v, 1, 100000);
      } else {
        ms.width = ms.height = m.number("size", ms.width, 1e-4, 1e3);
        ms.cells_u = ms.cells_v = m.integer("cells", ms.cells_u, 2, 100000);
        ms.notch = m.number("notch", ms.notch, 1e-6, 1e3);
        if (!(ms.notch < ms.width)) m.fail("notch", "must be smaller than the square");
      }
    }
    ms.ghost_layer = m.boolean("ghost_layer", ms.ghost_layer);
    m.finish();
  }
  s.level = r.integer("level", s.level, 1, 9);
  if (auto m = r.optional_object("material")) {
    s.material = parse_material(*m, s.preset);
    m->finish();
  } else {
    s.material = physics::denim_material();
  }
  s.quadrature = r.integer("quadrature", s.quadrature, 2, 5);
  if (auto p = r.optional_object("penalty")) {
    s.sigma = p->number("sigma", s.sigma, 0.0, 20.0);
    s.beta = p->number("beta", s.beta, 0.0, 1e30);
    p->finish();
  }
  s.analysis = r.choice("analysis", s.analysis, {"dynamic", "static"});
  if (auto t = r.optional_object("transform")) {
    s.translation = t->vec3("translation", Vec3::Zero());
    s.rotation_deg = t->vec3("rotation_deg", Vec3::Zero());
    t->finish();
  }
  for (auto& b : r.objects("boundary")) {
    ShellBoundarySpec bc;
    bc.type = b.choice("type", bc.type, {"fixed", "clamped"});
    bc.where = parse_selection(b, true);
    if (empty(bc.where)) b.fail("sides", "a boundary condition needs \"sides\", \"region\", \"points\" or \"control_points\"");
    bc.displacement = b.vec3("displacement", Vec3::Zero());
    bc.ramp_time = ramp(b);
    b.finish();
    s.boundary.push_back(bc);
  }
  for (auto& l : r.objects("loads")) {
    ShellLoadSpec ld;
    ld.type = l.choice("type", ld.type, {"point", "edge", "pressure"});
    if (ld.type == "pressure") {
      ld.pressure = l.required_number("pressure");
    } else {
      ld.where = parse_selection(l, false);
      ld.force = ld.type == "point" ? l.vec3("force", Vec3::Zero()) : l.vec3("force_per_length", Vec3::Zero());
      if (ld.type == "point" && ld.where.points.empty()) l.fail("points", "a point load needs \"points\"");
      if (ld.type == "edge" && ld.where.sides.empty() && !ld.where.region)
        l.fail("sides", "an edge load needs \"sides\" or \"region\"");
    }
    ld.ramp_time = ramp(l);
    l.finish();
    s.loads.push_back(ld);
  }
  s.probes = r.vec2s("probes");
  s.display_samples = r.integer("display_samples", s.display_samples, 1, 16);
  r.finish();
  return s;
}

namespace {
Json to_json(const ShellSelection& s) {
  Json j = Json::object();
  if (!s.sides.empty()) j["sides"] = s.sides;
  if (s.region) j["region"] = {{"min", vec_json(s.region->first)}, {"max", vec_json(s.region->second)}};
  if (!s.points.empty()) {
    j["points"] = Json::array();
    for (const auto& p : s.points) j["points"].push_back(vec_json(p));
  }
  if (!s.control_points.empty()) j["control_points"] = s.control_points;
  return j;
}
}  // namespace

Json to_json(const ShellSpec& s) {
  Json j;
  j["name"] = s.name;
  const auto& m = s.mesh;
  if (!m.file.empty()) {
    j["control_mesh"] = {{"file", m.file}, {"material_scale", m.material_scale}};
  } else if (m.generator == "rectangle") {
    j["control_mesh"] = {{"generator", m.generator}, {"width", m.width}, {"height", m.height}, {"cells_u", m.cells_u},
                         {"cells_v", m.cells_v}};
  } else {
    j["control_mesh"] = {{"generator", m.generator}, {"size", m.width}, {"cells", m.cells_u}, {"notch", m.notch}};
  }
  j["control_mesh"]["ghost_layer"] = m.ghost_layer;
  j["level"] = s.level;
  j["material"] = {{"preset", s.preset},
                   {"thickness", s.material.thickness},
                   {"density", s.material.density},
                   {"warp_angle_deg", s.material.warp_angle_deg},
                   {"thickness_points", s.material.thickness_points},
                   {"thickness_integration", s.material.integration == physics::ShellMaterial::Integration::split ? "split" : "gauss"}};
  if (s.preset == "stvk") {
    j["material"]["young"] = s.material.young;
    j["material"]["poisson"] = s.material.poisson;
  } else {
    j["material"]["k"] = s.material.k;
    j["material"]["energy_floor"] = s.material.woven_energy_floor;
    j["material"]["responses"] = Json::array();
    for (const auto& p : s.material.phi) j["material"]["responses"].push_back({{"mu", p.mu}, {"alpha", p.alpha}});
  }
  j["quadrature"] = s.quadrature;
  j["penalty"] = {{"sigma", s.sigma}, {"beta", s.beta}};
  j["analysis"] = s.analysis;
  j["transform"] = {{"translation", vec_json(s.translation)}, {"rotation_deg", vec_json(s.rotation_deg)}};
  j["boundary"] = Json::array();
  for (const auto& b : s.boundary) {
    Json bj = to_json(b.where);
    bj["type"] = b.type;
    bj["displacement"] = vec_json(b.displacement);
    bj["ramp_time"] = b.ramp_time;
    j["boundary"].push_back(bj);
  }
  j["loads"] = Json::array();
  for (const auto& l : s.loads) {
    Json lj = l.type == "pressure" ? Json::object() : to_json(l.where);
    lj["type"] = l.type;
    if (l.type == "pressure") lj["pressure"] = l.pressure;
    if (l.type == "point") lj["force"] = vec_json(l.force);
    if (l.type == "edge") lj["force_per_length"] = vec_json(l.force);
    lj["ramp_time"] = l.ramp_time;
    j["loads"].push_back(lj);
  }
  j["probes"] = Json::array();
  for (const auto& p : s.probes) j["probes"].push_back(vec_json(p));
  j["display_samples"] = s.display_samples;
  return j;
}

}  // namespace mgcloth::sim
