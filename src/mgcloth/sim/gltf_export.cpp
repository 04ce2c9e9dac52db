#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/sim/gltf_export.hpp>

#ifdef MGCLOTH_HAVE_GLTF
// Debian's libtinygltf-dev ships the implementation compiled (libtinygltf.so), so no TINYGLTF_IMPLEMENTATION here.
#include <tiny_gltf.h>
#endif

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numbers>

namespace mgcloth::sim {

namespace fs = std::filesystem;

#ifdef MGCLOTH_HAVE_GLTF
bool glb_available() { return true; }

namespace {

/// A rigid shape's triangles in its local frame, with normals: obstacles never deform, so their normals stay valid
/// under the node's animated transform (the cloth has none: viewers derive them from the morphed positions).
struct ShapeMesh {
  std::vector<float> positions, normals;
  std::vector<std::uint32_t> indices;

  std::uint32_t add_vertex(const Vec3& p, const Vec3& n) {
    for (int d = 0; d < 3; ++d) {
      positions.push_back(static_cast<float>(p[d]));
      normals.push_back(static_cast<float>(n[d]));
    }
    return static_cast<std::uint32_t>(positions.size() / 3 - 1);
  }
  void add_triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c) { indices.insert(indices.end(), {a, b, c}); }
};

/// A sphere, or a capsule (the sphere's upper half raised by half_length along z, its lower half lowered, joined by
/// a cylinder): rings of constant polar angle from the north pole down, counter-clockwise seen from outside.
ShapeMesh round_shape(double radius, double half_length) {
  constexpr int kSlices = 32, kStacks = 16;
  struct Ring {
    double theta, z;
  };
  std::vector<Ring> rings;
  for (int j = 0; j <= kStacks; ++j) {
    const double theta = std::numbers::pi * j / kStacks;
    if (half_length > 0.0 && 2 * j == kStacks) {
      rings.push_back({theta, half_length});
      rings.push_back({theta, -half_length});
    } else {
      rings.push_back({theta, 2 * j < kStacks ? half_length : -half_length});
    }
  }
  ShapeMesh m;
  for (const Ring& r : rings)
    for (int s = 0; s < kSlices; ++s) {
      const double phi = 2.0 * std::numbers::pi * s / kSlices;
      const Vec3 n(std::sin(r.theta) * std::cos(phi), std::sin(r.theta) * std::sin(phi), std::cos(r.theta));
      m.add_vertex(radius * n + Vec3(0.0, 0.0, r.z), n);
    }
  const auto vertex = [](size_t ring, int slice) { return static_cast<std::uint32_t>(ring * kSlices + slice % kSlices); };
  for (size_t r = 0; r + 1 < rings.size(); ++r)
    for (int s = 0; s < kSlices; ++s) {
      const auto a = vertex(r, s), b = vertex(r, s + 1), c = vertex(r + 1, s), d = vertex(r + 1, s + 1);
      // At the poles a ring collapses to a point: keep only the triangle that is not degenerate.
      if (r != 0) m.add_triangle(a, c, b);
      if (r + 2 != rings.size()) m.add_triangle(b, c, d);
    }
  return m;
}

/// 24 vertices so that each face has its own normal (flat shading).
ShapeMesh box_shape(const Vec3& half) {
  ShapeMesh m;
  for (int k = 0; k < 3; ++k)
    for (double sign : {1.0, -1.0}) {
      const Vec3 n = sign * Vec3::Unit(k);
      Vec3 u = Vec3::Unit((k + 1) % 3), v = Vec3::Unit((k + 2) % 3);
      if (sign < 0.0) std::swap(u, v);  // keeps u × v = n, so the face is counter-clockwise seen from outside
      std::uint32_t corner[4];
      const double cu[4] = {-1, 1, 1, -1}, cv[4] = {-1, -1, 1, 1};
      for (int c = 0; c < 4; ++c) corner[c] = m.add_vertex((n + cu[c] * u + cv[c] * v).cwiseProduct(half), n);
      m.add_triangle(corner[0], corner[1], corner[2]);
      m.add_triangle(corner[0], corner[2], corner[3]);
    }
  return m;
}

/// The plane z = 0 (solid below) as a square of half size `half` about the local origin, facing +z.
ShapeMesh plane_shape(double half) {
  ShapeMesh m;
  const Vec3 n = Vec3::UnitZ();
  const auto a = m.add_vertex(Vec3(-half, -half, 0.0), n), b = m.add_vertex(Vec3(half, -half, 0.0), n),
             c = m.add_vertex(Vec3(half, half, 0.0), n), d = m.add_vertex(Vec3(-half, half, 0.0), n);
  m.add_triangle(a, b, c);
  m.add_triangle(a, c, d);
  return m;
}

/// Builds the model: one buffer that every buffer view slices, appended to in order.
class ModelBuilder {
 public:
  tinygltf::Model model;

