#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/sim/gltf_export.hpp>
#include <mgcloth/sim/gltf_skin.hpp>

#ifdef MGCLOTH_HAVE_GLTF
// Debian's libtinygltf-dev ships the implementation compiled (libtinygltf.so), so no TINYGLTF_IMPLEMENTATION here.
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>
#endif

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <sstream>
#include <string_view>

namespace mgcloth::sim {

namespace fs = std::filesystem;

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

/// Area-weighted vertex normals (+z where a vertex has no area around it).
std::vector<float> vertex_normals(const Mat3X& v, const std::vector<Tri>& tris) {
  Mat3X n = Mat3X::Zero(3, v.cols());
  for (const Tri& t : tris) {
    const Vec3 a = (v.col(t[1]) - v.col(t[0])).cross(v.col(t[2]) - v.col(t[0]));
    for (Index i : t) n.col(i) += a;
  }
  std::vector<float> out;
  out.reserve(3 * static_cast<size_t>(v.cols()));
  for (Index i = 0; i < v.cols(); ++i) {
    const double len = n.col(i).norm();
    const Vec3 u = len > 0.0 ? Vec3(n.col(i) / len) : Vec3::UnitZ();
    for (int d = 0; d < 3; ++d) out.push_back(static_cast<float>(u[d]));
  }
  return out;
}

/// An obstacle's shape tessellated as write_glb draws it; a plane is sized to cover the sphere around the animated
/// surface (`centre`, in the obstacle's frame, and `radius`).
ShapeMesh obstacle_shape(const fs::path& path, const geometry::Obstacle& ob, const Vec3& centre, double radius) {
  if (ob.mesh) {
    // The mesh as it is, smooth-shaded by area-weighted vertex normals.
    const Mat3X& v = ob.mesh->vertices;
    ShapeMesh m;
    m.normals = vertex_normals(v, ob.mesh->tris);
    for (Index i = 0; i < v.cols(); ++i)
      for (int d = 0; d < 3; ++d) m.positions.push_back(static_cast<float>(v(d, i)));
    for (const Tri& t : ob.mesh->tris)
      m.add_triangle(static_cast<std::uint32_t>(t[0]), static_cast<std::uint32_t>(t[1]), static_cast<std::uint32_t>(t[2]));
    return m;
  }
  const auto params = ob.shape->params();
  switch (ob.shape->kind()) {
    // Large enough to lie under the whole animation, seen from any viewpoint that frames the cloth.
    case 0: return plane_shape(std::max(1.0, 2.0 * (centre.head<2>().norm() + radius)));
    case 1: return round_shape(params[0], 0.0);
    case 2: return box_shape(Vec3(params[0], params[1], params[2]));
    case 3: return round_shape(params[0], params[1]);
    default: throw_error("{}: obstacle \"{}\": cannot tessellate shape \"{}\"", path.string(), ob.name, ob.shape->type());
  }
}

/// A skinned mesh as a glb holds it. Its positions, normals and inverse bind matrices are taken through `bind`, the
/// world transform in the file of the node that the skeleton hangs from (at the first frame): then each inverse
/// bind matrix is the inverse of its joint's world transform in the bind pose, as importers that rebuild a rest
/// pose from them (Blender) assume, and the vertex data is the bind pose where the file shows it. Skinning gives
/// the same positions either way: bind cancels between a vertex and its inverse bind matrix.
struct SkinBuffers {
  std::vector<float> positions, normals, weights, inverse_bind;
  std::vector<std::uint32_t> indices;
  std::vector<std::uint16_t> joints;
  struct Channel {
    size_t joint;
    const char* path;
    const char* interpolation;
    int input;  ///< index into `inputs`; −1: the frame times
    int width;
    std::vector<float> output;
  };
  std::vector<std::vector<float>> inputs;  ///< the distinct key times of the tracks
  std::vector<Channel> channels;

