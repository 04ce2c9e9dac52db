// Reading skinned meshes from glTF. Their writing (write_skinned_glb) is in gltf_export.cpp, which builds every
// glb this library writes.
#include <mgcloth/core/error.hpp>
#include <mgcloth/sim/gltf_skin.hpp>

#ifdef MGCLOTH_HAVE_GLTF
// Debian's libtinygltf-dev ships the implementation compiled (libtinygltf.so), so no TINYGLTF_IMPLEMENTATION here.
#include <tiny_gltf.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <optional>
#include <unordered_map>

namespace mgcloth::sim {

namespace fs = std::filesystem;

std::optional<geometry::JointTransform> to_trs(const Eigen::Affine3d& m, double tolerance) {
  const Mat3 l = m.linear();
  Vec3 s(l.col(0).norm(), l.col(1).norm(), l.col(2).norm());
  if (!m.matrix().allFinite() || !(s.minCoeff() > 0.0)) return std::nullopt;
  Mat3 r = l * s.cwiseInverse().asDiagonal();
  // A mirror is a negative scale, which glTF allows; a rotation cannot hold it.
  if (r.determinant() < 0.0) {
    s.x() = -s.x();
    r.col(0) = -r.col(0);
  }
  if ((r.transpose() * r - Mat3::Identity()).norm() > tolerance) return std::nullopt;
  geometry::JointTransform trs;
  trs.translation = m.translation();
  trs.rotation = Eigen::Quaterniond(r).normalized();
  trs.scale = s;
  return trs;
}

#ifdef MGCLOTH_HAVE_GLTF

namespace {

using geometry::Interpolation;
using geometry::JointTransform;
using geometry::SkinnedMesh;

const char* type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    case TINYGLTF_TYPE_MAT2: return "MAT2";
    case TINYGLTF_TYPE_MAT3: return "MAT3";
    case TINYGLTF_TYPE_MAT4: return "MAT4";
    default: return "an unknown type";
  }
}

const char* component_name(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT: return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_INT: return "INT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return "FLOAT";
    case TINYGLTF_COMPONENT_TYPE_DOUBLE: return "DOUBLE";
    default: return "an unknown component type";
  }
}

const char* mode_name(int mode) {
  switch (mode) {
    case TINYGLTF_MODE_POINTS: return "POINTS";
    case TINYGLTF_MODE_LINE: return "LINES";
    case TINYGLTF_MODE_LINE_LOOP: return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP: return "LINE_STRIP";
    case TINYGLTF_MODE_TRIANGLES: return "TRIANGLES";
    case TINYGLTF_MODE_TRIANGLE_STRIP: return "TRIANGLE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_FAN: return "TRIANGLE_FAN";
    default: return "unknown";
  }
}

/// A component of `type` at `p` as a double, mapped to [0, 1] or [−1, 1] when `normalized` (glTF 2.0 3.11).
double component(const unsigned char* p, int type, bool normalized) {
  const auto get = [p](auto v) {
    std::memcpy(&v, p, sizeof v);
    return v;
  };
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const double v = get(std::int8_t{});
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
      const double v = get(std::uint8_t{});
      return normalized ? v / 255.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      const double v = get(std::int16_t{});
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      const double v = get(std::uint16_t{});
      return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return get(std::uint32_t{});
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return get(float{});
    default: return 0.0;
  }
}

/// The model of one file, read with the file's name at hand for every message.
class GltfFile {
 public:
  GltfFile(const fs::path& file, tinygltf::Model model) : m_file(file.string()), m(std::move(model)) {}

  template <class... Args>
  [[noreturn]] void fail(fmt::format_string<Args...> format, Args&&... args) const {
    throw InputError(m_file + ": " + fmt::format(format, std::forward<Args>(args)...));
  }

  const std::string& file() const { return m_file; }
  const tinygltf::Model& model() const { return m; }