  ModelBuilder() {
    model.asset.version = "2.0";
    model.asset.generator = "mgcloth";
    model.buffers.emplace_back();
  }
  std::vector<unsigned char>& bytes() { return model.buffers[0].data; }

  /// A buffer view over `size` bytes copied to the end of the buffer; target 0 for animation data.
  int view(const void* data, size_t size, int target) {
    auto& b = bytes();
    const size_t offset = b.size();  // every element is 4 bytes, so offsets stay 4-aligned
    b.resize(offset + size);
    std::memcpy(b.data() + offset, data, size);
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = offset;
    v.byteLength = size;
    v.target = target;
    model.bufferViews.push_back(v);
    return static_cast<int>(model.bufferViews.size() - 1);
  }

  /// Float accessor of `width` components per element (1 scalar, 3 vec3, 4 vec4) with its per-component min/max
  /// (required by glTF for POSITION attributes and animation inputs; written for every float accessor).
  int floats(const std::vector<float>& data, int width, int target) {
    tinygltf::Accessor a;
    a.bufferView = view(data.data(), data.size() * sizeof(float), target);
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.count = data.size() / static_cast<size_t>(width);
    a.type = width == 1 ? TINYGLTF_TYPE_SCALAR : width == 2 ? TINYGLTF_TYPE_VEC2 : width == 3 ? TINYGLTF_TYPE_VEC3 : TINYGLTF_TYPE_VEC4;
    a.minValues.assign(width, std::numeric_limits<double>::infinity());
    a.maxValues.assign(width, -std::numeric_limits<double>::infinity());
    for (size_t i = 0; i < data.size(); ++i) {
      const size_t c = i % static_cast<size_t>(width);
      a.minValues[c] = std::min(a.minValues[c], static_cast<double>(data[i]));
      a.maxValues[c] = std::max(a.maxValues[c], static_cast<double>(data[i]));
    }
    if (data.empty()) {
      a.minValues.assign(width, 0.0);
      a.maxValues.assign(width, 0.0);
    }
    model.accessors.push_back(a);
    return static_cast<int>(model.accessors.size() - 1);
  }