  std::uint64_t bytes() const {
    std::uint64_t b = 4 * (positions.size() + normals.size() + weights.size() + inverse_bind.size() + indices.size()) +
                      2 * joints.size();
    for (const auto& t : inputs) b += 4 * t.size();
    for (const auto& c : channels) b += 4 * c.output.size();
    return b;
  }
};

/// The buffers of `skin` (see SkinBuffers). With `looped_times` (a skin on a looping surface), every track is
/// sampled at those times with STEP interpolation, as TriangleSurface::at repeats the animation: a glTF channel
/// cannot repeat its keys.
SkinBuffers skin_buffers(const geometry::SkinnedMesh& skin, const Eigen::Affine3d& bind,
                         const std::vector<double>* looped_times) {
  using geometry::Interpolation;
  SkinBuffers d;
  // A singular placement has no inverse to put into the inverse bind matrices: the data stays in skin coordinates.
  const double det = bind.linear().determinant();
  const Eigen::Affine3d c = std::isfinite(det) && std::abs(det) > 1e-12 ? bind : Eigen::Affine3d::Identity();
  const Mat3X rest = c * skin.rest;
  for (Index v = 0; v < rest.cols(); ++v)
    for (int k = 0; k < 3; ++k) d.positions.push_back(static_cast<float>(rest(k, v)));
  d.normals = vertex_normals(rest, skin.tris);
  for (const Tri& t : skin.tris)
    for (Index v : t) d.indices.push_back(static_cast<std::uint32_t>(v));
  for (Index v = 0; v < skin.num_vertices(); ++v)
    for (int k = 0; k < 4; ++k) {
      const double w = skin.weights(k, v);
      d.joints.push_back(w > 0.0 ? static_cast<std::uint16_t>(skin.joints(k, v)) : std::uint16_t{0});
      d.weights.push_back(static_cast<float>(w));
    }
  const Eigen::Affine3d c_inverse = c.inverse();
  for (const auto& ib : skin.inverse_bind) {
    const Eigen::Matrix4d m = (ib * c_inverse).matrix();
    for (int k = 0; k < 16; ++k) d.inverse_bind.push_back(static_cast<float>(m(k)));  // column-major, as glTF
  }

  const auto name = [](Interpolation i) {
    return i == Interpolation::Step ? "STEP" : i == Interpolation::CubicSpline ? "CUBICSPLINE" : "LINEAR";
  };
  std::map<std::vector<float>, int> inputs;
  const auto add = [&](size_t joint, const char* path, const auto& track) {
    if (track.empty()) return;
    constexpr int width = static_cast<int>(std::decay_t<decltype(track)>::Value::RowsAtCompileTime);
    SkinBuffers::Channel ch{joint, path, looped_times ? "STEP" : name(track.interpolation), -1, width, {}};
    if (!looped_times) {
      std::vector<float> times(track.times.begin(), track.times.end());
      const auto [it, added] = inputs.try_emplace(std::move(times), static_cast<int>(d.inputs.size()));
      if (added) d.inputs.push_back(it->first);
      ch.input = it->second;
      const auto put = [&](const auto& value) {
        for (int k = 0; k < width; ++k) ch.output.push_back(static_cast<float>(value[k]));
      };
      for (size_t k = 0; k < track.times.size(); ++k) {
        // glTF 2.0 Appendix C: a CUBICSPLINE key's output is its in-tangent, its value, its out-tangent.
        if (track.interpolation == Interpolation::CubicSpline) put(track.in_tangents[k]);
        put(track.values[k]);
        if (track.interpolation == Interpolation::CubicSpline) put(track.out_tangents[k]);
      }
    }
    d.channels.push_back(std::move(ch));
  };
  for (size_t j = 0; j < skin.tracks.size(); ++j) {
    add(j, "translation", skin.tracks[j].translation);
    add(j, "rotation", skin.tracks[j].rotation);
    add(j, "scale", skin.tracks[j].scale);
  }
  if (looped_times) {
    const double period = skin.duration();
    for (double t : *looped_times) {
      // The time TriangleSurface::at poses a looping skin at.
      const auto local = skin.local_at(period > 0.0 ? std::fmod(std::max(t, 0.0), period) : t);
      for (auto& ch : d.channels) {
        const auto& l = local[ch.joint];
        const std::string_view path = ch.path;
        const Eigen::Vector4d v = path == "translation" ? Eigen::Vector4d(l.translation.x(), l.translation.y(), l.translation.z(), 0.0)
                                  : path == "scale"     ? Eigen::Vector4d(l.scale.x(), l.scale.y(), l.scale.z(), 0.0)
                                                        : Eigen::Vector4d(l.rotation.coeffs());  // x, y, z, w
        for (int k = 0; k < ch.width; ++k) ch.output.push_back(static_cast<float>(v[k]));
      }
    }
  }
  return d;
}

/// Whether a write_glb obstacle is a skinned mesh, and whether it is a mesh sequence (written as morph targets).
bool is_skinned(const geometry::Obstacle& ob) { return ob.mesh && ob.mesh->skin; }
bool is_sequence(const geometry::Obstacle& ob) { return ob.mesh && !ob.mesh->skin && !ob.mesh->frames.empty(); }
bool loops(const geometry::Obstacle& ob) { return ob.mesh->loop && ob.mesh->skin->duration() > 0.0; }

}  // namespace

