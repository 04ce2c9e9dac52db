// Skinned meshes: keyframe tracks, SkinnedMesh's checks, and glTF skins written and read back (read_skinned_gltf,
// write_skinned_glb), including files made here with tinygltf for what the writer never produces.
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/geometry/skin.hpp>
#include <mgcloth/sim/gltf_skin.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <numbers>
#include <string>
#include <unistd.h>

#ifdef MGCLOTH_HAVE_GLTF
#include <tiny_gltf.h>
#endif

using namespace mgcloth;
using geometry::Interpolation;
using geometry::SkinnedMesh;
using geometry::Track;
namespace fs = std::filesystem;

namespace {

Eigen::Vector4d quat(double angle, const Vec3& axis) {
  const Eigen::Quaterniond q(Eigen::AngleAxisd(angle, axis.normalized()));
  return {q.x(), q.y(), q.z(), q.w()};
}

/// A tube of 10 rings of 10 vertices along z from 0 to 1 (radius 0.1) bending at its middle: a "hip" joint at the
/// origin that slides (LINEAR translation), a "knee" joint at z = 0.5 below it that turns about x (CUBICSPLINE
/// rotation) and stretches (STEP scale). Vertices blend from the hip to the knee between z = 0.3 and 0.7.
SkinnedMesh bending_tube() {
  constexpr int kRings = 10, kAround = 10;
  SkinnedMesh s;
  s.rest.resize(3, kRings * kAround);
  s.joints = Eigen::Matrix4Xi::Zero(4, kRings * kAround);
  s.weights = Eigen::Matrix4Xd::Zero(4, kRings * kAround);
  for (int r = 0; r < kRings; ++r)
    for (int a = 0; a < kAround; ++a) {
      const int v = r * kAround + a;
      const double phi = 2 * std::numbers::pi * a / kAround, z = r / (kRings - 1.0);
      s.rest.col(v) = Vec3(0.1 * std::cos(phi), 0.1 * std::sin(phi), z);
      const double w = std::clamp((z - 0.3) / 0.4, 0.0, 1.0);
      s.joints.col(v) = Eigen::Vector4i(0, 1, 0, 0);
      s.weights.col(v) = Eigen::Vector4d(1.0 - w, w, 0.0, 0.0);
    }
  for (int r = 0; r + 1 < kRings; ++r)
    for (int a = 0; a < kAround; ++a) {
      const int i = r * kAround + a, j = r * kAround + (a + 1) % kAround;
      s.tris.push_back({i, j, j + kAround});
      s.tris.push_back({i, j + kAround, i + kAround});
    }
  s.joint_names = {"hip", "knee"};
  s.parent = {-1, 0};
  s.rest_local.resize(2);
  s.rest_local[1].translation = Vec3(0, 0, 0.5);
  s.inverse_bind = {Eigen::Affine3d::Identity(), Eigen::Affine3d(Eigen::Translation3d(0, 0, -0.5))};
  s.tracks.resize(2);
  auto& slide = s.tracks[0].translation;
  slide.times = {0.0, 1.0, 2.0};
  slide.values = {Vec3(0, 0, 0), Vec3(0.2, 0.0, 0.1), Vec3(0.1, 0.3, 0.0)};
  auto& bend = s.tracks[1].rotation;
  bend.interpolation = Interpolation::CubicSpline;
  bend.times = {0.0, 0.5, 1.5};
  bend.values = {quat(0.0, Vec3::UnitX()), quat(0.6, Vec3::UnitX()), quat(1.2, Vec3::UnitX())};
  bend.in_tangents = {Eigen::Vector4d::Zero(), Eigen::Vector4d(0.2, 0, 0, -0.05), Eigen::Vector4d(0.1, 0, 0, 0)};
  bend.out_tangents = {Eigen::Vector4d(0.3, 0, 0, 0), Eigen::Vector4d(0.2, 0, 0, -0.05), Eigen::Vector4d::Zero()};
  auto& stretch = s.tracks[1].scale;
  stretch.interpolation = Interpolation::Step;
  stretch.times = {0.25, 1.0};
  stretch.values = {Vec3(1, 1, 1), Vec3(1.2, 1, 1.3)};
  return s;
}

fs::path temp(const std::string& name) {
  return fs::temp_directory_path() / ("mgcloth_gltf_skin_" + std::to_string(::getpid()) + "_" + name);
}

}  // namespace

