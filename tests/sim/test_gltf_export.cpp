// The glb output format: animation.glb read back with tinygltf against the OBJ frames and the obstacle motion.
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/sim/gltf_export.hpp>
#include <mgcloth/sim/gltf_skin.hpp>
#include <mgcloth/sim/recorder.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <gtest/gtest.h>

#include <string>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#ifdef MGCLOTH_HAVE_GLTF
#include <tiny_gltf.h>
#endif

using namespace mgcloth;
namespace fs = std::filesystem;

namespace {

/// The shipped drape on a sphere, small and short, with the sphere sliding and spinning so that its channels are
/// not constant.
Json drape_json(int frames, const Json& formats) {
  const std::string path = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/drape_sphere.json";
  Json j = load_json(path);
  j["cloths"][0]["mesh"]["vertices"] = 100;
  j["frames"] = frames;
  j["solver"] = {{"name", "newton"}, {"rel_grad", 1e-4}, {"max_iters", 50}};
  j["obstacles"][0]["motion"] = {{"type", "constant_velocity"}, {"linear_velocity", {0.3, -0.1, 0.05}},
                                 {"angular_velocity", {0.0, 1.0, 2.0}}};
  j["output"]["format"] = formats;
  return j;
}

sim::Scene parse(const Json& j) {
  const std::string path = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/drape_sphere.json";
  return sim::parse_scene(j, path, fs::path(path).parent_path());
}

/// The `v` lines of an OBJ frame.
std::vector<Vec3> obj_positions(const fs::path& file) {
  std::istringstream in(read_file(file));
  std::vector<Vec3> v;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) != 0) continue;
    std::istringstream l(line.substr(2));
    Vec3 p;
    l >> p.x() >> p.y() >> p.z();
    v.push_back(p);
  }
  return v;
}

}  // namespace

TEST(GltfFormat, UnknownFormatIsRejectedNamingOutputFormat) {
  try {
    parse(drape_json(2, {"obj", "gltf"}));
    FAIL() << "an unknown format was accepted";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("output.format"), std::string::npos) << msg;
    EXPECT_NE(msg.find("\"gltf\""), std::string::npos) << msg;
    EXPECT_NE(msg.find("available: obj, glb"), std::string::npos) << msg;
  }
  EXPECT_THROW(parse(drape_json(2, {"glb", "glb"})), InputError);
  EXPECT_THROW(parse(drape_json(2, Json::array())), InputError);
  EXPECT_EQ(parse(drape_json(2, "glb")).output.formats, std::vector<std::string>{"glb"});
  EXPECT_EQ(sim::to_json(parse(drape_json(2, {"obj", "glb"})))["output"]["format"], Json({"obj", "glb"}));
}

