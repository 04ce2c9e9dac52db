// A run with OBJ output writes its mesh obstacles' surfaces for the viewer (docs/scene-format.md, Outputs):
// obstacles.json (which meshes, their triangles) once and obstacles_NNNNN.bin (float32 positions) with every OBJ
// frame, posed as the simulation had them: geometry::Obstacle::mesh_positions at the frame's time.
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/json.hpp>
#include <mgcloth/sim/scene.hpp>

#include "cli_run.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

class ObstacleFrames : public mgcloth::test::TempDirTest {
 protected:
  ObstacleFrames() : TempDirTest("mgcloth_obstacle_frames_") {}

  /// A small cloth far from its obstacles (so that the run takes no time) beside a sphere, the walking body (stands
  /// 0.05 s, then walks) and an OBJ tetrahedron moving at constant velocity. Frames of 0.05 s.
  fs::path write_scene(const std::string& name, const std::string& output) {
    std::ofstream(dir / "tetra.obj") << "v 0 0 0\nv 0.2 0 0\nv 0 0.2 0\nv 0 0 0.2\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    const fs::path scene = dir / name;
    std::ofstream(scene) << R"({ "frames": 3, "time_step": 0.05, "cloth_contact": {},
      "cloths": [ { "mesh": { "generator": "rectangle", "width": 0.2, "height": 0.2, "vertices": 16 },
                    "transform": { "translation": [3.0, 3.0, 1.0] } } ],
      "obstacles": [ { "name": "ball", "shape": { "type": "sphere", "radius": 0.1 }, "position": [-3, -3, 0] },
                     { "name": "body", "body": { "resolution": 0.05, "walk": { "stand": 0.05, "ramp": 0.1 } } },
                     { "name": "tetra", "mesh": "tetra.obj", "position": [0, 3, 0],
                       "rotation_deg": [10, 20, 30],
                       "motion": { "type": "constant_velocity", "linear_velocity": [0.5, 0, 0],
                                   "angular_velocity": [0, 0, 2] } } ],
      "output": )" << output << " }";
    return scene;
  }
  mgcloth::test::CliResult run(const fs::path& scene, const fs::path& out, const std::string& extra = "") {
    return mgcloth::test::run_cli(fmt::format("run {} -q --threads 1 --out {} {}", scene.string(), out.string(), extra));
  }
  static std::vector<float> read_floats(const fs::path& file) {
    const std::string bytes = mgcloth::read_file(file);
    std::vector<float> x(bytes.size() / sizeof(float));
    std::memcpy(x.data(), bytes.data(), sizeof(float) * x.size());
    return x;
  }
};