TEST(SkinTrack, LinearStepAndCubicSplineMatchHandComputedValues) {
  Track<3> linear;
  linear.times = {0.0, 2.0};
  linear.values = {Vec3(0, 0, 0), Vec3(2, 4, 6)};
  EXPECT_TRUE(linear.at(0.5).isApprox(Vec3(0.5, 1.0, 1.5)));
  EXPECT_EQ(linear.at(-1.0), Vec3(0, 0, 0));  // held before the first key
  EXPECT_EQ(linear.at(3.0), Vec3(2, 4, 6));   // and after the last

  Track<3> step;
  step.interpolation = Interpolation::Step;
  step.times = {0.0, 1.0, 2.0};
  step.values = {Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(3, 0, 0)};
  EXPECT_EQ(step.at(0.99).x(), 1.0);
  EXPECT_EQ(step.at(1.0).x(), 2.0);
  EXPECT_EQ(step.at(1.5).x(), 2.0);
  EXPECT_EQ(step.at(5.0).x(), 3.0);

  // Hermite over [0, 2] at s = 1/2: 0.5 v0 + 0.125 dt b0 + 0.5 v1 − 0.125 dt a1 with dt = 2.
  Track<3> spline;
  spline.interpolation = Interpolation::CubicSpline;
  spline.times = {0.0, 2.0};
  spline.values = {Vec3(0, 1, 0), Vec3(1, 1, 0)};
  spline.out_tangents = {Vec3(1, 0, 0), Vec3(0, 0, 0)};
  spline.in_tangents = {Vec3(0, 0, 0), Vec3(2, 0, 0)};
  EXPECT_TRUE(spline.at(1.0).isApprox(Vec3(0.25, 1.0, 0.0), 1e-12)) << spline.at(1.0).transpose();
  EXPECT_TRUE(spline.at(0.0).isApprox(Vec3(0, 1, 0)));
  EXPECT_TRUE(spline.at(2.0).isApprox(Vec3(1, 1, 0)));

  // Rotations: slerp between LINEAR keys, normalized after a spline; halfway to 90° about z is 45°.
  const Eigen::Vector4d half = quat(std::numbers::pi / 4, Vec3::UnitZ());
  Track<4> turn;
  turn.times = {0.0, 1.0};
  turn.values = {quat(0.0, Vec3::UnitZ()), quat(std::numbers::pi / 2, Vec3::UnitZ())};
  EXPECT_TRUE(turn.at(0.5).isApprox(half, 1e-12)) << turn.at(0.5).transpose();
  turn.interpolation = Interpolation::CubicSpline;
  turn.in_tangents = turn.out_tangents = {Eigen::Vector4d::Zero(), Eigen::Vector4d::Zero()};
  EXPECT_TRUE(turn.at(0.5).isApprox(half, 1e-12)) << turn.at(0.5).transpose();
  EXPECT_NEAR(turn.at(0.3).norm(), 1.0, 1e-12);

  Track<3> one;
  one.times = {1.0};
  one.values = {Vec3(7, 8, 9)};
  EXPECT_EQ(one.at(0.0), Vec3(7, 8, 9));
  EXPECT_EQ(one.at(9.0), Vec3(7, 8, 9));
}