  int indices(const std::vector<std::uint32_t>& data) {
    tinygltf::Accessor a;
    a.bufferView = view(data.data(), data.size() * sizeof(std::uint32_t), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    a.count = data.size();
    a.type = TINYGLTF_TYPE_SCALAR;
    model.accessors.push_back(a);
    return static_cast<int>(model.accessors.size() - 1);
  }

  int material(const std::string& name, const std::array<double, 3>& color, bool double_sided) {
    tinygltf::Material m;
    m.name = name;
    m.doubleSided = double_sided;
    m.pbrMetallicRoughness.baseColorFactor = {color[0], color[1], color[2], 1.0};
    m.pbrMetallicRoughness.metallicFactor = 0.0;
    m.pbrMetallicRoughness.roughnessFactor = 0.9;
    model.materials.push_back(m);
    return static_cast<int>(model.materials.size() - 1);
  }

  int node(tinygltf::Node n) {
    model.nodes.push_back(std::move(n));
    return static_cast<int>(model.nodes.size() - 1);
  }

  void channel(tinygltf::Animation& anim, int node, const std::string& path, int input, int output) {
    tinygltf::AnimationSampler s;
    s.input = input;
    s.output = output;
    s.interpolation = "STEP";
    anim.samplers.push_back(s);
    tinygltf::AnimationChannel c;
    c.sampler = static_cast<int>(anim.samplers.size() - 1);
    c.target_node = node;
    c.target_path = path;
    anim.channels.push_back(c);
  }
};

void check(const fs::path& path, const SurfaceAnimation& s) {
  const size_t n = static_cast<size_t>(s.num_vertices), frames = s.times.size();
  if (frames == 0 || n == 0) throw_error("{}: nothing to export ({} frames of {} vertices)", path.string(), frames, n);
  if (s.positions.size() != 3 * n * frames)
    throw_error("{}: {} position values for {} frames of {} vertices", path.string(), s.positions.size(), frames, n);
  if (!s.frame_numbers.empty() && s.frame_numbers.size() != frames)
    throw_error("{}: {} frame numbers for {} frames", path.string(), s.frame_numbers.size(), frames);
  if (s.uv.cols() != 0 && s.uv.cols() != s.num_vertices)
    throw_error("{}: {} texture coordinates for {} vertices", path.string(), s.uv.cols(), n);
  for (const Tri& t : s.tris)
    for (Index v : t)
      if (v < 0 || v >= s.num_vertices) throw_error("{}: triangle vertex {} out of range ({} vertices)", path.string(), v, n);
  // Times are stored as float: frames closer than float resolution would break the animation's ordering.
  for (size_t k = 1; k < frames; ++k)
    if (!(static_cast<float>(s.times[k]) > static_cast<float>(s.times[k - 1])))
      throw_error("{}: frame times {} and {} do not increase at float precision", path.string(), s.times[k - 1], s.times[k]);
}

/// Centre and half diagonal of the box around every position of every frame (sizes the planes).
std::pair<Vec3, double> bounding_sphere(const std::vector<float>& positions) {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (size_t i = 0; i + 2 < positions.size(); i += 3) {
    const Vec3 p(positions[i], positions[i + 1], positions[i + 2]);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return {0.5 * (lo + hi), 0.5 * (hi - lo).norm()};
}

std::vector<float> quaternion(const Eigen::Quaterniond& q) {
  const Eigen::Quaterniond u = q.normalized();
  return {static_cast<float>(u.x()), static_cast<float>(u.y()), static_cast<float>(u.z()), static_cast<float>(u.w())};
}

}  // namespace

void write_glb(const fs::path& path, const SurfaceAnimation& surface, const std::vector<geometry::Obstacle>& obstacles) {
  check(path, surface);
  const size_t n = static_cast<size_t>(surface.num_vertices), frames = surface.times.size();
  ModelBuilder b;
  tinygltf::Animation anim;
  anim.name = "simulation";

  // mgcloth is z-up (gravity along −z), glTF is y-up: a rotation of −90° about x on the root maps (x, y, z) to
  // (x, z, −y) and leaves all data below it in simulation coordinates.
  tinygltf::Node root;
  root.name = "z_up";
  root.rotation = {-std::sqrt(0.5), 0.0, 0.0, std::sqrt(0.5)};

  std::vector<float> times(frames);
  for (size_t k = 0; k < frames; ++k) times[k] = static_cast<float>(surface.times[k]);
  const int time_accessor = b.floats(times, 1, 0);

  // The surface: frame 0 as base positions, frame k as morph target k − 1 (offsets from the base).
  {
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    const std::vector<float> base(surface.positions.begin(), surface.positions.begin() + 3 * n);
    prim.attributes["POSITION"] = b.floats(base, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
    if (surface.uv.cols() == surface.num_vertices) {
      std::vector<float> uv(2 * n);
      // glTF puts the texture origin at the top left, OBJ at the bottom left.
      for (size_t i = 0; i < n; ++i) {
        uv[2 * i] = static_cast<float>(surface.uv(0, i));
        uv[2 * i + 1] = static_cast<float>(1.0 - surface.uv(1, i));
      }
      prim.attributes["TEXCOORD_0"] = b.floats(uv, 2, TINYGLTF_TARGET_ARRAY_BUFFER);
    }
    std::vector<std::uint32_t> idx;
    idx.reserve(3 * surface.tris.size());
    for (const Tri& t : surface.tris)
      for (Index v : t) idx.push_back(static_cast<std::uint32_t>(v));
    prim.indices = b.indices(idx);
    prim.material = b.material("cloth", {0.8, 0.3, 0.25}, /*double_sided=*/true);

    tinygltf::Mesh mesh;
    mesh.name = "cloth";
    tinygltf::Value::Array names;
    std::vector<float> delta(3 * n);
    for (size_t k = 1; k < frames; ++k) {
      const float* x = surface.positions.data() + 3 * n * k;
      for (size_t i = 0; i < 3 * n; ++i) delta[i] = x[i] - base[i];
      prim.targets.push_back({{"POSITION", b.floats(delta, 3, TINYGLTF_TARGET_ARRAY_BUFFER)}});
      names.emplace_back(fmt::format("frame_{:05d}", surface.frame_numbers.empty() ? static_cast<int>(k) : surface.frame_numbers[k]));
    }
    mesh.primitives.push_back(std::move(prim));
    std::vector<float> weights;
    if (frames > 1) {
      mesh.weights.assign(frames - 1, 0.0);
      // Blender names the shape keys, three.js the morphTargetDictionary entries, from extras.targetNames.
      tinygltf::Value::Object extras;
      extras["targetNames"] = tinygltf::Value(std::move(names));
      mesh.extras = tinygltf::Value(std::move(extras));
      // Frame k (k ≥ 1) shows target k − 1 alone; the output is frames × targets weights, so it grows
      // quadratically with the frame count (output.every keeps long runs small).
      weights.assign(frames * (frames - 1), 0.0f);
      for (size_t k = 1; k < frames; ++k) weights[k * (frames - 1) + (k - 1)] = 1.0f;
    }
    tinygltf::Node node;
    node.name = "cloth";
    node.mesh = static_cast<int>(b.model.meshes.size());
    b.model.meshes.push_back(std::move(mesh));
    const int cloth_node = b.node(node);
    root.children.push_back(cloth_node);
    if (frames > 1) b.channel(anim, cloth_node, "weights", time_accessor, b.floats(weights, 1, 0));
  }

  // Obstacles: a node per obstacle, posed at the first frame, with its poses at every frame as STEP channels when
  // it moves.
  const auto [centre, radius] = bounding_sphere(surface.positions);
  const int obstacle_material = obstacles.empty() ? -1 : b.material("obstacle", {0.6, 0.6, 0.65}, /*double_sided=*/false);
  for (const auto& ob : obstacles) {
    const geometry::Pose first = ob.motion ? ob.motion->pose(surface.times.front()) : geometry::Pose{};
    ShapeMesh shape;
    const auto params = ob.shape->params();
    switch (ob.shape->kind()) {
      case 0: {
        // Large enough to lie under the whole animation, seen from any viewpoint that frames the cloth.
        const Vec3 c = first.to_local(centre);
        shape = plane_shape(std::max(1.0, 2.0 * (c.head<2>().norm() + radius)));
        break;
      }
      case 1: shape = round_shape(params[0], 0.0); break;
      case 2: shape = box_shape(Vec3(params[0], params[1], params[2])); break;
      case 3: shape = round_shape(params[0], params[1]); break;
      default: throw_error("{}: obstacle \"{}\": cannot tessellate shape \"{}\"", path.string(), ob.name, ob.shape->type());
    }
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    prim.attributes["POSITION"] = b.floats(shape.positions, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
    prim.attributes["NORMAL"] = b.floats(shape.normals, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
    prim.indices = b.indices(shape.indices);
    prim.material = obstacle_material;
    tinygltf::Mesh mesh;
    mesh.name = ob.name;
    mesh.primitives.push_back(std::move(prim));
    tinygltf::Node node;
    node.name = ob.name;
    node.mesh = static_cast<int>(b.model.meshes.size());
    b.model.meshes.push_back(std::move(mesh));
    node.translation = {first.translation.x(), first.translation.y(), first.translation.z()};
    const auto q0 = quaternion(first.rotation);
    node.rotation.assign(q0.begin(), q0.end());
    const int index = b.node(node);
    root.children.push_back(index);
    if (!ob.motion) continue;
    std::vector<float> translations, rotations;
    Eigen::Quaterniond previous = first.rotation;
    bool moves = false;
    for (double t : surface.times) {
      const geometry::Pose p = ob.motion->pose(t);
      moves = moves || p.translation != first.translation || p.rotation.coeffs() != first.rotation.coeffs();
      for (int d = 0; d < 3; ++d) translations.push_back(static_cast<float>(p.translation[d]));
      // q and −q are the same rotation; staying in one hemisphere keeps interpolating importers on the short arc.
      Eigen::Quaterniond q = p.rotation;
      if (q.dot(previous) < 0.0) q.coeffs() = -q.coeffs();
      previous = q;
      const auto qf = quaternion(q);
      rotations.insert(rotations.end(), qf.begin(), qf.end());
    }
    if (!moves) continue;  // a static obstacle's node pose says it all
    b.channel(anim, index, "translation", time_accessor, b.floats(translations, 3, 0));
    b.channel(anim, index, "rotation", time_accessor, b.floats(rotations, 4, 0));
  }

  const int root_index = b.node(root);
  tinygltf::Scene scene;
  scene.name = "mgcloth";
  scene.nodes.push_back(root_index);
  b.model.scenes.push_back(scene);
  b.model.defaultScene = 0;
  if (!anim.channels.empty()) b.model.animations.push_back(std::move(anim));

  // A .glb addresses its chunks with 32-bit lengths.
  const size_t bytes = b.bytes().size();
  if (bytes > std::numeric_limits<std::uint32_t>::max() - (64u << 20))
    throw_error("{}: the animation needs {:.1f} GiB of binary data, more than a .glb can hold (4 GiB); "
                "write fewer frames with output.every",
                path.string(), static_cast<double>(bytes) / (1u << 30));
  b.model.buffers[0].name = "data";
  write_file_atomic(
      path,
      [&](std::ostream& o) {
        tinygltf::TinyGLTF writer;
        if (!writer.WriteGltfSceneToStream(&b.model, o, /*prettyPrint=*/false, /*writeBinary=*/true))
          throw_error("{}: tinygltf could not serialize the model", path.string());
      },
      /*binary=*/true);
}

#else
bool glb_available() { return false; }

void write_glb(const fs::path& path, const SurfaceAnimation&, const std::vector<geometry::Obstacle>&) {
  throw_error("{}: this build of mgcloth has no glTF export (configured without libtinygltf-dev; install it and "
              "re-run cmake)",
              path.string());
}
#endif

}  // namespace mgcloth::sim
