// Drives the built `mgcloth` executable the way a user does: exit codes, one-line errors, outputs on disk.
#include <mgcloth/core/file_io.hpp>

#include <fmt/format.h>

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <sys/wait.h>

namespace fs = std::filesystem;

namespace {
struct Result {
  int code = -1;
  std::string out;  ///< stdout and stderr together
};

Result run(const std::string& args) {
  const std::string cmd = std::string(MGCLOTH_CLI) + " " + args + " 2>&1";
  Result r;
  FILE* p = popen(cmd.c_str(), "r");
  std::array<char, 4096> buf;
  while (size_t n = fread(buf.data(), 1, buf.size(), p)) r.out.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() / ("mgcloth_cli_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string write(const std::string& name, const std::string& content) {
    std::ofstream(dir / name) << content;
    return (dir / name).string();
  }
  /// A small hanging-cloth scene (fast) writing into `out`.
  std::string small_scene(const std::string& extra = "") {
    return write("scene.json", R"({ "frames": 4, "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 120 },
      "pins": [ { "points": [[0, 1], [1, 1]] } ] } ],
      "obstacles": [ { "shape": { "type": "sphere", "radius": 0.2 }, "position": [0.5, 0.5, -0.3] } ] )" + extra + "}");
  }
  fs::path dir;
};
}  // namespace

TEST_F(Cli, RunWritesFramesStatsResolvedSceneAndCheckpoint) {
  const auto r = run("run " + small_scene() + " --out " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.out;
  for (int f = 0; f <= 4; ++f) EXPECT_TRUE(fs::exists(dir / "out" / fmt::format("frame_{:05d}.obj", f))) << f;
  EXPECT_TRUE(fs::exists(dir / "out" / "scene.resolved.json"));
  EXPECT_TRUE(fs::exists(dir / "out" / "checkpoint.bin"));
  const auto stats = mgcloth::read_file(dir / "out" / "stats.csv");
  EXPECT_EQ(stats.rfind("frame,step,sim_time,solver,iterations,energy,grad_norm,wall_ms", 0), 0u);
  EXPECT_EQ(std::count(stats.begin(), stats.end(), '\n'), 5);
  // Not a terminal: one progress line per frame.
  EXPECT_NE(r.out.find("frame 4/4"), std::string::npos) << r.out;
  // Frames keep the material coordinates.
  EXPECT_NE(mgcloth::read_file(dir / "out" / "frame_00004.obj").find("\nvt "), std::string::npos);
  // No temporary files are left behind.
  for (const auto& e : fs::directory_iterator(dir / "out")) EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos);
}

TEST_F(Cli, TraceRecordsEveryIteration) {
  const auto r = run("run " + small_scene() + " -q --trace --frames 2 --out " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.out;
  const auto trace = mgcloth::read_file(dir / "out" / "trace.csv");
  EXPECT_EQ(trace.rfind("frame,step,cloth,iteration,energy,grad_norm,wall_ms,alpha", 0), 0u);
  // Every step contributes its iteration-0 row plus one per iteration.
  long expected = 0;
  const auto stats = mgcloth::read_file(dir / "out" / "stats.csv");
  std::istringstream in(stats);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::istringstream cols(line);
    std::string c;
    for (int k = 0; k < 5; ++k) std::getline(cols, c, ',');
    expected += 1 + std::stol(c);
  }
  EXPECT_EQ(std::count(trace.begin(), trace.end(), '\n'), expected + 1);
}