TEST(SkinnedMesh, SkinsVerticesByTheirJoints) {
  const SkinnedMesh s = bending_tube();
  ASSERT_NO_THROW(s.validate("tube"));
  EXPECT_EQ(s.duration(), 2.0);
  // At t = 1 the hip has slid by (0.2, 0, 0.1): a vertex on the hip alone goes with it.
  const Mat3X p = s.at(1.0);
  EXPECT_TRUE(p.col(0).isApprox(s.rest.col(0) + Vec3(0.2, 0.0, 0.1), 1e-12));
  // The top ring follows the knee: turned about x by the spline's value at t = 1, scaled, and slid.
  const auto world = s.world_at(1.0);
  const Index top = s.num_vertices() - 1;
  EXPECT_TRUE(p.col(top).isApprox(world[1] * s.inverse_bind[1] * s.rest.col(top), 1e-12));
  // placement applies after skinning.
  SkinnedMesh moved = s;
  moved.placement = Eigen::Translation3d(1, 2, 3) * Eigen::AngleAxisd(0.4, Vec3::UnitY());
  EXPECT_TRUE(moved.at(0.7).isApprox(moved.placement * s.at(0.7), 1e-12));
}

TEST(SkinnedMesh, ValidateNamesWhatIsWrong) {
  const SkinnedMesh good = bending_tube();
  const auto expect_error = [](const SkinnedMesh& s, const std::string& part) {
    try {
      s.validate("the_tube");
      ADD_FAILURE() << "accepted: " << part;
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("the_tube"), std::string::npos) << msg;
      EXPECT_NE(msg.find(part), std::string::npos) << msg;
    }
  };
  SkinnedMesh s = good;
  s.parent = {1, -1};
  expect_error(s, "does not come before it");
  s = good;
  s.joints(1, 50) = 7;
  expect_error(s, "joint index 7");
  s = good;
  s.weights(0, 3) = -0.5;
  s.weights(1, 3) = 1.5;
  expect_error(s, "vertex 3");
  s = good;
  s.weights(0, 4) = 0.5;
  expect_error(s, "weights sum to 0.5");
  s = good;
  s.tracks[0].translation.times = {0.0, 1.0, 1.0};
  expect_error(s, "translation key 2");
  s = good;
  s.tracks[0].translation.values.pop_back();
  expect_error(s, "3 keys but 2 values");
  s = good;
  s.tracks[1].rotation.in_tangents.pop_back();
  expect_error(s, "spline tangents");
  s = good;
  s.inverse_bind.pop_back();
  expect_error(s, "disagree in size");
  s = good;
  s.tris.push_back({0, 1, 100});
  expect_error(s, "vertex 100 of 100");
  s = good;
  s.weights.conservativeResize(4, 99);
  expect_error(s, "100 vertices");
  s = SkinnedMesh{};
  expect_error(s, "no joints");
}

TEST(SkinTrs, DecomposesTranslationRotationScaleAndRefusesShear) {
  const Eigen::Quaterniond r(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()));
  Eigen::Affine3d m = Eigen::Translation3d(1, 2, 3) * r * Eigen::Scaling(2.0, 3.0, 0.5);
  auto trs = sim::to_trs(m);
  ASSERT_TRUE(trs.has_value());
  EXPECT_TRUE(trs->translation.isApprox(Vec3(1, 2, 3)));
  EXPECT_NEAR(std::abs(trs->rotation.dot(r)), 1.0, 1e-12);
  EXPECT_TRUE(trs->scale.isApprox(Vec3(2, 3, 0.5)));
  EXPECT_TRUE(trs->matrix().isApprox(m, 1e-12));
  // A mirror is a negative scale.
  m = Eigen::Affine3d(r) * Eigen::Scaling(-1.0, 1.0, 1.0);
  trs = sim::to_trs(m);
  ASSERT_TRUE(trs.has_value());
  EXPECT_TRUE(trs->matrix().isApprox(m, 1e-12));
  m.linear()(0, 1) = 0.3;  // shear
  EXPECT_FALSE(sim::to_trs(m).has_value());
  Eigen::Affine3d flat = Eigen::Affine3d::Identity();
  flat.linear()(1, 1) = 0.0;
  EXPECT_FALSE(sim::to_trs(flat).has_value());
}

#ifdef MGCLOTH_HAVE_GLTF