  std::string mesh_label(int mesh) const {
    const auto& name = m.meshes[static_cast<size_t>(mesh)].name;
    return name.empty() ? fmt::format("mesh {}", mesh) : fmt::format("mesh {} (\"{}\")", mesh, name);
  }
  std::string node_label(int node) const {
    const auto& name = m.nodes[static_cast<size_t>(node)].name;
    return name.empty() ? fmt::format("node {}", node) : fmt::format("node {} (\"{}\")", node, name);
  }
  std::string animation_label(int anim) const {
    const auto& name = m.animations[static_cast<size_t>(anim)].name;
    return name.empty() ? fmt::format("animation {}", anim) : fmt::format("animation {} (\"{}\")", anim, name);
  }

  /// The values of accessor `index`, its components in order, as doubles. Integer components are normalized when
  /// the accessor says so or `normalize` is set. `what` names the use for messages ("mesh 0 primitive 1 POSITION").
  std::vector<double> read(int index, const std::string& what, std::initializer_list<int> types,
                           std::initializer_list<int> components, bool normalize = false) const {
    if (index < 0 || static_cast<size_t>(index) >= m.accessors.size())
      fail("{}: accessor {} does not exist ({} accessors)", what, index, m.accessors.size());
    const auto& a = m.accessors[static_cast<size_t>(index)];
    if (std::find(types.begin(), types.end(), a.type) == types.end())
      fail("{}: accessor {} is {}, not {}", what, index, type_name(a.type), type_name(*types.begin()));
    if (std::find(components.begin(), components.end(), a.componentType) == components.end())
      fail("{}: accessor {} has components of {}", what, index, component_name(a.componentType));
    const size_t width = static_cast<size_t>(tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(a.type)));
    const size_t size = static_cast<size_t>(tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(a.componentType)));
    const bool norm = normalize || a.normalized;
    std::vector<double> out;
    if (a.bufferView >= 0) {
      const auto [data, length] = view(a.bufferView, what, index);
      const size_t stride = m.bufferViews[static_cast<size_t>(a.bufferView)].byteStride
                                ? m.bufferViews[static_cast<size_t>(a.bufferView)].byteStride
                                : width * size;
      // Every element takes a byte at least, so a count beyond the view's length is out of range and the product
      // below cannot overflow.
      if (a.count > length || (a.count > 0 && a.byteOffset + (a.count - 1) * stride + width * size > length))
        fail("{}: accessor {} ({} elements from byte {}) runs past the end of its buffer view {} ({} bytes)", what,
             index, a.count, a.byteOffset, a.bufferView, length);
      out.resize(a.count * width);
      for (size_t i = 0; i < a.count; ++i)
        for (size_t c = 0; c < width; ++c)
          out[i * width + c] = component(data + a.byteOffset + i * stride + c * size, a.componentType, norm);
    } else {
      out.assign(a.count * width, 0.0);  // glTF: an accessor without a view holds zeros (before its sparse values)
    }
    if (a.sparse.isSparse) {
      const auto n = static_cast<size_t>(std::max(a.sparse.count, 0));
      const int itype = a.sparse.indices.componentType;
      if (itype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && itype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
          itype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
        fail("{}: accessor {}: sparse indices of {}", what, index, component_name(itype));
      const size_t isize = static_cast<size_t>(tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(itype)));
      const auto [idata, ilength] = view(a.sparse.indices.bufferView, what, index);
      const auto [vdata, vlength] = view(a.sparse.values.bufferView, what, index);
      const auto ioffset = static_cast<size_t>(std::max(a.sparse.indices.byteOffset, 0));
      const auto voffset = static_cast<size_t>(std::max(a.sparse.values.byteOffset, 0));
      if (n > ilength || ioffset + n * isize > ilength || n > vlength || voffset + n * width * size > vlength)
        fail("{}: accessor {}: its {} sparse values run past the end of their buffer views", what, index, n);
      for (size_t k = 0; k < n; ++k) {
        const auto i = static_cast<size_t>(component(idata + ioffset + k * isize, itype, false));
        if (i >= a.count) fail("{}: accessor {}: sparse index {} of {} elements", what, index, i, a.count);
        for (size_t c = 0; c < width; ++c)
          out[i * width + c] = component(vdata + voffset + (k * width + c) * size, a.componentType, norm);
      }
    }
    return out;
  }

  size_t count(int accessor) const { return m.accessors[static_cast<size_t>(accessor)].count; }

 private:
  /// The bytes of buffer view `index` and their number, checked to lie in their buffer.
  std::pair<const unsigned char*, size_t> view(int index, const std::string& what, int accessor) const {
    if (index < 0 || static_cast<size_t>(index) >= m.bufferViews.size())
      fail("{}: accessor {}: buffer view {} does not exist ({} views)", what, accessor, index, m.bufferViews.size());
    const auto& v = m.bufferViews[static_cast<size_t>(index)];
    if (v.buffer < 0 || static_cast<size_t>(v.buffer) >= m.buffers.size())
      fail("{}: accessor {}: buffer view {} names buffer {} of {}", what, accessor, index, v.buffer, m.buffers.size());
    const auto& data = m.buffers[static_cast<size_t>(v.buffer)].data;
    if (v.byteOffset > data.size() || v.byteLength > data.size() - v.byteOffset)
      fail("{}: accessor {}: buffer view {} ({} bytes from byte {}) runs past the end of buffer {} ({} bytes)", what,
           accessor, index, v.byteLength, v.byteOffset, v.buffer, data.size());
    return {data.data() + v.byteOffset, v.byteLength};
  }

  std::string m_file;
  tinygltf::Model m;
};