#ifdef MGCLOTH_HAVE_GLTF
namespace {

tinygltf::Model load_glb(const fs::path& file) {
  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  const bool ok = loader.LoadBinaryFromFile(&model, &err, &warn, file.string());
  EXPECT_TRUE(ok) << file << ": " << err;
  EXPECT_TRUE(warn.empty()) << warn;
  return model;
}

/// The float values of an accessor, `width` per element, following its view's stride.
std::vector<float> floats(const tinygltf::Model& m, int accessor) {
  const auto& a = m.accessors.at(accessor);
  EXPECT_EQ(a.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
  const auto& view = m.bufferViews.at(a.bufferView);
  const auto& buffer = m.buffers.at(view.buffer);
  const size_t width = static_cast<size_t>(tinygltf::GetNumComponentsInType(static_cast<uint32_t>(a.type)));
  const size_t stride = view.byteStride ? view.byteStride : width * sizeof(float);
  std::vector<float> out(a.count * width);
  for (size_t i = 0; i < a.count; ++i)
    std::memcpy(&out[i * width], buffer.data.data() + view.byteOffset + a.byteOffset + i * stride, width * sizeof(float));
  return out;
}

int node_named(const tinygltf::Model& m, const std::string& name) {
  for (size_t i = 0; i < m.nodes.size(); ++i)
    if (m.nodes[i].name == name) return static_cast<int>(i);
  ADD_FAILURE() << "no node named " << name;
  return -1;
}

/// The sampler of the channel animating `path` of `node`; null when there is none.
const tinygltf::AnimationSampler* sampler_of(const tinygltf::Model& m, int node, const std::string& path) {
  for (const auto& anim : m.animations)
    for (const auto& c : anim.channels)
      if (c.target_node == node && c.target_path == path) return &anim.samplers.at(c.sampler);
  return nullptr;
}

/// Positions of every frame decoded from the cloth's base and morph targets (frame k = base + target k − 1).
std::vector<std::vector<float>> cloth_frames(const tinygltf::Model& m) {
  const auto& mesh = m.meshes.at(m.nodes.at(node_named(m, "cloth")).mesh);
  EXPECT_EQ(mesh.primitives.size(), 1u);
  const auto& prim = mesh.primitives.at(0);
  std::vector<std::vector<float>> frames{floats(m, prim.attributes.at("POSITION"))};
  for (const auto& target : prim.targets) {
    auto x = floats(m, target.at("POSITION"));
    for (size_t i = 0; i < x.size(); ++i) x[i] += frames[0][i];
    frames.push_back(std::move(x));
  }
  return frames;
}

/// Runs `frames` frames into `dir` (a fresh run), or continues the run there when `resume`; then finish().
void run(const sim::Scene& scene, const fs::path& dir, bool resume, int stop_after = -1) {
  sim::Simulator s(scene);
  sim::Recorder rec(dir, s);
  if (resume) rec.resume(s);
  else rec.start(s);
  const int last = stop_after >= 0 ? stop_after : scene.frames;
  while (s.frame() < last) rec.record_frame(s, s.advance_frame());
  rec.finish(s);
}

}  // namespace

TEST(GltfFormat, AnimationMatchesObjFramesAndObstaclePoses) {
  const fs::path dir = fs::temp_directory_path() / ("mgcloth_gltf_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  constexpr int kFrames = 4;
  const sim::Scene scene = parse(drape_json(kFrames, {"obj", "glb"}));
  run(scene, dir, false);
  const auto m = load_glb(dir / "animation.glb");
  const sim::Simulator reference(scene);  // for the obstacle's motion

  // One scene whose one root turns z-up into y-up, over the cloth and the obstacle.
  ASSERT_EQ(m.scenes.size(), 1u);
  ASSERT_EQ(m.scenes[0].nodes.size(), 1u);
  const auto& root = m.nodes.at(m.scenes[0].nodes[0]);
  ASSERT_EQ(root.rotation.size(), 4u);
  EXPECT_NEAR(root.rotation[0], -std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(root.rotation[3], std::sqrt(0.5), 1e-12);
  EXPECT_EQ(root.children.size(), 2u);

  // The cloth: one mesh with a morph target per frame after the first; frame k decodes to frame_k.obj.
  const int cloth = node_named(m, "cloth");
  const auto& mesh = m.meshes.at(m.nodes.at(cloth).mesh);
  const auto& prim = mesh.primitives.at(0);
  ASSERT_EQ(prim.targets.size(), static_cast<size_t>(kFrames));
  EXPECT_EQ(mesh.weights.size(), static_cast<size_t>(kFrames));
  EXPECT_TRUE(prim.attributes.count("TEXCOORD_0"));
  const auto& pos = m.accessors.at(prim.attributes.at("POSITION"));
  EXPECT_EQ(pos.minValues.size(), 3u);
  EXPECT_EQ(pos.maxValues.size(), 3u);
  for (const auto& t : prim.targets) EXPECT_EQ(m.accessors.at(t.at("POSITION")).minValues.size(), 3u);
  EXPECT_EQ(m.accessors.at(prim.indices).count, 3 * static_cast<size_t>(reference.cloths()[0]->mesh().num_triangles()));
  // The size the run is checked against before it starts is the size written.
  EXPECT_EQ(m.buffers.at(0).data.size(),
            sim::glb_binary_bytes(static_cast<std::uint64_t>(reference.cloths()[0]->mesh().num_vertices()),
                                  static_cast<std::uint64_t>(reference.cloths()[0]->mesh().num_triangles()), true,
                                  kFrames + 1, reference.obstacles()));
  const auto frames = cloth_frames(m);
  for (int k = 0; k <= kFrames; ++k) {
    const auto obj = obj_positions(sim::Recorder::frame_path(dir, k));
    ASSERT_EQ(frames[k].size(), 3 * obj.size()) << "frame " << k;
    for (size_t i = 0; i < obj.size(); ++i)
      for (int d = 0; d < 3; ++d)
        ASSERT_NEAR(frames[k][3 * i + d], obj[i][d], 1e-6 * std::max(1.0, std::abs(obj[i][d]))) << "frame " << k << " vertex " << i;
  }

  // Frame k shows target k − 1 alone, from its time on (STEP).
  const auto* weights = sampler_of(m, cloth, "weights");
  ASSERT_NE(weights, nullptr);
  EXPECT_EQ(weights->interpolation, "STEP");
  const auto times = floats(m, weights->input);
  const auto w = floats(m, weights->output);
  ASSERT_EQ(times.size(), static_cast<size_t>(kFrames + 1));
  ASSERT_EQ(w.size(), static_cast<size_t>((kFrames + 1) * kFrames));
  for (int k = 0; k <= kFrames; ++k) {
    EXPECT_NEAR(times[k], k * scene.frame_time, 1e-6);
    for (int t = 0; t < kFrames; ++t) EXPECT_EQ(w[k * kFrames + t], t == k - 1 ? 1.0f : 0.0f) << "frame " << k << " target " << t;
  }

  // The sphere: its mesh at its radius about its node, and its node at the obstacle's pose at every frame.
  const int sphere = node_named(m, "sphere");
  const auto& sphere_prim = m.meshes.at(m.nodes.at(sphere).mesh).primitives.at(0);
  const auto verts = floats(m, sphere_prim.attributes.at("POSITION"));
  for (size_t i = 0; i < verts.size(); i += 3)
    EXPECT_NEAR(Vec3(verts[i], verts[i + 1], verts[i + 2]).norm(), scene.obstacles[0].radius, 1e-6);
  EXPECT_TRUE(sphere_prim.attributes.count("NORMAL"));
  const auto* tr = sampler_of(m, sphere, "translation");
  const auto* rot = sampler_of(m, sphere, "rotation");
  ASSERT_NE(tr, nullptr);
  ASSERT_NE(rot, nullptr);
  const auto translation = floats(m, tr->output), rotation = floats(m, rot->output);
  ASSERT_EQ(translation.size(), 3u * (kFrames + 1));
  ASSERT_EQ(rotation.size(), 4u * (kFrames + 1));
  const auto& motion = *reference.obstacles()[0].motion;
  for (int k = 0; k <= kFrames; ++k) {
    const auto pose = motion.pose(k * scene.frame_time);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(translation[3 * k + d], pose.translation[d], 1e-6) << "frame " << k;
    const Eigen::Quaterniond q(rotation[4 * k + 3], rotation[4 * k], rotation[4 * k + 1], rotation[4 * k + 2]);
    EXPECT_NEAR(std::abs(q.dot(pose.rotation)), 1.0, 1e-6) << "frame " << k;
  }
  EXPECT_NE(translation[0], translation[3 * kFrames]);  // it did move
  fs::remove_all(dir);
}

// A run interrupted after frames.bin got a frame but before that frame's checkpoint, with a record cut short at
// its end, resumes to an animation with every frame exactly once, equal to an uninterrupted run's.
TEST(GltfFormat, ResumeKeepsEveryFrameOnce) {
  const fs::path root = fs::temp_directory_path() / ("mgcloth_gltf_resume_test_" + std::to_string(::getpid()));
  fs::remove_all(root);
  constexpr int kFrames = 6;
  const sim::Scene full = parse(drape_json(kFrames, {"obj", "glb"}));
  run(full, root / "full", false);

  const sim::Scene glb_only = parse(drape_json(kFrames, "glb"));
  const fs::path split = root / "split";
  run(glb_only, split, false, 3);
  const std::string checkpoint = read_file(split / "checkpoint.bin");
  run(glb_only, split, true, 4);  // frame 4 reaches frames.bin...
  write_file_atomic(split / "checkpoint.bin", [&](std::ostream& o) { o << checkpoint; }, true);  // ...not the checkpoint
  {
    std::ofstream torn(split / "frames.bin", std::ios::binary | std::ios::app);
    torn << "half a record";
  }
  run(glb_only, split, true);

  const auto a = cloth_frames(load_glb(root / "full" / "animation.glb"));
  const auto split_model = load_glb(split / "animation.glb");
  const auto b = cloth_frames(split_model);
  ASSERT_EQ(b.size(), static_cast<size_t>(kFrames + 1));
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k)
    for (size_t i = 0; i < a[k].size(); ++i) ASSERT_NEAR(a[k][i], b[k][i], 1e-6) << "frame " << k << " value " << i;
  const auto times = floats(split_model, sampler_of(split_model, node_named(split_model, "cloth"), "weights")->input);
  for (int k = 0; k <= kFrames; ++k) EXPECT_NEAR(times[k], k * full.frame_time, 1e-6);
  // Only the formats asked for: no OBJ frames in the glb-only run.
  EXPECT_FALSE(fs::exists(sim::Recorder::frame_path(split, 0)));

  // A run that had no glb before resuming starts the animation at the checkpoint's frame.
  const fs::path late = root / "late";
  run(parse(drape_json(2, "obj")), late, false);
  run(parse(drape_json(4, {"obj", "glb"})), late, true);
  const auto late_model = load_glb(late / "animation.glb");
  const auto late_times = floats(late_model, sampler_of(late_model, node_named(late_model, "cloth"), "weights")->input);
  ASSERT_EQ(late_times.size(), 3u);
  EXPECT_NEAR(late_times[0], 2 * full.frame_time, 1e-6);
  fs::remove_all(root);
}

// The file is streamed (its buffer written a frame at a time, from frames.bin) but is byte for byte what tinygltf
// writes for the model it holds, as the whole model built in memory was written before.
TEST(GltfFormat, StreamedFileIsWhatTinygltfWritesForItsModel) {
  const fs::path dir = fs::temp_directory_path() / ("mgcloth_gltf_stream_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  run(parse(drape_json(5, "glb")), dir, false);
  const std::string bytes = read_file(dir / "animation.glb");
  tinygltf::Model model = load_glb(dir / "animation.glb");
  EXPECT_EQ(model.meshes.at(0).primitives.at(0).targets.size(), 5u);
  std::ostringstream rewritten;
  tinygltf::TinyGLTF writer;
  ASSERT_TRUE(writer.WriteGltfSceneToStream(&model, rewritten, false, true));
  EXPECT_TRUE(rewritten.str() == bytes) << rewritten.str().size() << " bytes vs " << bytes.size();
  fs::remove_all(dir);
}

// Frames that the reader cannot deliver are an error naming the file, and nothing is left in its place.
TEST(GltfFormat, AFailedFrameReadLeavesNoFile) {
  sim::SurfaceAnimation s;
  s.num_vertices = 3;
  s.tris = {{0, 1, 2}};
  s.times = {0.0, 0.5, 1.0};
  const fs::path dir = fs::temp_directory_path() / ("mgcloth_gltf_read_fails_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  int reads = 0;
  const auto read = [&](size_t k, float* out) {
    if (++reads > 4) throw Error(fmt::format("{}: cannot read frame record {}", (dir / "frames.bin").string(), k));
    for (int i = 0; i < 9; ++i) out[i] = static_cast<float>(i + k);
  };
  EXPECT_THROW(sim::write_glb(dir / "animation.glb", s, read, {}), Error);
  EXPECT_EQ(reads, 5);  // three for the bounds, then the first target's frame again, then the failure
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

namespace {
/// One triangle rising by 1 m in two frames, beside the obstacles of the tests below.
sim::SurfaceAnimation rising_triangle() {
  sim::SurfaceAnimation s;
  s.num_vertices = 3;
  s.tris = {{0, 1, 2}};
  s.times = {0.0, 0.5};
  s.positions = {0, 0, 1, 3, 0, 1, 0, 3, 1, /* frame 1 */ 0, 0, 2, 3, 0, 2, 0, 3, 2};
  return s;
}
}  // namespace

// Every shape kind tessellated at its size in the obstacle's frame; the plane covers the animated surface.
TEST(GltfFormat, ObstacleShapesAreTessellatedToSize) {
  sim::SurfaceAnimation s = rising_triangle();
  std::vector<geometry::Obstacle> obstacles(4);
  obstacles[0].name = "floor";
  obstacles[0].shape = std::make_shared<geometry::Plane>();
  obstacles[1].name = "ball";
  obstacles[1].shape = std::make_shared<geometry::Sphere>(0.5);
  obstacles[2].name = "crate";
  obstacles[2].shape = std::make_shared<geometry::Box>(Vec3(0.1, 0.2, 0.3));
  const geometry::Pose placed{Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Vec3::UnitZ())), Vec3(1.0, 2.0, 3.0)};
  obstacles[2].motion = std::make_shared<geometry::ConstantVelocityMotion>(placed, Vec3::Zero(), Vec3::Zero());
  obstacles[3].name = "pill";
  obstacles[3].shape = std::make_shared<geometry::Capsule>(0.2, 0.4);
  const fs::path file = fs::temp_directory_path() / ("mgcloth_gltf_shapes_test_" + std::to_string(::getpid()) + ".glb");
  sim::write_glb(file, s, obstacles);
  const auto m = load_glb(file);
  const auto bounds = [&](const std::string& name) {
    const auto& a = m.accessors.at(m.meshes.at(m.nodes.at(node_named(m, name)).mesh).primitives.at(0).attributes.at("POSITION"));
    return std::pair{Vec3(a.minValues[0], a.minValues[1], a.minValues[2]), Vec3(a.maxValues[0], a.maxValues[1], a.maxValues[2])};
  };
  const auto [floor_lo, floor_hi] = bounds("floor");
  EXPECT_LE(floor_lo.x(), 0.0);
  EXPECT_GE(floor_hi.x(), 3.0);
  EXPECT_GE(floor_hi.y(), 3.0);
  EXPECT_EQ(floor_hi.z(), 0.0);
  EXPECT_NEAR(bounds("ball").second.z(), 0.5, 1e-6);
  EXPECT_NEAR(bounds("ball").first.z(), -0.5, 1e-6);
  EXPECT_TRUE(bounds("crate").second.isApprox(Vec3(0.1, 0.2, 0.3), 1e-6));
  EXPECT_TRUE(bounds("crate").first.isApprox(Vec3(-0.1, -0.2, -0.3), 1e-6));
  EXPECT_NEAR(bounds("pill").second.z(), 0.6, 1e-6);
  EXPECT_NEAR(bounds("pill").first.z(), -0.6, 1e-6);
  EXPECT_NEAR(bounds("pill").second.x(), 0.2, 1e-6);
  // Static obstacles are placed by their node and have no channels: the only one is the surface's weights.
  const auto& crate = m.nodes.at(node_named(m, "crate"));
  ASSERT_EQ(crate.translation.size(), 3u);
  EXPECT_NEAR(crate.translation[1], 2.0, 1e-6);
  ASSERT_EQ(crate.rotation.size(), 4u);
  EXPECT_NEAR(crate.rotation[2], std::sin(0.25), 1e-6);
  ASSERT_EQ(m.animations.size(), 1u);
  EXPECT_EQ(m.animations[0].channels.size(), 1u);
  // Mismatched input is an error naming the file.
  s.positions.pop_back();
  try {
    sim::write_glb(file, s, obstacles);
    FAIL() << "inconsistent positions were accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
  }
  fs::remove(file);
}
// A mesh obstacle is written as its own mesh, in its frame, its node placed by its pose, with a normal per vertex.
TEST(GltfFormat, MeshObstaclesAreWrittenAsTheirMesh) {
  const sim::SurfaceAnimation s = rising_triangle();
  std::vector<geometry::Obstacle> obstacles(1);
  obstacles[0].name = "tent";
  auto surface = std::make_shared<geometry::TriangleSurface>();
  surface->vertices.resize(3, 4);
  surface->vertices << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;  // a corner of a tetrahedron and its three edges
  surface->tris = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}};
  obstacles[0].mesh = surface;
  const geometry::Pose placed{Eigen::Quaterniond::Identity(), Vec3(1.0, 2.0, 3.0)};
  obstacles[0].motion = std::make_shared<geometry::ConstantVelocityMotion>(placed, Vec3::Zero(), Vec3::Zero());
  const fs::path file = fs::temp_directory_path() / ("mgcloth_gltf_mesh_obstacle_" + std::to_string(::getpid()) + ".glb");
  sim::write_glb(file, s, obstacles);
  const auto m = load_glb(file);
  const auto& node = m.nodes.at(node_named(m, "tent"));
  const auto& primitive = m.meshes.at(node.mesh).primitives.at(0);
  const auto& positions = m.accessors.at(primitive.attributes.at("POSITION"));
  EXPECT_EQ(positions.count, 4u);
  EXPECT_EQ(m.accessors.at(primitive.attributes.at("NORMAL")).count, 4u);
  EXPECT_EQ(m.accessors.at(primitive.indices).count, 9u);
  EXPECT_EQ(positions.maxValues, (std::vector<double>{1, 1, 1}));
  ASSERT_EQ(node.translation.size(), 3u);
  EXPECT_NEAR(node.translation[2], 3.0, 1e-6);
  // The size check of the recorder counts it as written.
  EXPECT_GT(sim::glb_binary_bytes(3, 1, true, 1, obstacles), sim::glb_binary_bytes(3, 1, true, 1, {}));
  fs::remove(file);
}

namespace {

/// A triangle over `frames` frames `dt` apart (dyadic times, exact in the file's floats), rising 0.1 m a frame.
sim::SurfaceAnimation moving_triangle(int frames, double dt) {
  sim::SurfaceAnimation s;
  s.num_vertices = 3;
  s.tris = {{0, 1, 2}};
  for (int k = 0; k < frames; ++k) {
    s.times.push_back(k * dt);
    for (float p : {0.0f, 0.0f, 1.0f, 3.0f, 0.0f, 1.0f, 0.0f, 3.0f, 1.0f}) s.positions.push_back(p);
    for (int i = 0; i < 3; ++i) s.positions[s.positions.size() - 1 - 3 * i] += 0.1f * static_cast<float>(k);
  }
  return s;
}

/// A column of 3 rings of 4 vertices (z = 0, 0.5, 1) on two joints: "base" slides (LINEAR) and "top", at z = 0.5
/// above it, bends about x (CUBICSPLINE); the middle ring is shared half and half. Its placement turns and scales it.
std::shared_ptr<geometry::SkinnedMesh> bending_column() {
  auto s = std::make_shared<geometry::SkinnedMesh>();
  s->rest.resize(3, 12);
  s->joints = Eigen::Matrix4Xi::Zero(4, 12);
  s->weights = Eigen::Matrix4Xd::Zero(4, 12);
  for (int r = 0; r < 3; ++r)
    for (int a = 0; a < 4; ++a) {
      const int v = 4 * r + a;
      s->rest.col(v) = Vec3(0.1 * std::cos(a * M_PI / 2), 0.1 * std::sin(a * M_PI / 2), 0.5 * r);
      s->joints.col(v) = Eigen::Vector4i(0, 1, 0, 0);
      s->weights.col(v) = Eigen::Vector4d(1.0 - 0.5 * r, 0.5 * r, 0, 0);
    }
  for (int r = 0; r < 2; ++r)
    for (int a = 0; a < 4; ++a) {
      const int i = 4 * r + a, j = 4 * r + (a + 1) % 4;
      s->tris.push_back({i, j, j + 4});
      s->tris.push_back({i, j + 4, i + 4});
    }
  s->joint_names = {"base", "top"};
  s->parent = {-1, 0};
  s->rest_local.resize(2);
  s->rest_local[1].translation = Vec3(0, 0, 0.5);
  s->inverse_bind = {Eigen::Affine3d::Identity(), Eigen::Affine3d(Eigen::Translation3d(0, 0, -0.5))};
  s->tracks.resize(2);
  s->tracks[0].translation.times = {0.0, 1.0};
  s->tracks[0].translation.values = {Vec3(0, 0, 0), Vec3(0.3, -0.2, 0.1)};
  auto& bend = s->tracks[1].rotation;
  bend.interpolation = geometry::Interpolation::CubicSpline;
  bend.times = {0.0, 0.5, 1.0};
  for (double angle : {0.0, 0.5, 1.0}) {
    const Eigen::Quaterniond q(Eigen::AngleAxisd(angle, Vec3::UnitX()));
    bend.values.emplace_back(q.x(), q.y(), q.z(), q.w());
    bend.in_tangents.emplace_back(0.25, 0.0, 0.0, -0.05);
    bend.out_tangents.emplace_back(0.25, 0.0, 0.0, -0.05);
  }
  s->placement = Eigen::Translation3d(0.0, 0.0, 0.2) * Eigen::AngleAxisd(0.5, Vec3::UnitZ()) * Eigen::Scaling(0.8);
  return s;
}

/// Expects the skinned mesh read back from `file` to pose like `ob` at every frame of `s`.
void expect_skin_matches_obstacle(const fs::path& file, const geometry::Obstacle& ob, const sim::SurfaceAnimation& s) {
  sim::SkinReadOptions ro;
  ro.mesh = ob.name;
  const geometry::SkinnedMesh back = sim::read_skinned_gltf(file, ro);
  for (double t : s.times) {
    const Mat3X p = back.at(t);
    const VecX expect = ob.mesh_positions(t);
    ASSERT_EQ(3 * p.cols(), expect.size());
    for (Index v = 0; v < p.cols(); ++v)
      ASSERT_LT((p.col(v) - expect.segment<3>(3 * v)).norm(), 1e-5) << "t = " << t << ", vertex " << v;
  }
}

}  // namespace

// A skinned mesh obstacle is a glTF skin whose skeleton hangs from the obstacle's moving node, with its tracks as
// channels; skinned back from the file it is where the simulation had it at every frame.
TEST(GltfFormat, SkinnedMeshObstaclesAnimateTheirSkeleton) {
  const sim::SurfaceAnimation s = moving_triangle(6, 0.25);
  auto skin = bending_column();
  auto surface = std::make_shared<geometry::TriangleSurface>();
  surface->vertices = skin->rest;
  surface->tris = skin->tris;
  surface->skin = skin;
  std::vector<geometry::Obstacle> obstacles(1);
  obstacles[0].name = "leg";
  obstacles[0].mesh = surface;
  const geometry::Pose placed{Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Vec3::UnitZ())), Vec3(1.0, 2.0, 3.0)};
  obstacles[0].motion = std::make_shared<geometry::ConstantVelocityMotion>(placed, Vec3(0.2, 0.0, 0.1), Vec3(0.0, 0.4, 0.5));
  const fs::path file = fs::temp_directory_path() / ("mgcloth_gltf_skinned_obstacle_" + std::to_string(::getpid()) + ".glb");
  sim::write_glb(file, s, obstacles);
  {
    const auto m = load_glb(file);
    ASSERT_EQ(m.skins.size(), 1u);
    const auto& skin_nodes = m.skins[0].joints;
    ASSERT_EQ(skin_nodes.size(), 2u);
    EXPECT_EQ(m.nodes.at(skin_nodes[0]).name, "base");
    EXPECT_GE(m.accessors.at(m.skins[0].inverseBindMatrices).count, 2u);
    // The mesh's node is at the top of the scene, untransformed; the skeleton hangs from the obstacle's node.
    const int mesh_node = node_named(m, "leg_skin");
    ASSERT_EQ(m.scenes.at(0).nodes.size(), 2u);
    EXPECT_EQ(m.scenes[0].nodes[1], mesh_node);
    EXPECT_EQ(m.nodes.at(mesh_node).skin, 0);
    EXPECT_TRUE(m.nodes.at(mesh_node).translation.empty() && m.nodes.at(mesh_node).rotation.empty());
    const auto& prim = m.meshes.at(m.nodes.at(mesh_node).mesh).primitives.at(0);
    EXPECT_EQ(m.accessors.at(prim.attributes.at("POSITION")).count, 12u);
    EXPECT_EQ(m.accessors.at(prim.attributes.at("JOINTS_0")).componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
    EXPECT_EQ(m.accessors.at(prim.attributes.at("WEIGHTS_0")).count, 12u);
    EXPECT_EQ(m.accessors.at(prim.indices).count, 3u * 16u);
    // One channel per track, at its keys, and the obstacle's pose at every frame.
    const auto* bend = sampler_of(m, skin_nodes[1], "rotation");
    ASSERT_NE(bend, nullptr);
    EXPECT_EQ(bend->interpolation, "CUBICSPLINE");
    EXPECT_EQ(m.accessors.at(bend->input).count, 3u);
    EXPECT_EQ(m.accessors.at(bend->output).count, 9u);
    ASSERT_NE(sampler_of(m, skin_nodes[0], "translation"), nullptr);
    EXPECT_EQ(sampler_of(m, skin_nodes[0], "translation")->interpolation, "LINEAR");
    const auto* pose = sampler_of(m, node_named(m, "leg"), "translation");
    ASSERT_NE(pose, nullptr);
    EXPECT_EQ(m.accessors.at(pose->output).count, s.times.size());
    EXPECT_EQ(m.buffers.at(0).data.size(), sim::glb_binary_bytes(3, 1, false, s.times.size(), obstacles));
  }
  expect_skin_matches_obstacle(file, obstacles[0], s);

  // Looping, the animation repeats each second: sampled at the frames, past its last key.
  surface->loop = true;
  sim::write_glb(file, s, obstacles);
  {
    const auto m = load_glb(file);
    const auto* bend = sampler_of(m, m.skins.at(0).joints.at(1), "rotation");
    ASSERT_NE(bend, nullptr);
    EXPECT_EQ(bend->interpolation, "STEP");
    EXPECT_EQ(m.accessors.at(bend->output).count, s.times.size());
    EXPECT_EQ(m.buffers.at(0).data.size(), sim::glb_binary_bytes(3, 1, false, s.times.size(), obstacles));
  }
  expect_skin_matches_obstacle(file, obstacles[0], s);
  EXPECT_GT((obstacles[0].mesh_positions(1.25) - obstacles[0].mesh_positions(1.0)).norm(), 0.1);  // it does loop
  fs::remove(file);
}