namespace {

/// Expects `f` to throw InputError whose message names `file` and contains `element`.
void expect_input_error(const std::function<void()>& f, const fs::path& file, const std::string& element) {
  try {
    f();
    ADD_FAILURE() << "no error for " << element;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(file.string()), std::string::npos) << msg;
    EXPECT_NE(msg.find(element), std::string::npos) << msg;
  }
}

void expect_same_positions(const SkinnedMesh& a, const SkinnedMesh& b, double t, double tol = 1e-5) {
  const Mat3X pa = a.at(t), pb = b.at(t);
  ASSERT_EQ(pa.cols(), pb.cols());
  for (Index v = 0; v < pa.cols(); ++v)
    ASSERT_LT((pa.col(v) - pb.col(v)).norm(), tol) << "t = " << t << ", vertex " << v << ": " << pa.col(v).transpose()
                                                   << " vs " << pb.col(v).transpose();
}

/// A model with one buffer that the test fills view by view, written as .glb (or .gltf) with tinygltf.
struct ModelMaker {
  tinygltf::Model m;
  ModelMaker() {
    m.asset.version = "2.0";
    m.buffers.emplace_back();
  }
  template <class T>
  int accessor(const std::vector<T>& data, int type, int component, bool normalized = false) {
    auto& buf = m.buffers[0].data;
    while (buf.size() % 4) buf.push_back(0);
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = buf.size();
    v.byteLength = data.size() * sizeof(T);
    const auto* bytes = reinterpret_cast<const unsigned char*>(data.data());
    buf.insert(buf.end(), bytes, bytes + v.byteLength);
    m.bufferViews.push_back(v);
    tinygltf::Accessor a;
    a.bufferView = static_cast<int>(m.bufferViews.size() - 1);
    a.componentType = component;
    a.type = type;
    a.normalized = normalized;
    a.count = data.size() / static_cast<size_t>(tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(type)));
    if (type == TINYGLTF_TYPE_VEC3 && component == TINYGLTF_COMPONENT_TYPE_FLOAT) {
      a.minValues = {-1e9, -1e9, -1e9};
      a.maxValues = {1e9, 1e9, 1e9};
    }
    m.accessors.push_back(a);
    return static_cast<int>(m.accessors.size() - 1);
  }
  int positions(const std::vector<float>& p) { return accessor(p, TINYGLTF_TYPE_VEC3, TINYGLTF_COMPONENT_TYPE_FLOAT); }
  int node(tinygltf::Node n) {
    m.nodes.push_back(std::move(n));
    return static_cast<int>(m.nodes.size() - 1);
  }
  int mesh(std::vector<tinygltf::Primitive> prims, const std::string& name = "") {
    tinygltf::Mesh mesh;
    mesh.name = name;
    mesh.primitives = std::move(prims);
    m.meshes.push_back(mesh);
    return static_cast<int>(m.meshes.size() - 1);
  }
  void write(const fs::path& file, bool binary = true) {
    tinygltf::Scene scene;
    for (size_t i = 0; i < m.nodes.size(); ++i) {
      bool child = false;
      for (const auto& n : m.nodes)
        for (int c : n.children) child = child || c == static_cast<int>(i);
      if (!child) scene.nodes.push_back(static_cast<int>(i));
    }
    m.scenes = {scene};
    m.defaultScene = 0;
    if (m.buffers[0].data.empty()) m.buffers.clear();  // tinygltf refuses an empty buffer
    tinygltf::TinyGLTF writer;
    ASSERT_TRUE(writer.WriteGltfSceneToFile(&m, file.string(), true, true, !binary, binary)) << file;
  }
};

tinygltf::Primitive triangles(int position, int indices = -1) {
  tinygltf::Primitive p;
  p.mode = TINYGLTF_MODE_TRIANGLES;
  p.attributes["POSITION"] = position;
  p.indices = indices;
  return p;
}