tinygltf::Model load(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throw_error<InputError>("{}: no such file", file.string());
  char magic[4] = {};
  {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw_error<InputError>("{}: cannot open the file", file.string());
    in.read(magic, 4);
  }
  tinygltf::TinyGLTF loader;
  // Only the geometry and the animation are read: decoding the textures would cost time for nothing.
  loader.SetImageLoader([](tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*,
                           int, void*) { return true; },
                        nullptr);
  tinygltf::Model model;
  std::string err, warn;
  bool ok = false;
  try {
    ok = std::memcmp(magic, "glTF", 4) == 0 ? loader.LoadBinaryFromFile(&model, &err, &warn, file.string())
                                             : loader.LoadASCIIFromFile(&model, &err, &warn, file.string());
  } catch (const std::exception& e) {
    err = e.what();
  }
  while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
  if (!ok) throw_error<InputError>("{}: not a glTF 2.0 file that can be read: {}", file.string(), err.empty() ? "(no reason given)" : err);
  return model;
}

Eigen::Affine3d node_matrix(const GltfFile& g, int index);

/// A node's local transform as translation, rotation and scale (its matrix decomposed).
JointTransform node_trs(const GltfFile& g, int index) {
  const auto& n = g.model().nodes[static_cast<size_t>(index)];
  if (!n.matrix.empty()) {
    // Exporters write matrices from float data: allow their rounding, not a real shear.
    const auto trs = to_trs(node_matrix(g, index), 1e-4);
    if (!trs)
      g.fail("{}: its matrix has shear or a zero scale, which a joint's translation, rotation and scale cannot hold",
             g.node_label(index));
    return *trs;
  }
  JointTransform t;
  const auto sized = [&](const std::vector<double>& v, size_t size, const char* what) {
    if (!v.empty() && v.size() != size) g.fail("{}: {} has {} numbers, not {}", g.node_label(index), what, v.size(), size);
    return !v.empty();
  };
  if (sized(n.translation, 3, "translation")) t.translation = Vec3(n.translation[0], n.translation[1], n.translation[2]);
  if (sized(n.rotation, 4, "rotation")) {
    const Eigen::Quaterniond q(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);
    if (!(q.norm() > 0.0)) g.fail("{}: its rotation is the zero quaternion", g.node_label(index));
    t.rotation = q.normalized();
  }
  if (sized(n.scale, 3, "scale")) t.scale = Vec3(n.scale[0], n.scale[1], n.scale[2]);
  if (!t.translation.allFinite() || !t.rotation.coeffs().allFinite() || !t.scale.allFinite())
    g.fail("{}: its translation, rotation or scale is not finite", g.node_label(index));
  return t;
}