// A mesh sequence obstacle morphs like the surface: a target per frame after the first, driven by the same weights.
TEST(GltfFormat, MeshSequenceObstaclesMorphLikeTheSurface) {
  const sim::SurfaceAnimation s = moving_triangle(6, 0.25);
  auto surface = std::make_shared<geometry::TriangleSurface>();
  Mat3X tent(3, 4);
  tent << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  surface->tris = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}};
  for (int f = 0; f < 3; ++f) {
    Mat3X x = tent;
    x(2, 3) += 0.5 * f;  // the apex rises
    x(0, 1) -= 0.25 * f;
    surface->frames.push_back(x);
  }
  surface->vertices = surface->frames[0];
  surface->rate = 2.0;  // frames at 0, 0.5, 1 s; the output's frames fall between them too
  std::vector<geometry::Obstacle> obstacles(1);
  obstacles[0].name = "tent";
  obstacles[0].mesh = surface;
  const fs::path file = fs::temp_directory_path() / ("mgcloth_gltf_sequence_obstacle_" + std::to_string(::getpid()) + ".glb");
  sim::write_glb(file, s, obstacles);
  const auto m = load_glb(file);
  const int tent_node = node_named(m, "tent");
  const auto& mesh = m.meshes.at(m.nodes.at(tent_node).mesh);
  const auto& prim = mesh.primitives.at(0);
  ASSERT_EQ(prim.targets.size(), s.times.size() - 1);
  EXPECT_EQ(mesh.weights.size(), s.times.size() - 1);
  const auto* w = sampler_of(m, tent_node, "weights");
  ASSERT_NE(w, nullptr);
  EXPECT_EQ(w->interpolation, "STEP");
  EXPECT_EQ(w->output, sampler_of(m, node_named(m, "cloth"), "weights")->output);  // shared with the surface
  const auto base = floats(m, prim.attributes.at("POSITION"));
  for (size_t k = 0; k < s.times.size(); ++k) {
    auto x = base;
    if (k > 0) {
      const auto d = floats(m, prim.targets[k - 1].at("POSITION"));
      for (size_t i = 0; i < x.size(); ++i) x[i] += d[i];
    }
    const Mat3X expect = surface->at(s.times[k]);
    for (Index v = 0; v < 4; ++v)
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(x[3 * v + c], expect(c, v), 1e-6) << "frame " << k << " vertex " << v;
  }
  EXPECT_EQ(m.buffers.at(0).data.size(), sim::glb_binary_bytes(3, 1, false, s.times.size(), obstacles));
  fs::remove(file);
}
#else
TEST(GltfFormat, GlbIsRefusedWithoutTinygltf) {
  const sim::Scene scene = parse(drape_json(1, "glb"));
  sim::Simulator s(scene);
  EXPECT_THROW(sim::Recorder(fs::temp_directory_path() / ("mgcloth_gltf_unavailable_" + std::to_string(::getpid())), s), InputError);
}
#endif
