// Hostile input to the `mgcloth` executable (issue 25): each case ends with one clear line naming the file, field,
// option or element at fault, a non-zero exit, and nothing half-written.
#include <mgcloth/core/file_io.hpp>

#include "cli_run.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

namespace fs = std::filesystem;

namespace {

using mgcloth::test::CliResult;

class BadInput : public mgcloth::test::TempDirTest {
 protected:
  BadInput() : TempDirTest("mgcloth_bad_input_") {}
  std::string write(const std::string& name, const std::string& content) {
    std::ofstream(dir / name, std::ios::binary) << content;
    return (dir / name).string();
  }
  std::string out(const std::string& name = "out") const { return (dir / name).string(); }
};

/// An error is one line "mgcloth: error: …" containing every part, with exit code 1.
::testing::AssertionResult fails_with(const CliResult& r, const std::vector<std::string>& parts) {
  if (r.code != 1) return ::testing::AssertionFailure() << "exit code " << r.code << ": " << r.out;
  if (r.out.rfind("mgcloth: error: ", 0) != 0 || std::count(r.out.begin(), r.out.end(), '\n') != 1)
    return ::testing::AssertionFailure() << "not one error line: " << r.out;
  for (const auto& p : parts)
    if (r.out.find(p) == std::string::npos) return ::testing::AssertionFailure() << "lacks \"" << p << "\": " << r.out;
  return ::testing::AssertionSuccess();
}

}  // namespace

// `mgcloth info` reported "no problems found" for all of these: tinyobjloader had read them as zeros and truncated
// indices.
TEST_F(BadInput, InfoRejectsMalformedObjStatementsWithTheLine) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("info " + write("nan.obj", "v nan 1 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")),
                         {"nan.obj: line 1: `v` coordinate 1 is not finite"}));
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("info " + write("short.obj", "v 0 0 0\nv 1 0 0\nv 0 1\nf 1 2 3\n")),
                         {"short.obj: line 3: `v` needs 3 coordinates"}));
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("info " + write("frac.obj", tri + "f 1 2 3.5\n")),
                         {"frac.obj: line 4: cannot parse the `f` statement", "\"3.5\"", "not an integer"}));
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("info " + write("wrap.obj", tri + "f 1 2 4294967299\n")),
                         {"wrap.obj: line 4", "\"4294967299\"", "out of range"}));
}

// nlohmann kept the last of two equal keys, and its number overflow came out raw ("[json.exception.out_of_range.406]").
TEST_F(BadInput, SceneJsonDuplicateKeysAndOverflowNameFileAndPath) {
  const auto dup = write("dup.json", R"({ "frames": 3, "cloths": [ { "mesh": { "vertices": 50, "vertices": 60 } } ] })");
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run " + dup + " -q --out " + out()),
                         {"dup.json: cloths[0].mesh.vertices: duplicate key \"vertices\""}));
  const auto big = write("big.json", R"({ "time_step": 1e400, "cloths": [ { "mesh": {} } ] })");
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run " + big + " -q --out " + out()),
                         {"big.json: time_step: number overflow parsing '1e400'"}));
  EXPECT_FALSE(fs::exists(out()));
}

// A 1e-30 m triangle passed the relative zero-area test and failed in frame 1, in the coarsest Galerkin matrix,
// after frame 0 had been written.
TEST_F(BadInput, TinyTriangleIsRejectedAtLoadNamingClothAndTriangle) {
  write("tiny.obj", "v 0 0 0\nv 1e-30 0 0\nv 0 1e-30 0\nf 1 2 3\n");
  const auto scene = write("tiny.json", R"({ "frames": 2, "cloths": [ { "name": "speck", "mesh": { "file": "tiny.obj" } } ] })");
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run " + scene + " -q --out " + out()),
                         {"tiny.json: cloths[0] (\"speck\")", "tiny.obj: triangle 0 (vertices 0, 1, 2)",
                          "1.41e-30 m across in material space"}));
  EXPECT_FALSE(fs::exists(out()));
}

TEST_F(BadInput, SceneMessagesNameTheRealMistake) {
  // The misspelled key, not the cloth it leaves missing.
  const auto typo = write("typo.json", R"({ "frames": 2, "cloth": [ { "mesh": {} } ] })");
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run " + typo + " -q --out " + out()),
                         {"typo.json: cloth: unknown key (did you mean \"cloths\"?)"}));
  // Was "Invalid argument []".
  const auto dir_empty = write("dir.json", R"({ "frames": 2, "cloths": [ { "mesh": {} } ], "output": { "dir": "" } })");
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run " + dir_empty + " -q"), {"dir.json: output.dir: must not be empty"}));
  // Was "every quad is a ghost quad".
  const auto empty = write("empty.obj", "# no faces\n");
  const auto shell = write("shell.json", R"({ "frames": 1, "shells": [ { "name": "sheet", "control_mesh": { "file": "empty.obj" } } ] })");
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run " + shell + " -q --out " + out()),
                         {"shell.json: shells[0] (\"sheet\"): ", empty + ": the control mesh is empty"}));
  EXPECT_FALSE(fs::exists(out()));
}