TEST_F(ObstacleFrames, ObjRunsWriteTheMeshObstaclesPosedAtEachFrame) {
  const fs::path scene = write_scene("scene.json", R"({ "format": "obj" })");
  const fs::path out = dir / "out";
  const auto r = run(scene, out);
  ASSERT_EQ(r.code, 0) << r.out;

  // The obstacles as the run built them.
  const mgcloth::sim::Scene sc = mgcloth::sim::load_scene(scene);
  ASSERT_EQ(sc.obstacles.size(), 3u);
  const auto body = sc.obstacles[1].build(), tetra = sc.obstacles[2].build();
  ASSERT_TRUE(body.mesh && body.mesh->skin && tetra.mesh);
  const long nb = body.mesh->vertices.cols(), nt = tetra.mesh->vertices.cols();
  ASSERT_EQ(nt, 4);

  const auto j = mgcloth::Json::parse(mgcloth::read_file(out / "obstacles.json"));
  EXPECT_EQ(j.at("vertices").get<long>(), nb + nt);
  ASSERT_EQ(j.at("meshes").size(), 2u);  // the sphere is drawn from scene.resolved.json
  const auto& mb = j["meshes"][0];
  const auto& mt = j["meshes"][1];
  EXPECT_EQ(mb.at("name"), "body");
  EXPECT_EQ(mb.at("obstacle").get<int>(), 1);
  EXPECT_EQ(mb.at("vertices"), mgcloth::Json::array({0, nb}));
  EXPECT_EQ(mb.at("triangles").get<size_t>(), body.mesh->tris.size());
  ASSERT_EQ(mb.at("indices").size(), 3 * body.mesh->tris.size());
  for (size_t t = 0; t < body.mesh->tris.size(); t += 97)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(mb["indices"][3 * t + c].get<long>(), body.mesh->tris[t][c]) << t;
  EXPECT_EQ(mt.at("name"), "tetra");
  EXPECT_EQ(mt.at("obstacle").get<int>(), 2);
  EXPECT_EQ(mt.at("vertices"), mgcloth::Json::array({nb, nt}));
  EXPECT_EQ(mt.at("triangles").get<size_t>(), 4u);
  ASSERT_EQ(mt.at("indices").size(), 12u);
  for (size_t t = 0; t < 4; ++t)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(mt["indices"][3 * t + c].get<long>(), tetra.mesh->tris[t][c]) << t;

  std::vector<float> first;
  for (int f = 0; f <= 3; ++f) {
    const fs::path file = out / fmt::format("obstacles_{:05d}.bin", f);
    ASSERT_TRUE(fs::exists(file)) << file;
    const std::vector<float> x = read_floats(file);
    ASSERT_EQ(fs::file_size(file), 12u * static_cast<std::uintmax_t>(nb + nt)) << file;
    const double t = 0.05 * f;
    const mgcloth::VecX want_b = body.mesh_positions(t), want_t = tetra.mesh_positions(t);
    double worst = 0.0;
    for (long i = 0; i < 3 * nb; ++i) worst = std::max(worst, std::abs(x[i] - want_b[i]) / std::max(1.0, std::abs(want_b[i])));
    for (long i = 0; i < 3 * nt; ++i)
      worst = std::max(worst, std::abs(x[3 * nb + i] - want_t[i]) / std::max(1.0, std::abs(want_t[i])));
    EXPECT_LT(worst, 2e-7) << "frame " << f;  // float32 rounding of the exact pose
    if (f == 0) first = x;
  }
  // The body walked and the tetrahedron moved: the frames are not copies of the first.
  const std::vector<float> last = read_floats(out / "obstacles_00003.bin");
  double body_moved = 0.0;
  for (long i = 0; i < 3 * nb; ++i) body_moved = std::max(body_moved, static_cast<double>(std::abs(last[i] - first[i])));
  EXPECT_GT(body_moved, 0.01);
  EXPECT_NEAR(last[3 * nb] - first[3 * nb], 0.5 * 0.15, 1e-5);  // the tetrahedron's origin vertex, at 0.5 m/s
}

TEST_F(ObstacleFrames, AResumedRunContinuesThemAndAFreshRunRemovesThem) {
  const fs::path scene = write_scene("scene.json", R"({ "format": "obj" })");
  const fs::path whole = dir / "whole", parts = dir / "parts";
  auto r = run(scene, whole);
  ASSERT_EQ(r.code, 0) << r.out;
  r = run(scene, parts, "--frames 1");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_FALSE(fs::exists(parts / "obstacles_00002.bin"));
  r = run(scene, parts, "--resume");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(mgcloth::read_file(parts / "obstacles.json"), mgcloth::read_file(whole / "obstacles.json"));
  for (int f = 0; f <= 3; ++f) {
    const std::string name = fmt::format("obstacles_{:05d}.bin", f);
    ASSERT_TRUE(fs::exists(parts / name)) << name;
    EXPECT_TRUE(mgcloth::read_file(parts / name) == mgcloth::read_file(whole / name)) << name << " differs";
  }

  // output.every: written with the OBJ frames, at the same frames.
  const fs::path every = write_scene("every.json", R"({ "format": "obj", "every": 2 })");
  r = run(every, whole);
  ASSERT_EQ(r.code, 0) << r.out;
  for (int f = 0; f <= 3; ++f) {
    EXPECT_EQ(fs::exists(whole / fmt::format("obstacles_{:05d}.bin", f)), f % 2 == 0) << f;
    EXPECT_EQ(fs::exists(whole / fmt::format("frame_{:05d}.obj", f)), f % 2 == 0) << f;
  }

  // A fresh run without mesh obstacles in the same folder leaves none of the earlier run's behind.
  std::ofstream(dir / "plain.json") << R"({ "frames": 1, "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 16 } } ] })";
  r = run(dir / "plain.json", whole);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::exists(whole / "frame_00001.obj"));
  EXPECT_FALSE(fs::exists(whole / "obstacles.json"));
  EXPECT_FALSE(fs::exists(whole / "obstacles_00000.bin"));

#ifdef MGCLOTH_HAVE_GLTF
  // The glb holds the obstacles itself: without "obj" nothing is written beside it.
  const fs::path glb = write_scene("glb.json", R"({ "format": "glb" })");
  r = run(glb, dir / "glb");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::exists(dir / "glb" / "animation.glb"));
  EXPECT_FALSE(fs::exists(dir / "glb" / "obstacles.json"));
  EXPECT_FALSE(fs::exists(dir / "glb" / "obstacles_00000.bin"));
#endif
}

}  // namespace