TEST_F(Cli, OutputFramesAreValidInputMeshes) {
  ASSERT_EQ(run("run " + small_scene() + " -q --frames 1 --out " + (dir / "a").string()).code, 0);
  // A scene whose cloth is read from the first run's frame (relative path: resolved against the scene's folder).
  const auto scene = write("from_obj.json", R"({ "frames": 2, "cloths": [ { "mesh": { "file": "a/frame_00001.obj" },
    "pins": [ { "region": { "min": [0, 0.9], "max": [1, 1] } } ] } ] })");
  const auto r = run("run " + scene + " -q --out " + (dir / "b").string());
  ASSERT_EQ(r.code, 0) << r.out;
  const auto a = mgcloth::read_file(dir / "a" / "frame_00001.obj");
  const auto b = mgcloth::read_file(dir / "b" / "frame_00000.obj");
  // Same vertex, uv and face counts: the material coordinates survived the round trip.
  for (const char* tag : {"\nv ", "\nvt ", "\nf "}) {
    size_t ca = 0, cb = 0;
    for (size_t p = a.find(tag); p != std::string::npos; p = a.find(tag, p + 1)) ++ca;
    for (size_t p = b.find(tag); p != std::string::npos; p = b.find(tag, p + 1)) ++cb;
    EXPECT_EQ(ca, cb) << tag;
    EXPECT_GT(ca, 0u);
  }
}

TEST_F(Cli, QuietPrintsNothing) {
  const auto r = run("run " + small_scene() + " --frames 1 --quiet --out " + (dir / "out").string());
  EXPECT_EQ(r.code, 0);
  EXPECT_EQ(r.out, "");
}

TEST_F(Cli, ResumeContinuesToTheSameFrames) {
  const std::string scene = small_scene();
  ASSERT_EQ(run("run " + scene + " -q --out " + (dir / "a").string()).code, 0);
  ASSERT_EQ(run("run " + scene + " -q --frames 2 --out " + (dir / "b").string()).code, 0);
  const auto r = run("run " + scene + " -q --resume --out " + (dir / "b").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(mgcloth::read_file(dir / "a" / "frame_00004.obj"), mgcloth::read_file(dir / "b" / "frame_00004.obj"));
  EXPECT_EQ(run("run " + scene + " -q --resume --out " + (dir / "nothing").string()).code, 1);
}

TEST_F(Cli, BadInputGivesOneLineAndNonZeroExit) {
  const auto unknown = run("run " + small_scene(R"(, "solver": { "nmae": "newton" })") + " -q --out " + (dir / "o").string());
  EXPECT_EQ(unknown.code, 1);
  EXPECT_NE(unknown.out.find("solver.nmae: unknown key"), std::string::npos) << unknown.out;
  EXPECT_EQ(std::count(unknown.out.begin(), unknown.out.end(), '\n'), 1) << unknown.out;

  const auto malformed = run("run " + write("bad.json", "{ \"frames\": 3,, }") + " -q");
  EXPECT_EQ(malformed.code, 1);
  EXPECT_NE(malformed.out.find("bad.json:1:"), std::string::npos) << malformed.out;

  const auto missing_mesh = run("run " + write("m.json", R"({ "cloths": [ { "mesh": { "file": "nope.obj" } } ] })") + " -q --out " + (dir / "o2").string());
  EXPECT_EQ(missing_mesh.code, 1);
  EXPECT_NE(missing_mesh.out.find("nope.obj"), std::string::npos) << missing_mesh.out;

  EXPECT_NE(run("run " + (dir / "absent.json").string()).code, 0);
  const auto solver = run("run " + small_scene() + " -q --solver nonsense --out " + (dir / "o3").string());
  EXPECT_EQ(solver.code, 1);
  EXPECT_NE(solver.out.find("unknown solver \"nonsense\""), std::string::npos) << solver.out;

  const auto diverge = run("run " + write("d.json", R"({ "frames": 2, "cloths": [ { "mesh": { "vertices": 50 }, "initial_velocity": [0, 0, 1e300], "pins": [ { "vertices": [0] } ] } ] })") + " -q --out " + (dir / "o4").string());
  EXPECT_EQ(diverge.code, 1);
  EXPECT_NE(diverge.out.find("diverged"), std::string::npos) << diverge.out;
}

TEST_F(Cli, InfoReportsMeshAndRejectsBrokenFiles) {
  const auto good = write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n");
  const auto r = run("info " + good);
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("4"), std::string::npos);
  const auto broken = run("info " + write("broken.obj", "v 0 0 0\nf 1 2 3\n"));
  EXPECT_EQ(broken.code, 1) << broken.out;
  EXPECT_NE(broken.out.find("broken.obj"), std::string::npos) << broken.out;
  EXPECT_EQ(run("info " + (dir / "missing.obj").string()).code, 1);
}