/// One triangle skinned by 6 root joints through JOINTS_0/WEIGHTS_0 and JOINTS_1/WEIGHTS_1; `weights1` gives the
/// second set's weights of every vertex.
ModelMaker six_joint_triangle(const std::vector<float>& weights0, const std::vector<float>& weights1) {
  ModelMaker mk;
  auto prim = triangles(mk.positions({0, 0, 0, 1, 0, 0, 0, 1, 0}));
  std::vector<std::uint8_t> j0, j1;
  for (int v = 0; v < 3; ++v) {
    j0.insert(j0.end(), {0, 1, 2, 3});
    j1.insert(j1.end(), {4, 5, 0, 0});
  }
  prim.attributes["JOINTS_0"] = mk.accessor(j0, TINYGLTF_TYPE_VEC4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE);
  prim.attributes["WEIGHTS_0"] = mk.accessor(weights0, TINYGLTF_TYPE_VEC4, TINYGLTF_COMPONENT_TYPE_FLOAT);
  prim.attributes["JOINTS_1"] = mk.accessor(j1, TINYGLTF_TYPE_VEC4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE);
  prim.attributes["WEIGHTS_1"] = mk.accessor(weights1, TINYGLTF_TYPE_VEC4, TINYGLTF_COMPONENT_TYPE_FLOAT);
  tinygltf::Skin skin;
  for (int j = 0; j < 6; ++j) {
    tinygltf::Node n;
    n.name = "j" + std::to_string(j);
    n.translation = {0.0, static_cast<double>(j), 0.0};
    skin.joints.push_back(mk.node(n));
  }
  mk.m.skins.push_back(skin);
  tinygltf::Node holder;
  holder.name = "tri";
  holder.mesh = mk.mesh({prim}, "tri");
  holder.skin = 0;
  mk.node(holder);
  return mk;
}

}  // namespace

TEST(GltfSkin, RoundTripReproducesPosedVertices) {
  const SkinnedMesh tube = bending_tube();
  const fs::path file = temp("tube.glb");
  sim::SkinWriteOptions wo;
  wo.animation = "bend";
  sim::write_skinned_glb(file, tube, wo);
  const SkinnedMesh back = sim::read_skinned_gltf(file);
  EXPECT_EQ(back.num_vertices(), tube.num_vertices());
  EXPECT_EQ(back.tris, tube.tris);  // the accessor's order is kept
  // The root node that turns z-up into y-up is a node above the joints: it joins the skeleton.
  ASSERT_EQ(back.num_joints(), tube.num_joints() + 1);
  EXPECT_EQ(back.joint_names, (std::vector<std::string>{"z_up", "hip", "knee"}));
  EXPECT_EQ(back.tracks[2].rotation.interpolation, Interpolation::CubicSpline);
  EXPECT_EQ(back.tracks[2].scale.interpolation, Interpolation::Step);
  EXPECT_EQ(back.tracks[1].translation.interpolation, Interpolation::Linear);
  EXPECT_NEAR(back.duration(), tube.duration(), 1e-7);
  for (double t : {-0.5, 0.0, 0.25, 0.3, 0.5, 0.99, 1.0, 1.37, 2.0, 3.5}) expect_same_positions(tube, back, t);

  // The named animation, and a placement that the root takes over.
  sim::SkinReadOptions ro;
  ro.animation = "bend";
  EXPECT_NO_THROW(sim::read_skinned_gltf(file, ro));
  SkinnedMesh placed = tube;
  placed.placement = Eigen::Translation3d(0.5, -1.0, 2.0) * Eigen::AngleAxisd(0.8, Vec3(1, 1, 0).normalized()) *
                     Eigen::Scaling(1.5);
  sim::write_skinned_glb(file, placed);
  const SkinnedMesh placed_back = sim::read_skinned_gltf(file);
  for (double t : {0.0, 0.6, 1.8}) expect_same_positions(placed, placed_back, t);

  // Read as y-up data without the turn, and scaled: the same, turned and scaled.
  ro = {};
  ro.y_up = false;
  ro.scale = 2.0;
  const SkinnedMesh raw = sim::read_skinned_gltf(file, ro);
  Eigen::Affine3d to_gltf(Eigen::AngleAxisd(-std::numbers::pi / 2, Vec3::UnitX()));
  to_gltf.prescale(2.0);
  EXPECT_TRUE(raw.at(0.6).isApprox(to_gltf * placed.at(0.6), 1e-5));
  fs::remove(file);
}