/// A node's local transform as a matrix (any affine matrix where the node has one).
Eigen::Affine3d node_matrix(const GltfFile& g, int index) {
  const auto& n = g.model().nodes[static_cast<size_t>(index)];
  if (n.matrix.empty()) return node_trs(g, index).matrix();
  if (n.matrix.size() != 16) g.fail("{}: its matrix has {} numbers, not 16", g.node_label(index), n.matrix.size());
  const Eigen::Matrix4d a = Eigen::Map<const Eigen::Matrix4d>(n.matrix.data());  // glTF: column-major
  if (!a.allFinite() || !a.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)))
    g.fail("{}: its matrix is not a finite affine transform", g.node_label(index));
  Eigen::Affine3d m;
  m.matrix() = a;
  return m;
}

struct PositionHash {
  size_t operator()(const std::array<double, 3>& p) const {
    size_t h = 0;
    for (double c : p) h = h * 1000003u ^ std::hash<double>()(c);
    return h;
  }
};

/// Names of the meshes or animations, for the message of a name that is not among them.
template <class T>
std::string names_of(const std::vector<T>& items) {
  std::string out;
  for (size_t i = 0; i < items.size(); ++i) {
    if (i == 8) return out + ", …";
    out += (i ? ", \"" : "\"") + items[i].name + "\"";
  }
  return out.empty() ? "none" : out;
}

/// The keys of one animation sampler as a Track of N components.
template <int N>
geometry::Track<N> make_track(const GltfFile& g, const std::string& what, Interpolation interpolation,
                              const std::vector<double>& times, const std::vector<double>& values) {
  geometry::Track<N> t;
  t.interpolation = interpolation;
  t.times = times;
  const auto value = [&](size_t i) { return typename geometry::Track<N>::Value(values.data() + N * i); };
  for (size_t k = 0; k < times.size(); ++k) {
    if (interpolation == Interpolation::CubicSpline) {
      // glTF 2.0 Appendix C: each key's output is its in-tangent, its value, its out-tangent.
      t.in_tangents.push_back(value(3 * k));
      t.values.push_back(value(3 * k + 1));
      t.out_tangents.push_back(value(3 * k + 2));
    } else {
      t.values.push_back(value(k));
    }
  }
  if constexpr (N == 4) {
    for (const auto& q : t.values)
      if (!(q.norm() > 0.0)) g.fail("{}: a rotation key is the zero quaternion", what);
  }
  return t;
}

}  // namespace