std::uint64_t glb_binary_bytes(std::uint64_t vertices, std::uint64_t triangles, bool uv, std::uint64_t frames,
                               const std::vector<geometry::Obstacle>& obstacles) {
  const std::uint64_t f = 4, targets = frames > 0 ? frames - 1 : 0;
  // Times, base positions, texture coordinates, and three uint32 indices per triangle.
  std::uint64_t bytes = f * frames + 3 * f * vertices + (uv ? 2 * f * vertices : 0) + 3 * f * triangles;
  bytes += 3 * f * vertices * targets;  // morph targets
  bytes += f * frames * targets;        // their weights, frames × targets
  for (const auto& ob : obstacles) {
    if (is_skinned(ob)) {
      // Only the number of sampled keys matters here, not their times.
      const std::vector<double> sampled(frames, 0.0);
      bytes += skin_buffers(*ob.mesh->skin, Eigen::Affine3d::Identity(), loops(ob) ? &sampled : nullptr).bytes();
    } else if (is_sequence(ob)) {
      // Base positions, indices, and a morph target per frame after the first (driven by the surface's weights).
      const std::uint64_t v = static_cast<std::uint64_t>(ob.mesh->vertices.cols());
      bytes += 3 * f * v + 3 * f * ob.mesh->tris.size() + 3 * f * v * targets;
    } else {
      const ShapeMesh shape = obstacle_shape("", ob, Vec3::Zero(), 0.0);
      bytes += f * (shape.positions.size() + shape.normals.size() + shape.indices.size());
    }
    if (ob.motion) bytes += 7 * f * frames;  // translation and rotation channels
  }
  return bytes;
}

#ifdef MGCLOTH_HAVE_GLTF
bool glb_available() { return true; }

namespace {

/// Builds the model: one buffer that every buffer view slices, appended to in order. The large views (the morph
/// targets and their weights, which grow with the frame count) are streamed: only their size is known here, and
/// their bytes are produced when the file is written.
class ModelBuilder {
 public:
  tinygltf::Model model;

  ModelBuilder() {
    model.asset.version = "2.0";
    model.asset.generator = "mgcloth";
    model.buffers.emplace_back();
  }
  std::uint64_t buffer_bytes() const { return m_size; }

  /// A buffer view over a copy of `size` bytes at the end of the buffer; target 0 for animation data.
  int view(const void* data, size_t size, int target) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    m_chunks.push_back({std::vector<unsigned char>(bytes, bytes + size), nullptr});
    return add_view(size, target);
  }
  /// A buffer view over `size` bytes at the end of the buffer that `write` puts out when the file is written.
  int streamed_view(size_t size, int target, std::function<void(std::ostream&)> write) {
    m_chunks.push_back({{}, std::move(write)});
    return add_view(size, target);
  }
  /// Writes the buffer's bytes: every view's in order.
  void write_buffer(std::ostream& o) const {
    for (const auto& c : m_chunks) {
      if (c.write) c.write(o);
      else o.write(reinterpret_cast<const char*>(c.bytes.data()), static_cast<std::streamsize>(c.bytes.size()));
    }
  }

  /// Float accessor of `count` elements of `width` components (1 scalar, 2 vec2, 3 vec3, 4 vec4, 16 mat4) over a view, with
  /// its per-component min/max (required by glTF for POSITION attributes and animation inputs; written for every
  /// float accessor).
  int float_accessor(int view, size_t count, int width, std::vector<double> min, std::vector<double> max) {
    tinygltf::Accessor a;
    a.bufferView = view;
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.count = count;
    a.type = width == 1 ? TINYGLTF_TYPE_SCALAR : width == 2 ? TINYGLTF_TYPE_VEC2 : width == 3 ? TINYGLTF_TYPE_VEC3
           : width == 4 ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_MAT4;
    a.minValues = std::move(min);
    a.maxValues = std::move(max);
    model.accessors.push_back(a);
    return static_cast<int>(model.accessors.size() - 1);
  }

  int floats(const std::vector<float>& data, int width, int target) {
    auto [min, max] = bounds(data.data(), data.size(), width);
    return float_accessor(view(data.data(), data.size() * sizeof(float), target), data.size() / static_cast<size_t>(width),
                          width, std::move(min), std::move(max));
  }