namespace {
const char* kSmallScene = R"({ "frames": 2, "cloths": [ { "mesh": { "vertices": 50 }, "pins": [ { "vertices": [0] } ] } ] })";
}  // namespace

// Overrides skipped the scene's range checks and wrote a scene.resolved.json that mgcloth itself rejected.
TEST_F(BadInput, CommandLineOverridesPassTheScenesChecks) {
  const auto scene = write("scene.json", kSmallScene);
  const auto run = [&](const std::string& args) { return mgcloth::test::run_cli("run " + scene + " -q " + args); };
  EXPECT_TRUE(fails_with(run("--threads 99999 --out " + out()), {"--threads 99999: must be in [0, 1024], got 99999"}));
  EXPECT_TRUE(fails_with(run("--frames 10000001 --out " + out()), {"--frames 10000001: must be in [0, 10000000]"}));
  EXPECT_TRUE(fails_with(run("--frames -1 --out " + out()), {"--frames -1: must be in [0, 10000000], got -1"}));
  EXPECT_TRUE(fails_with(run("--level 3 --out " + out()), {"--level: the scene has no shells"}));
  EXPECT_FALSE(fs::exists(out()));
  // Silently ignored before.
  EXPECT_TRUE(fails_with(run("--out ''"), {"--out: must not be empty"}));
  EXPECT_TRUE(fails_with(run("--solver '' --out " + out()), {"--solver: must not be empty (available: fmg"}));
  EXPECT_FALSE(fs::exists(out()));
  // Accepted overrides make a resolved scene that reads back (0 threads: all cores, as in the scene).
  const auto ok = run("--threads 0 --frames 1 --solver newton-direct --out " + out());
  ASSERT_EQ(ok.code, 0) << ok.out;
  const auto resolved = mgcloth::read_file(dir / "out" / "scene.resolved.json");
  EXPECT_NE(resolved.find("\"newton-direct\""), std::string::npos);
  const auto again = mgcloth::test::run_cli("run " + (dir / "out" / "scene.resolved.json").string() + " -q --out " + out("again"));
  EXPECT_EQ(again.code, 0) << again.out;
}

// CLI11's checks printed the largest double, 309 digits, as the bound.
TEST_F(BadInput, OptionRangesAreSaidPlainly) {
  const auto scene = write("scene.json", kSmallScene);
  const auto r = mgcloth::test::run_cli("run " + scene + " -q --threads -1 --out " + out());
  EXPECT_TRUE(fails_with(r, {"--threads -1: must be in [0, 1024], got -1"}));
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("render " + dir.string() + " --out x.png --frame -1"),
                         {"--frame: must be a frame number >= 0 (got -1)"}));
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("info " + scene + " --material-scale 0"),
                         {"--material-scale: must be in [1e-9, 1e9]"}));
  // A negative number is a value, then out of range ("At Most 1 required but received 2" was reported for it).
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("bench convergence " + scene + " --step 1 --solvers fmg --out " + out() +
                                                " --budget -1"),
                         {"--budget: must be a positive number of seconds (got -1)"}));
  // Parse errors are one line too.
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run"), {"scene is required"}));
}

// rmtr blamed "a shell of level 1" on a cloth scene, after writing frame 0.
TEST_F(BadInput, SolverThatCannotWorkOnTheBodiesFailsBeforeAnyOutput) {
  const auto scene = write("scene.json", kSmallScene);
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run " + scene + " -q --solver rmtr --out " + out()),
                         {"scene.json: cloths[0] (\"cloth0\"): solver rmtr needs a mesh hierarchy of at least two "
                          "levels", "hierarchy.max_coarse_vertices (400)", "(fmg, newton-direct, tr-dogleg"}));
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run " + scene + " -q --solver fas --out " + out()),
                         {"scene.json: cloths[0] (\"cloth0\"): solver fas needs a mesh hierarchy of at least two "
                          "levels"}));
  const auto shell = write("shell.json", R"({ "frames": 1, "shells": [ { "name": "sheet", "level": 1,
    "control_mesh": { "generator": "rectangle", "cells_u": 2, "cells_v": 2 } } ], "solver": { "name": "rmtr" } })");
  EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run " + shell + " -q --out " + out()),
                         {"shell.json: shells[0] (\"sheet\"): solver rmtr needs at least two levels",
                          "the shell is subdivided to level 1"}));
  EXPECT_FALSE(fs::exists(out()));
}

// A cloth named "a,b" or with a newline, quote or NUL made stats.csv unreadable.
TEST_F(BadInput, ClothNamesThatBreakStatsCsvAreRejected) {
  for (const std::string& name : {std::string("a,b"), std::string("x\\ny"), std::string("q\\\"q"), std::string("n\\u0000l")}) {
    const auto scene = write("names.json", R"({ "frames": 1, "cloths": [ { "name": ")" + name + R"(", "mesh": { "vertices": 50 } } ] })");
    EXPECT_TRUE(fails_with(mgcloth::test::run_cli("run " + scene + " -q --out " + out()),
                           {"names.json: cloths[0].name: ", "a name goes unquoted into CSV columns"}))
        << name;
  }
  EXPECT_FALSE(fs::exists(out()));
}