geometry::SkinnedMesh read_skinned_gltf(const fs::path& file, const SkinReadOptions& opt) {
  if (!(opt.scale > 0.0) || !std::isfinite(opt.scale))
    throw_error<InputError>("{}: scale {} is not a positive number", file.string(), opt.scale);
  const GltfFile g(file, load(file));
  const tinygltf::Model& m = g.model();
  const size_t num_nodes = m.nodes.size();

  std::vector<int> parent(num_nodes, -1);
  for (size_t i = 0; i < num_nodes; ++i)
    for (int c : m.nodes[i].children) {
      if (c < 0 || static_cast<size_t>(c) >= num_nodes)
        g.fail("{}: child {} does not exist ({} nodes)", g.node_label(static_cast<int>(i)), c, num_nodes);
      if (parent[static_cast<size_t>(c)] >= 0)
        g.fail("{} is a child of both node {} and node {}", g.node_label(c), parent[static_cast<size_t>(c)], i);
      parent[static_cast<size_t>(c)] = static_cast<int>(i);
    }
  for (size_t i = 0; i < num_nodes; ++i) {
    const auto& n = m.nodes[i];
    if (n.mesh >= static_cast<int>(m.meshes.size()))
      g.fail("{}: mesh {} does not exist ({} meshes)", g.node_label(static_cast<int>(i)), n.mesh, m.meshes.size());
    if (n.skin >= static_cast<int>(m.skins.size()))
      g.fail("{}: skin {} does not exist ({} skins)", g.node_label(static_cast<int>(i)), n.skin, m.skins.size());
  }
  // The chain of nodes from `node` up to its scene root, itself first.
  const auto ancestry = [&](int node) {
    std::vector<int> chain;
    for (int k = node; k >= 0; k = parent[static_cast<size_t>(k)]) {
      if (chain.size() == num_nodes) g.fail("{} is its own ancestor: the node hierarchy has a cycle", g.node_label(node));
      chain.push_back(k);
    }
    return chain;
  };

  // The mesh, and the node that instances it (with a skin where one does).
  int mesh_index = -1, node_index = -1;
  const auto instancing = [&](int mesh, bool skinned) {
    for (size_t i = 0; i < num_nodes; ++i)
      if ((mesh < 0 ? m.nodes[i].mesh >= 0 : m.nodes[i].mesh == mesh) && (m.nodes[i].skin >= 0) == skinned)
        return static_cast<int>(i);
    return -1;
  };
  if (!opt.mesh.empty()) {
    for (size_t i = 0; i < m.meshes.size() && mesh_index < 0; ++i)
      if (m.meshes[i].name == opt.mesh) mesh_index = static_cast<int>(i);
    if (mesh_index < 0) g.fail("no mesh named \"{}\" (meshes: {})", opt.mesh, names_of(m.meshes));
    node_index = instancing(mesh_index, true);
    if (node_index < 0) node_index = instancing(mesh_index, false);
  } else {
    node_index = instancing(-1, true);
    if (node_index < 0) node_index = instancing(-1, false);
    if (node_index >= 0) mesh_index = m.nodes[static_cast<size_t>(node_index)].mesh;
    else if (!m.meshes.empty()) mesh_index = 0;
    else g.fail("the file has no mesh");
  }
  const bool skinned = node_index >= 0 && m.nodes[static_cast<size_t>(node_index)].skin >= 0;

  geometry::SkinnedMesh out;
  // The skeleton: the skin's joints and the nodes above them, parents first (slot: a node's joint index, or −1).
  std::vector<int> slot(num_nodes, -1), order, joint_slot;
  if (skinned) {
    const int skin_index = m.nodes[static_cast<size_t>(node_index)].skin;
    const auto& skin = m.skins[static_cast<size_t>(skin_index)];
    const std::string skin_label =
        skin.name.empty() ? fmt::format("skin {}", skin_index) : fmt::format("skin {} (\"{}\")", skin_index, skin.name);
    if (skin.joints.empty()) g.fail("{} has no joints", skin_label);
    for (int joint : skin.joints) {
      if (joint < 0 || static_cast<size_t>(joint) >= num_nodes)
        g.fail("{}: joint node {} does not exist ({} nodes)", skin_label, joint, num_nodes);
      if (slot[static_cast<size_t>(joint)] >= 0 &&
          std::find(joint_slot.begin(), joint_slot.end(), slot[static_cast<size_t>(joint)]) != joint_slot.end())
        g.fail("{}: {} is listed twice among its joints", skin_label, g.node_label(joint));
      const auto chain = ancestry(joint);
      for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
        if (slot[static_cast<size_t>(*it)] >= 0) continue;
        slot[static_cast<size_t>(*it)] = static_cast<int>(order.size());
        order.push_back(*it);
      }
      joint_slot.push_back(slot[static_cast<size_t>(joint)]);
    }
    for (int n : order) {
      const auto& node = m.nodes[static_cast<size_t>(n)];
      out.joint_names.push_back(node.name.empty() ? fmt::format("node{}", n) : node.name);
      const int p = parent[static_cast<size_t>(n)];
      out.parent.push_back(p < 0 ? -1 : slot[static_cast<size_t>(p)]);
      out.rest_local.push_back(node_trs(g, n));
      out.inverse_bind.push_back(Eigen::Affine3d::Identity());
    }
    if (skin.inverseBindMatrices >= 0) {
      const auto ibm = g.read(skin.inverseBindMatrices, skin_label + " inverseBindMatrices", {TINYGLTF_TYPE_MAT4},
                              {TINYGLTF_COMPONENT_TYPE_FLOAT});
      if (ibm.size() < 16 * skin.joints.size())
        g.fail("{}: {} inverse bind matrices for {} joints", skin_label, ibm.size() / 16, skin.joints.size());
      for (size_t i = 0; i < skin.joints.size(); ++i) {
        Eigen::Affine3d b;
        b.matrix() = Eigen::Map<const Eigen::Matrix4d>(ibm.data() + 16 * i);
        out.inverse_bind[static_cast<size_t>(joint_slot[i])] = b;
      }
    }
  } else {
    const std::string& name = node_index >= 0 ? m.nodes[static_cast<size_t>(node_index)].name
                                              : m.meshes[static_cast<size_t>(mesh_index)].name;
    out.joint_names.push_back(name.empty() ? "root" : name);
    out.parent.push_back(-1);
    out.rest_local.emplace_back();
    out.inverse_bind.push_back(Eigen::Affine3d::Identity());
  }
  out.tracks.resize(out.joint_names.size());

  // The vertices: every primitive's, welded by position into one list.
  const auto& mesh = m.meshes[static_cast<size_t>(mesh_index)];
  if (mesh.primitives.empty()) g.fail("{} has no primitives", g.mesh_label(mesh_index));
  std::unordered_map<std::array<double, 3>, Index, PositionHash> welded;
  std::vector<Vec3> positions;
  std::vector<Eigen::Vector4i> joints;
  std::vector<Eigen::Vector4d> weights;
  const size_t skin_joints = joint_slot.size();
  for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
    const auto& prim = mesh.primitives[pi];
    const std::string what = fmt::format("{} primitive {}", g.mesh_label(mesh_index), pi);
    if (prim.mode != -1 && prim.mode != TINYGLTF_MODE_TRIANGLES)
      g.fail("{}: mode {} ({}), not TRIANGLES", what, prim.mode, mode_name(prim.mode));
    const auto pos_it = prim.attributes.find("POSITION");
    if (pos_it == prim.attributes.end()) g.fail("{} has no POSITION", what);
    const auto pos = g.read(pos_it->second, what + " POSITION", {TINYGLTF_TYPE_VEC3}, {TINYGLTF_COMPONENT_TYPE_FLOAT});
    const size_t nv = pos.size() / 3;
    std::vector<size_t> index;
    if (prim.indices >= 0) {
      for (double i : g.read(prim.indices, what + " indices", {TINYGLTF_TYPE_SCALAR},
                             {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                              TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT})) {
        if (i >= static_cast<double>(nv)) g.fail("{}: index {} of {} vertices", what, i, nv);
        index.push_back(static_cast<size_t>(i));
      }
    } else {
      for (size_t i = 0; i < nv; ++i) index.push_back(i);
    }
    if (index.size() % 3 != 0) g.fail("{}: {} vertex indices, not whole triangles", what, index.size());

    // Influence sets JOINTS_k / WEIGHTS_k, k = 0, 1, …
    std::vector<std::pair<std::vector<double>, std::vector<double>>> sets;
    for (int k = 0; skinned; ++k) {
      const std::string js = fmt::format("JOINTS_{}", k), ws = fmt::format("WEIGHTS_{}", k);
      const auto j_it = prim.attributes.find(js), w_it = prim.attributes.find(ws);
      if (j_it == prim.attributes.end() && w_it == prim.attributes.end()) break;
      if (j_it == prim.attributes.end() || w_it == prim.attributes.end())
        g.fail("{} has {} without {}", what, j_it == prim.attributes.end() ? ws : js,
               j_it == prim.attributes.end() ? js : ws);
      auto jv = g.read(j_it->second, what + " " + js, {TINYGLTF_TYPE_VEC4},
                       {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT});
      // Integer weights are fractions of their range (glTF requires them normalized); the sum is renormalized below.
      auto wv = g.read(w_it->second, what + " " + ws, {TINYGLTF_TYPE_VEC4},
                       {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                        TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
                       /*normalize=*/true);
      if (jv.size() != 4 * nv || wv.size() != 4 * nv)
        g.fail("{}: {} and {} have {} and {} elements for {} vertices", what, js, ws, jv.size() / 4, wv.size() / 4, nv);
      sets.emplace_back(std::move(jv), std::move(wv));
    }
    if (skinned && sets.empty())
      g.fail("{} has no JOINTS_0 and WEIGHTS_0, but {} gives it a skin", what, g.node_label(node_index));

    std::vector<Index> global(nv, -1);
    const auto add = [&](size_t v) {
      if (global[v] >= 0) return global[v];
      // + 0.0 turns −0 into +0, the same position.
      const std::array<double, 3> key{pos[3 * v] + 0.0, pos[3 * v + 1] + 0.0, pos[3 * v + 2] + 0.0};
      const auto [it, inserted] = welded.try_emplace(key, static_cast<Index>(positions.size()));
      global[v] = it->second;
      if (!inserted) return global[v];
      positions.emplace_back(key[0], key[1], key[2]);
      Eigen::Vector4i jv = Eigen::Vector4i::Zero();
      Eigen::Vector4d wv(1.0, 0.0, 0.0, 0.0);
      if (skinned) {
        std::vector<std::pair<double, int>> influence;  // (weight, skin joint), one per joint
        for (const auto& [js, ws] : sets)
          for (size_t c = 0; c < 4; ++c) {
            const double w = ws[4 * v + c];
            if (!std::isfinite(w) || w < 0.0) g.fail("{}: vertex {}: weight {} is negative or not finite", what, v, w);
            if (w == 0.0) continue;
            const auto j = static_cast<size_t>(js[4 * v + c]);
            if (j >= skin_joints) g.fail("{}: vertex {}: joint {} of the skin's {} joints", what, v, j, skin_joints);
            const int joint = joint_slot[j];
            auto same = std::find_if(influence.begin(), influence.end(), [&](const auto& i) { return i.second == joint; });
            if (same != influence.end()) same->first += w;
            else influence.emplace_back(w, joint);
          }
        if (influence.empty()) g.fail("{}: vertex {} has no weight (all its weights are 0)", what, v);
        std::stable_sort(influence.begin(), influence.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
        if (influence.size() > 4) influence.resize(4);
        double sum = 0.0;
        for (const auto& i : influence) sum += i.first;
        wv.setZero();
        for (size_t i = 0; i < influence.size(); ++i) {
          wv[static_cast<Index>(i)] = influence[i].first / sum;
          jv[static_cast<Index>(i)] = influence[i].second;
        }
      }
      joints.push_back(jv);
      weights.push_back(wv);
      return global[v];
    };
    // In the accessor's order, so that a file written from a mesh gives its vertices back in their order.
    std::vector<bool> used(nv, false);
    for (size_t i : index) used[i] = true;
    for (size_t v = 0; v < nv; ++v)
      if (used[v]) add(v);
    for (size_t t = 0; t + 2 < index.size(); t += 3) {
      const Tri tri{add(index[t]), add(index[t + 1]), add(index[t + 2])};
      // Welding collapses triangles whose corners share a position: they have no area to touch.
      if (tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2]) out.tris.push_back(tri);
    }
  }
  if (out.tris.empty()) g.fail("{} has no triangles", g.mesh_label(mesh_index));

  const auto nv = static_cast<Index>(positions.size());
  out.rest.resize(3, nv);
  out.joints.resize(4, nv);
  out.weights.resize(4, nv);
  for (Index v = 0; v < nv; ++v) {
    out.rest.col(v) = positions[static_cast<size_t>(v)];
    out.joints.col(v) = joints[static_cast<size_t>(v)];
    out.weights.col(v) = weights[static_cast<size_t>(v)];
  }
  if (!skinned && node_index >= 0) {
    // glTF ignores a skinned mesh's node transform, but places a static mesh by its node.
    Eigen::Affine3d world = Eigen::Affine3d::Identity();
    for (int n : ancestry(node_index)) world = node_matrix(g, n) * world;
    out.rest = world * out.rest;
  }

  // The animation.
  int anim_index = -1;
  const auto animates_skeleton = [&](const tinygltf::Animation& a) {
    for (const auto& c : a.channels)
      if (c.target_node >= 0 && static_cast<size_t>(c.target_node) < num_nodes &&
          slot[static_cast<size_t>(c.target_node)] >= 0 && c.target_path != "weights")
        return true;
    return false;
  };
  if (!opt.animation.empty()) {
    for (size_t i = 0; i < m.animations.size() && anim_index < 0; ++i)
      if (m.animations[i].name == opt.animation) anim_index = static_cast<int>(i);
    if (anim_index < 0) g.fail("no animation named \"{}\" (animations: {})", opt.animation, names_of(m.animations));
  } else if (skinned) {
    // A file may hold several characters: the first animation that moves this one.
    for (size_t i = 0; i < m.animations.size() && anim_index < 0; ++i)
      if (animates_skeleton(m.animations[i])) anim_index = static_cast<int>(i);
  }
  if (skinned && anim_index >= 0) {
    const auto& anim = m.animations[static_cast<size_t>(anim_index)];
    for (size_t ci = 0; ci < anim.channels.size(); ++ci) {
      const auto& c = anim.channels[ci];
      const std::string& path = c.target_path;
      if (path != "translation" && path != "rotation" && path != "scale") continue;  // morph weights, extensions
      if (c.target_node < 0) continue;  // targets something other than a node (an extension's pointer)
      if (static_cast<size_t>(c.target_node) >= num_nodes)
        g.fail("{} channel {}: node {} does not exist ({} nodes)", g.animation_label(anim_index), ci, c.target_node, num_nodes);
      const int joint = slot[static_cast<size_t>(c.target_node)];
      if (joint < 0) continue;  // moves a node that does not move this mesh
      const std::string what =
          fmt::format("{} channel {} ({} of {})", g.animation_label(anim_index), ci, path, g.node_label(c.target_node));
      if (c.sampler < 0 || static_cast<size_t>(c.sampler) >= anim.samplers.size())
        g.fail("{}: sampler {} does not exist ({} samplers)", what, c.sampler, anim.samplers.size());
      const auto& s = anim.samplers[static_cast<size_t>(c.sampler)];
      Interpolation interpolation = Interpolation::Linear;
      if (s.interpolation == "STEP") interpolation = Interpolation::Step;
      else if (s.interpolation == "CUBICSPLINE") interpolation = Interpolation::CubicSpline;
      else if (s.interpolation != "LINEAR" && !s.interpolation.empty())
        g.fail("{}: interpolation \"{}\" is not LINEAR, STEP or CUBICSPLINE", what, s.interpolation);
      const auto times = g.read(s.input, what + " input", {TINYGLTF_TYPE_SCALAR}, {TINYGLTF_COMPONENT_TYPE_FLOAT});
      const bool rotation = path == "rotation";
      const auto values =
          rotation ? g.read(s.output, what + " output", {TINYGLTF_TYPE_VEC4},
                            {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                             TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT})
                   : g.read(s.output, what + " output", {TINYGLTF_TYPE_VEC3}, {TINYGLTF_COMPONENT_TYPE_FLOAT});
      const size_t per_key = (interpolation == Interpolation::CubicSpline ? 3 : 1) * (rotation ? 4 : 3);
      if (values.size() != times.size() * per_key)
        g.fail("{}: {} keys but {} output values{}", what, times.size(), values.size() / (rotation ? 4 : 3),
               interpolation == Interpolation::CubicSpline ? " (CUBICSPLINE needs 3 per key)" : "");
      if (times.empty()) continue;
      auto& tracks = out.tracks[static_cast<size_t>(joint)];
      // Two channels on one property: the first wins, as in most viewers.
      if (path == "translation" && tracks.translation.empty())
        tracks.translation = make_track<3>(g, what, interpolation, times, values);
      else if (path == "rotation" && tracks.rotation.empty())
        tracks.rotation = make_track<4>(g, what, interpolation, times, values);
      else if (path == "scale" && tracks.scale.empty())
        tracks.scale = make_track<3>(g, what, interpolation, times, values);
    }
  }

  if (opt.y_up) {
    // glTF's up is +y, mgcloth's +z: a quarter turn about x takes (x, y, z) to (x, −z, y).
    out.placement.linear() << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  }
  out.placement.prescale(opt.scale);
  out.validate(file.string());
  return out;
}

#else

geometry::SkinnedMesh read_skinned_gltf(const fs::path& file, const SkinReadOptions&) {
  throw_error("{}: this build of mgcloth has no glTF support (configured without libtinygltf-dev; install it and "
              "re-run cmake)",
              file.string());
}

#endif

}  // namespace mgcloth::sim