  /// Per-component min and max of `size` floats, `width` per element (zeros when there are none).
  static std::pair<std::vector<double>, std::vector<double>> bounds(const float* data, size_t size, int width) {
    if (size == 0) return {std::vector<double>(width, 0.0), std::vector<double>(width, 0.0)};
    std::vector<double> min(width, std::numeric_limits<double>::infinity()), max(width, -std::numeric_limits<double>::infinity());
    for (size_t i = 0; i < size; ++i) {
      const size_t c = i % static_cast<size_t>(width);
      min[c] = std::min(min[c], static_cast<double>(data[i]));
      max[c] = std::max(max[c], static_cast<double>(data[i]));
    }
    return {min, max};
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

  /// Unsigned short VEC4 vertex attribute (JOINTS_0); 8 bytes per element keep the buffer's offsets 4-aligned.
  int joints(const std::vector<std::uint16_t>& data) {
    tinygltf::Accessor a;
    a.bufferView = view(data.data(), data.size() * sizeof(std::uint16_t), TINYGLTF_TARGET_ARRAY_BUFFER);
    a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
    a.count = data.size() / 4;
    a.type = TINYGLTF_TYPE_VEC4;
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

  void channel(tinygltf::Animation& anim, int node, const std::string& path, int input, int output,
               const char* interpolation = "STEP") {
    tinygltf::AnimationSampler s;
    s.input = input;
    s.output = output;
    s.interpolation = interpolation;
    anim.samplers.push_back(s);
    tinygltf::AnimationChannel c;
    c.sampler = static_cast<int>(anim.samplers.size() - 1);
    c.target_node = node;
    c.target_path = path;
    anim.channels.push_back(c);
  }

 private:
  int add_view(size_t size, int target) {
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = m_size;  // every element is 4 bytes, so offsets stay 4-aligned
    v.byteLength = size;
    v.target = target;
    model.bufferViews.push_back(v);
    m_size += size;
    return static_cast<int>(model.bufferViews.size() - 1);
  }

  struct Chunk {
    std::vector<unsigned char> bytes;
    std::function<void(std::ostream&)> write;  ///< set for a streamed view
  };
  std::vector<Chunk> m_chunks;
  std::uint64_t m_size = 0;
};

void check(const fs::path& path, const SurfaceAnimation& s) {
  const size_t n = static_cast<size_t>(s.num_vertices), frames = s.times.size();
  if (frames == 0 || n == 0) throw_error("{}: nothing to export ({} frames of {} vertices)", path.string(), frames, n);
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

std::vector<float> quaternion(const Eigen::Quaterniond& q) {
  const Eigen::Quaterniond u = q.normalized();
  return {static_cast<float>(u.x()), static_cast<float>(u.y()), static_cast<float>(u.z()), static_cast<float>(u.w())};
}

void put_u32(std::ostream& o, std::uint32_t v) {
  const unsigned char b[4] = {static_cast<unsigned char>(v), static_cast<unsigned char>(v >> 8),
                              static_cast<unsigned char>(v >> 16), static_cast<unsigned char>(v >> 24)};
  o.write(reinterpret_cast<const char*>(b), 4);
}

/// The model's JSON as tinygltf writes it into a .glb, with the buffer's length, which the model does not hold.
std::string gltf_json(const tinygltf::Model& model, std::uint64_t buffer_bytes, const fs::path& path) {
  std::ostringstream glb;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, glb, /*prettyPrint=*/false, /*writeBinary=*/true))
    throw_error("{}: tinygltf could not serialize the model", path.string());
  // The .glb of a model without buffer data is a 12-byte header and the JSON chunk (8 bytes, then the JSON
  // padded with spaces, which the parser skips).
  const std::string bytes = std::move(glb).str();
  if (bytes.size() < 20) throw_error("{}: tinygltf wrote no JSON chunk", path.string());
  nlohmann::json j = nlohmann::json::parse(bytes.begin() + 20, bytes.end());
  j["buffers"][0]["byteLength"] = buffer_bytes;
  return j.dump();
}

/// mgcloth is z-up (gravity along −z), glTF is y-up: a rotation of −90° about x maps (x, y, z) to (x, z, −y).
Eigen::Affine3d z_up() {
  Eigen::Affine3d m = Eigen::Affine3d::Identity();
  m.linear() << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // exact, where a rotation by π/2 would leave 6e-17 in the file's data
  return m;
}

Eigen::Affine3d affine(const geometry::Pose& p) {
  Eigen::Affine3d m = Eigen::Affine3d::Identity();
  m.translate(p.translation);
  m.rotate(p.rotation);
  return m;
}

/// A node's translation, rotation and scale, leaving out those at their defaults.
void set_trs(tinygltf::Node& n, const geometry::JointTransform& t) {
  n.translation.clear();
  n.rotation.clear();
  n.scale.clear();
  n.matrix.clear();
  if (t.translation != Vec3::Zero()) n.translation = {t.translation.x(), t.translation.y(), t.translation.z()};
  const Eigen::Quaterniond q = t.rotation.normalized();
  if (q.coeffs() != Eigen::Quaterniond::Identity().coeffs()) n.rotation = {q.x(), q.y(), q.z(), q.w()};
  if (t.scale != Vec3::Ones()) n.scale = {t.scale.x(), t.scale.y(), t.scale.z()};
}

/// A node's transform: as translation, rotation and scale where `m` is one, as its matrix otherwise (shear, which
/// glTF allows on nodes that are not animated).
void set_transform(tinygltf::Node& n, const Eigen::Affine3d& m) {
  if (const auto trs = to_trs(m, 1e-9)) return set_trs(n, *trs);
  set_trs(n, {});
  const Eigen::Matrix4d a = m.matrix();
  n.matrix.assign(a.data(), a.data() + 16);  // column-major, as glTF
}

/// What write_glb and write_skinned_glb refuse in a skin: what does not validate, joints beyond JOINTS_0's unsigned
/// shorts, and key times that float rounding would merge.
void check_skin(const std::string& what, const geometry::SkinnedMesh& skin) {
  skin.validate(what);
  if (skin.num_joints() > 65536)
    throw_error("{}: {} joints, more than glTF's JOINTS_0 of unsigned shorts can name", what, skin.num_joints());
  const auto times = [&](const auto& track, const std::string& joint) {
    for (size_t k = 1; k < track.times.size(); ++k)
      if (!(static_cast<float>(track.times[k]) > static_cast<float>(track.times[k - 1])))
        throw_error("{}: joint \"{}\": key times {} and {} do not increase at float precision", what, joint,
                    track.times[k - 1], track.times[k]);
  };
  for (size_t j = 0; j < skin.tracks.size(); ++j) {
    times(skin.tracks[j].translation, skin.joint_names[j]);
    times(skin.tracks[j].rotation, skin.joint_names[j]);
    times(skin.tracks[j].scale, skin.joint_names[j]);
  }
}

/// Adds `skin` (its buffers `d`) to the model: a node per joint below node `container`, the skin, the mesh, and a
/// channel per track in `anim` (`frame_times`: the accessor of the frame times, for sampled tracks). The mesh's
/// node is returned for the caller to put at the top of the scene with no transform: glTF ignores the transform of
/// a skinned mesh's node, and viewers disagree on what they do with it (three.js binds through it).
int add_skin(ModelBuilder& b, tinygltf::Animation& anim, const geometry::SkinnedMesh& skin, const SkinBuffers& d,
             int container, const std::string& mesh_name, const std::string& node_name, int material, int frame_times) {
  std::vector<int> nodes;
  for (Index j = 0; j < skin.num_joints(); ++j) {
    tinygltf::Node n;
    n.name = skin.joint_names[static_cast<size_t>(j)];
    set_trs(n, skin.rest_local[static_cast<size_t>(j)]);
    nodes.push_back(b.node(n));
  }
  for (size_t j = 0; j < nodes.size(); ++j) {
    const int p = skin.parent[j];
    b.model.nodes[static_cast<size_t>(p < 0 ? container : nodes[static_cast<size_t>(p)])].children.push_back(nodes[j]);
  }
  tinygltf::Skin sk;
  sk.name = mesh_name;
  sk.joints = nodes;
  sk.skeleton = container;  // glTF allows any node above the joints' closest common root
  sk.inverseBindMatrices = b.floats(d.inverse_bind, 16, 0);
  b.model.skins.push_back(sk);

  tinygltf::Primitive prim;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  prim.attributes["POSITION"] = b.floats(d.positions, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
  prim.attributes["NORMAL"] = b.floats(d.normals, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
  prim.attributes["JOINTS_0"] = b.joints(d.joints);
  prim.attributes["WEIGHTS_0"] = b.floats(d.weights, 4, TINYGLTF_TARGET_ARRAY_BUFFER);
  prim.indices = b.indices(d.indices);
  prim.material = material;
  tinygltf::Mesh mesh;
  mesh.name = mesh_name;
  mesh.primitives.push_back(std::move(prim));
  tinygltf::Node node;
  node.name = node_name;
  node.mesh = static_cast<int>(b.model.meshes.size());
  node.skin = static_cast<int>(b.model.skins.size() - 1);
  b.model.meshes.push_back(std::move(mesh));

  std::vector<int> inputs(d.inputs.size(), -1);
  for (const auto& ch : d.channels) {
    int input = frame_times;
    if (ch.input >= 0) {
      int& in = inputs[static_cast<size_t>(ch.input)];
      if (in < 0) in = b.floats(d.inputs[static_cast<size_t>(ch.input)], 1, 0);
      input = in;
    }
    b.channel(anim, nodes[ch.joint], ch.path, input, b.floats(ch.output, ch.width, 0), ch.interpolation);
  }
  return b.node(node);
}

/// The morph targets of a mesh obstacle's sequence, like the surface's: its vertices at frame 0 as base positions,
/// those of frame k as target k − 1, in the obstacle's frame (its node carries its pose). Streamed like the
/// surface's targets: the obstacle's frames are interpolated again when the file is written.
tinygltf::Mesh sequence_mesh(ModelBuilder& b, const geometry::Obstacle& ob, const std::vector<double>& times,
                             const tinygltf::Value::Array& target_names, int material) {
  const auto& surface = *ob.mesh;
  const Mat3X first = surface.at(times.front());
  auto base = std::make_shared<std::vector<float>>(first.data(), first.data() + first.size());
  tinygltf::Primitive prim;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  prim.attributes["POSITION"] = b.floats(*base, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
  std::vector<std::uint32_t> idx;
  for (const Tri& t : surface.tris)
    for (Index v : t) idx.push_back(static_cast<std::uint32_t>(v));
  prim.indices = b.indices(idx);
  prim.material = material;
  const size_t n = base->size();
  const auto delta = [&surface, base, n](double t) {
    const Mat3X x = surface.at(t);
    std::vector<float> d(n);
    for (size_t i = 0; i < n; ++i) d[i] = static_cast<float>(x.data()[i]) - (*base)[i];
    return d;
  };
  for (size_t k = 1; k < times.size(); ++k) {
    const std::vector<float> d = delta(times[k]);
    auto [min, max] = ModelBuilder::bounds(d.data(), d.size(), 3);
    const int view = b.streamed_view(n * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER, [delta, t = times[k]](std::ostream& o) {
      const std::vector<float> d = delta(t);
      o.write(reinterpret_cast<const char*>(d.data()), static_cast<std::streamsize>(d.size() * sizeof(float)));
    });
    prim.targets.push_back({{"POSITION", b.float_accessor(view, n / 3, 3, std::move(min), std::move(max))}});
  }
  tinygltf::Mesh mesh;
  mesh.name = ob.name;
  mesh.primitives.push_back(std::move(prim));
  if (times.size() > 1) {
    mesh.weights.assign(times.size() - 1, 0.0);
    tinygltf::Value::Object extras;
    extras["targetNames"] = tinygltf::Value(target_names);
    mesh.extras = tinygltf::Value(std::move(extras));
  }
  return mesh;
}

/// Writes the model and its buffer as a .glb, atomically.
void write_model(const fs::path& path, const ModelBuilder& b) {
  // A .glb: a 12-byte header and two chunks (8 bytes each, then their data padded to 4 bytes), the JSON and the
  // buffer, all addressed with 32-bit lengths.
  const std::string json = gltf_json(b.model, b.buffer_bytes(), path);
  const std::uint64_t json_chunk = (json.size() + 3) / 4 * 4, bin_chunk = (b.buffer_bytes() + 3) / 4 * 4;
  const std::uint64_t total = 12 + 8 + json_chunk + (bin_chunk > 0 ? 8 + bin_chunk : 0);
  if (total > std::numeric_limits<std::uint32_t>::max())
    throw_error("{}: the animation needs {:.1f} GiB, more than a .glb can hold (4 GiB); write fewer frames with "
                "output.every",
                path.string(), static_cast<double>(total) / (1u << 30));
  write_file_atomic(
      path,
      [&](std::ostream& o) {
        o.write("glTF", 4);
        put_u32(o, 2);
        put_u32(o, static_cast<std::uint32_t>(total));
        put_u32(o, static_cast<std::uint32_t>(json_chunk));
        put_u32(o, 0x4E4F534A);  // "JSON"
        o << json << std::string(json_chunk - json.size(), ' ');
        if (bin_chunk == 0) return;
        put_u32(o, static_cast<std::uint32_t>(bin_chunk));
        put_u32(o, 0x004E4942);  // "BIN"
        b.write_buffer(o);
        o << std::string(bin_chunk - b.buffer_bytes(), '\0');
        if (o && o.tellp() != static_cast<std::streamoff>(total))
          throw_error("{}: wrote {} bytes instead of {}", path.string(), static_cast<std::int64_t>(o.tellp()), total);
      },
      /*binary=*/true);
}

}  // namespace

void write_glb(const fs::path& path, const SurfaceAnimation& surface, const std::vector<geometry::Obstacle>& obstacles) {
  const size_t values = 3 * static_cast<size_t>(surface.num_vertices);
  if (surface.positions.size() != values * surface.times.size())
    throw_error("{}: {} position values for {} frames of {} vertices", path.string(), surface.positions.size(),
                surface.times.size(), surface.num_vertices);
  write_glb(
      path, surface,
      [&](size_t k, float* out) { std::memcpy(out, surface.positions.data() + values * k, values * sizeof(float)); },
      obstacles);
}

void write_glb(const fs::path& path, const SurfaceAnimation& surface, const FrameReader& read,
               const std::vector<geometry::Obstacle>& obstacles) {
  check(path, surface);
  const size_t n = static_cast<size_t>(surface.num_vertices), frames = surface.times.size();
  // One pass over the frames for what the JSON needs before the data: the bounds of every morph target, and the
  // box around every position of every frame (sizes the planes). The base stays in memory for the deltas.
  std::vector<float> base(3 * n), x(3 * n), delta(3 * n);
  read(0, base.data());
  std::vector<std::pair<std::vector<double>, std::vector<double>>> target_bounds;
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (size_t k = 0; k < frames; ++k) {
    const float* p = base.data();
    if (k > 0) {
      read(k, x.data());
      for (size_t i = 0; i < 3 * n; ++i) delta[i] = x[i] - base[i];
      target_bounds.push_back(ModelBuilder::bounds(delta.data(), delta.size(), 3));
      p = x.data();
    }
    for (size_t i = 0; i < n; ++i) {
      const Vec3 v(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
  const Vec3 centre = 0.5 * (lo + hi);
  const double radius = 0.5 * (hi - lo).norm();

  ModelBuilder b;
  tinygltf::Animation anim;
  anim.name = "simulation";

  // mgcloth is z-up (gravity along −z), glTF is y-up: a rotation of −90° about x on the root maps (x, y, z) to
  // (x, z, −y) and leaves all data below it in simulation coordinates (z_up()).
  tinygltf::Node root;
  root.name = "z_up";
  root.rotation = {-std::sqrt(0.5), 0.0, 0.0, std::sqrt(0.5)};

  std::vector<float> times(frames);
  for (size_t k = 0; k < frames; ++k) times[k] = static_cast<float>(surface.times[k]);
  const int time_accessor = b.floats(times, 1, 0);
  // Morph target k − 1 shows frame k, on the surface and on the mesh sequences of obstacles.
  tinygltf::Value::Array names;
  for (size_t k = 1; k < frames; ++k)
    names.emplace_back(fmt::format("frame_{:05d}", surface.frame_numbers.empty() ? static_cast<int>(k) : surface.frame_numbers[k]));
  int weights = -1;  // the weights that show frame k at its time, for every mesh with a target per frame

  // The surface: frame 0 as base positions, frame k as morph target k − 1 (offsets from the base).
  {
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
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
    const size_t target_bytes = 3 * n * sizeof(float);
    for (size_t k = 1; k < frames; ++k) {
      // Runs when the file is written, after this block: what it refers to lives as long as write_glb.
      const auto write = [&read, &base, &x, &delta, k](std::ostream& o) {
        read(k, x.data());
        for (size_t i = 0; i < x.size(); ++i) delta[i] = x[i] - base[i];
        o.write(reinterpret_cast<const char*>(delta.data()), static_cast<std::streamsize>(delta.size() * sizeof(float)));
      };
      const int view = b.streamed_view(target_bytes, TINYGLTF_TARGET_ARRAY_BUFFER, write);
      auto& [min, max] = target_bounds[k - 1];
      prim.targets.push_back({{"POSITION", b.float_accessor(view, n, 3, std::move(min), std::move(max))}});
    }
    mesh.primitives.push_back(std::move(prim));
    if (frames > 1) {
      mesh.weights.assign(frames - 1, 0.0);
      // Blender names the shape keys, three.js the morphTargetDictionary entries, from extras.targetNames.
      tinygltf::Value::Object extras;
      extras["targetNames"] = tinygltf::Value(names);
      mesh.extras = tinygltf::Value(std::move(extras));
      // Frame k (k ≥ 1) shows target k − 1 alone; the output is frames × targets weights, so it grows
      // quadratically with the frame count (output.every keeps long runs small). Written a frame at a time.
      const size_t targets = frames - 1;
      const int view = b.streamed_view(frames * targets * sizeof(float), 0, [frames, targets](std::ostream& o) {
        std::vector<float> row(targets, 0.0f);
        for (size_t k = 0; k < frames; ++k) {
          if (k > 0) row[k - 1] = 1.0f;
          o.write(reinterpret_cast<const char*>(row.data()), static_cast<std::streamsize>(targets * sizeof(float)));
          if (k > 0) row[k - 1] = 0.0f;
        }
      });
      // Frame 0's row is all zeros and frame 1's holds a one.
      weights = b.float_accessor(view, frames * targets, 1, {0.0}, {1.0});
    }
    tinygltf::Node node;
    node.name = "cloth";
    node.mesh = static_cast<int>(b.model.meshes.size());
    b.model.meshes.push_back(std::move(mesh));
    const int cloth_node = b.node(node);
    root.children.push_back(cloth_node);
    if (frames > 1) b.channel(anim, cloth_node, "weights", time_accessor, weights);
  }

  // Obstacles: a node per obstacle, posed at the first frame, with its poses at every frame as STEP channels when
  // it moves. A mesh sequence morphs like the surface; a skinned mesh hangs its skeleton from the obstacle's node
  // (through a node for its placement), and its mesh's node sits at the top of the scene.
  const int obstacle_material = obstacles.empty() ? -1 : b.material("obstacle", {0.6, 0.6, 0.65}, /*double_sided=*/false);
  std::vector<int> skinned_nodes;
  for (const auto& ob : obstacles) {
    const geometry::Pose first = ob.motion ? ob.motion->pose(surface.times.front()) : geometry::Pose{};
    tinygltf::Node node;
    node.name = ob.name;
    if (is_sequence(ob)) {
      node.mesh = static_cast<int>(b.model.meshes.size());
      b.model.meshes.push_back(sequence_mesh(b, ob, surface.times, names, obstacle_material));
    } else if (!is_skinned(ob)) {
      const ShapeMesh shape = obstacle_shape(path, ob, first.to_local(centre), radius);
      tinygltf::Primitive prim;
      prim.mode = TINYGLTF_MODE_TRIANGLES;
      prim.attributes["POSITION"] = b.floats(shape.positions, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
      prim.attributes["NORMAL"] = b.floats(shape.normals, 3, TINYGLTF_TARGET_ARRAY_BUFFER);
      prim.indices = b.indices(shape.indices);
      prim.material = obstacle_material;
      tinygltf::Mesh mesh;
      mesh.name = ob.name;
      mesh.primitives.push_back(std::move(prim));
      node.mesh = static_cast<int>(b.model.meshes.size());
      b.model.meshes.push_back(std::move(mesh));
    }
    node.translation = {first.translation.x(), first.translation.y(), first.translation.z()};
    const auto q0 = quaternion(first.rotation);
    node.rotation.assign(q0.begin(), q0.end());
    const int index = b.node(node);
    root.children.push_back(index);
    if (is_sequence(ob) && frames > 1) b.channel(anim, index, "weights", time_accessor, weights);
    if (is_skinned(ob)) {
      const auto& skin = *ob.mesh->skin;
      check_skin(fmt::format("{}: obstacle \"{}\"", path.string(), ob.name), skin);
      int container = index;
      if (!skin.placement.matrix().isIdentity(0.0)) {
        tinygltf::Node placement;
        placement.name = ob.name + "_placement";
        set_transform(placement, skin.placement);
        container = b.node(placement);
        b.model.nodes[static_cast<size_t>(index)].children.push_back(container);
      }
      const SkinBuffers d = skin_buffers(skin, z_up() * affine(first) * skin.placement, loops(ob) ? &surface.times : nullptr);
      skinned_nodes.push_back(add_skin(b, anim, skin, d, container, ob.name, ob.name + "_skin", obstacle_material, time_accessor));
    }
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
  scene.nodes.insert(scene.nodes.end(), skinned_nodes.begin(), skinned_nodes.end());
  b.model.scenes.push_back(scene);
  b.model.defaultScene = 0;
  if (!anim.channels.empty()) b.model.animations.push_back(std::move(anim));
  b.model.buffers[0].name = "data";

  write_model(path, b);
}

void write_skinned_glb(const fs::path& file, const geometry::SkinnedMesh& skin, const SkinWriteOptions& opt) {
  check_skin(file.string(), skin);
  ModelBuilder b;
  // The root turns z-up into y-up after the skin's placement, so that the joints below it are the skin's own.
  const Eigen::Affine3d top = z_up() * skin.placement;
  tinygltf::Node root;
  root.name = "z_up";
  set_transform(root, top);
  const int root_index = b.node(root);
  tinygltf::Animation anim;
  anim.name = opt.animation;
  const int material = b.material(opt.material, opt.colour, /*double_sided=*/false);
  const int mesh_node = add_skin(b, anim, skin, skin_buffers(skin, top, nullptr), root_index, opt.name, opt.name, material, -1);
  tinygltf::Scene scene;
  scene.name = opt.name;
  scene.nodes = {root_index, mesh_node};
  b.model.scenes.push_back(scene);
  b.model.defaultScene = 0;
  if (!anim.channels.empty()) b.model.animations.push_back(std::move(anim));
  b.model.buffers[0].name = "data";
  write_model(file, b);
}

#else
bool glb_available() { return false; }

void write_skinned_glb(const fs::path& file, const geometry::SkinnedMesh&, const SkinWriteOptions&) {
  throw_error("{}: this build of mgcloth has no glTF support (configured without libtinygltf-dev; install it and "
              "re-run cmake)",
              file.string());
}

void write_glb(const fs::path& path, const SurfaceAnimation&, const std::vector<geometry::Obstacle>&) {
  throw_error("{}: this build of mgcloth has no glTF export (configured without libtinygltf-dev; install it and "
              "re-run cmake)",
              path.string());
}

void write_glb(const fs::path& path, const SurfaceAnimation&, const FrameReader&, const std::vector<geometry::Obstacle>&) {
  throw_error("{}: this build of mgcloth has no glTF export (configured without libtinygltf-dev; install it and "
              "re-run cmake)",
              path.string());
}
#endif

}  // namespace mgcloth::sim