TEST(GltfSkin, StaticMeshReadsAsOneJointPlacedByItsNode) {
  // A unit square in glTF's x-y plane in two primitives, one indexed and one not: the shared edge's vertices are
  // written twice and read once.
  ModelMaker mk;
  const int a = mk.positions({0, 0, 0, 1, 0, 0, 1, 1, 0, 7, 7, 7});  // the last is in no triangle: left out
  const int b = mk.positions({0, 0, 0, 1, 1, 0, 0, 1, 0});
  const int idx = mk.accessor(std::vector<std::uint16_t>{0, 1, 2}, TINYGLTF_TYPE_SCALAR, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
  tinygltf::Node node;
  node.name = "floor";
  node.translation = {2.0, 0.0, 0.0};
  node.mesh = mk.mesh({triangles(a, idx), triangles(b)}, "square");
  mk.node(node);
  const fs::path file = temp("static.glb");
  mk.write(file);
  SkinnedMesh s = sim::read_skinned_gltf(file);
  EXPECT_EQ(s.num_joints(), 1);
  EXPECT_EQ(s.joint_names[0], "floor");
  EXPECT_EQ(s.duration(), 0.0);
  EXPECT_EQ(s.num_vertices(), 4);
  EXPECT_EQ(s.tris.size(), 2u);
  // glTF's y = 1 is mgcloth's z = 1; the node's translation applies to an unskinned mesh.
  const Mat3X p = s.at(0.0);
  EXPECT_TRUE(p.col(2).isApprox(Vec3(3, 0, 1))) << p;
  EXPECT_TRUE(p.col(3).isApprox(Vec3(2, 0, 1))) << p;
  sim::SkinReadOptions ro;
  ro.y_up = false;
  ro.mesh = "square";
  EXPECT_TRUE(sim::read_skinned_gltf(file, ro).at(0.0).col(3).isApprox(Vec3(2, 1, 0)));

  // The same as text glTF, its buffer embedded.
  const fs::path text = temp("static.gltf");
  mk.write(text, false);
  EXPECT_TRUE(sim::read_skinned_gltf(text).at(0.0).isApprox(p));
  fs::remove(file);
  fs::remove(text);
}

TEST(GltfSkin, ExtraInfluencesKeepTheFourLargestRenormalized) {
  // Joints 0–3 weigh 0.1, 0.2, 0.05, 0.15 and joints 4, 5 weigh 0.3, 0.2: keep 4, 1, 5, 3 (sum 0.85).
  std::vector<float> w0, w1;
  for (int v = 0; v < 3; ++v) {
    w0.insert(w0.end(), {0.1f, 0.2f, 0.05f, 0.15f});
    w1.insert(w1.end(), {0.3f, 0.2f, 0.0f, 0.0f});
  }
  ModelMaker mk = six_joint_triangle(w0, w1);
  const fs::path file = temp("influences.glb");
  mk.write(file);
  const SkinnedMesh s = sim::read_skinned_gltf(file);
  ASSERT_EQ(s.num_joints(), 6);
  ASSERT_EQ(s.num_vertices(), 3);
  for (Index v = 0; v < 3; ++v) {
    EXPECT_EQ(s.joints.col(v), Eigen::Vector4i(4, 1, 5, 3)) << s.joints.col(v).transpose();
    const Eigen::Vector4d expect = Eigen::Vector4d(0.3, 0.2, 0.2, 0.15) / 0.85;
    EXPECT_TRUE(s.weights.col(v).isApprox(expect, 1e-6)) << s.weights.col(v).transpose();
  }
  // Without inverse bind matrices they are identities, so each joint shifts its share along y by its index.
  const double shift = (0.3 * 4 + 0.2 * 1 + 0.2 * 5 + 0.15 * 3) / 0.85;
  EXPECT_NEAR(s.at(0.0)(2, 0), shift, 1e-6);  // y-up: glTF's y is mgcloth's z
  fs::remove(file);
}

TEST(GltfSkin, BadInputIsAnInputErrorNamingFileAndElement) {
  const fs::path missing = temp("missing.glb");
  expect_input_error([&] { sim::read_skinned_gltf(missing); }, missing, "no such file");

  const fs::path garbage = temp("garbage.glb");
  write_file_atomic(garbage, std::string("\x01\x02 this is not glTF \xff", 21));
  expect_input_error([&] { sim::read_skinned_gltf(garbage); }, garbage, "not a glTF");
  write_file_atomic(garbage, std::string("glTF\x02\0\0\0\x10\0\0\0garbage!", 20));
  expect_input_error([&] { sim::read_skinned_gltf(garbage); }, garbage, "not a glTF");
  fs::remove(garbage);

  const fs::path file = temp("bad.glb");
  sim::write_skinned_glb(file, bending_tube());
  sim::SkinReadOptions ro;
  ro.mesh = "no_such_mesh";
  expect_input_error([&] { sim::read_skinned_gltf(file, ro); }, file, "no mesh named \"no_such_mesh\"");
  ro = {};
  ro.animation = "no_such_animation";
  expect_input_error([&] { sim::read_skinned_gltf(file, ro); }, file, "no animation named \"no_such_animation\"");

  // Vertex 1 of the triangle has no weight at all.
  std::vector<float> w0(12, 0.0f), w1(12, 0.0f);
  w0[0] = w0[8] = 1.0f;
  six_joint_triangle(w0, w1).write(file);
  expect_input_error([&] { sim::read_skinned_gltf(file); }, file, "mesh 0 (\"tri\") primitive 0: vertex 1 has no weight");

  // Lines are no surface.
  {
    ModelMaker mk;
    auto prim = triangles(mk.positions({0, 0, 0, 1, 0, 0}));
    prim.mode = TINYGLTF_MODE_LINE;
    tinygltf::Node node;
    node.mesh = mk.mesh({triangles(mk.positions({0, 0, 0, 1, 0, 0, 0, 1, 0})), prim}, "wire");
    mk.node(node);
    mk.write(file);
  }
  expect_input_error([&] { sim::read_skinned_gltf(file); }, file, "mesh 0 (\"wire\") primitive 1: mode 1 (LINES)");

  // An accessor that runs past its buffer view.
  {
    ModelMaker mk;
    const int p = mk.positions({0, 0, 0, 1, 0, 0, 0, 1, 0});
    mk.m.accessors[static_cast<size_t>(p)].count = 4;
    tinygltf::Node node;
    node.mesh = mk.mesh({triangles(p)});
    mk.node(node);
    mk.write(file);
  }
  expect_input_error([&] { sim::read_skinned_gltf(file); }, file, "mesh 0 primitive 0 POSITION: accessor 0");

  // A placement with shear is the root's matrix, which the file holds but a joint cannot.
  SkinnedMesh sheared = bending_tube();
  sheared.placement.linear()(0, 1) = 0.5;
  sim::write_skinned_glb(file, sheared);
  expect_input_error([&] { sim::read_skinned_gltf(file); }, file, "node 0 (\"z_up\"): its matrix has shear");
  ro = {};
  ro.scale = -1.0;
  expect_input_error([&] { sim::read_skinned_gltf(file, ro); }, file, "scale -1");

  // No mesh at all.
  {
    ModelMaker mk;
    tinygltf::Node empty;
    empty.name = "empty";  // tinygltf writes a node with nothing in it as null
    mk.node(empty);
    mk.write(file);
  }
  expect_input_error([&] { sim::read_skinned_gltf(file); }, file, "no mesh");
  fs::remove(file);
}

#else

TEST(GltfSkin, ReadingNeedsTinygltf) {
  EXPECT_THROW(sim::read_skinned_gltf(temp("any.glb")), Error);
  EXPECT_THROW(sim::write_skinned_glb(temp("any.glb"), bending_tube()), Error);
}

#endif
