// Runs that are healthy must not be aborted by a solve (issue 25): long runs of the shipped scenes and cloths that
// come to rest, to their last frame.
#include <mgcloth/core/file_io.hpp>

#include "cli_run.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;

namespace {

class HealthyRun : public mgcloth::test::TempDirTest {
 protected:
  HealthyRun() : TempDirTest("mgcloth_healthy_") {}
  /// Lines of stats.csv after the header.
  long steps(const fs::path& out) {
    const std::string stats = mgcloth::read_file(out / "stats.csv");
    return static_cast<long>(std::count(stats.begin(), stats.end(), '\n')) - 1;
  }
};

TEST_F(HealthyRun, TheHangingSceneRunsAllSixHundredFrames) {
  // Step 581 used to end the run: "fmg: no search direction decreased the energy in cycle 9 (|g| = 1.155e-06,
  // relative 1.827e-03)"; every direction's energy decrease was below the energy's round-off there.
  const fs::path out = dir / "out";
  const auto r = mgcloth::test::run_cli(std::string("run ") + MGCLOTH_SOURCE_DIR + "/scenes/hanging.json --frames 600 "
                                        "--threads 2 -q --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(steps(out), 600);
  EXPECT_TRUE(fs::exists(out / "frame_00600.obj"));
}

TEST_F(HealthyRun, AStripComesToRestAtRelativeGradient1e7) {
  // Once the strip hangs still, the start of every step is at the gradient's round-off, and 1e-7 of it is out of
  // reach: the steps end converged or stagnated and the run goes on.
  const fs::path scene = dir / "strip.json", out = dir / "out";
  std::ofstream(scene) << R"({ "frames": 300, "cloths": [ { "name": "strip",
      "mesh": { "generator": "rectangle", "width": 0.2, "height": 0.025, "vertices": 800 },
      "pins": [ { "region": { "min": [0, 0], "max": [0.0, 0.025] } } ] } ],
    "solver": { "name": "fmg", "rel_grad": 1e-7, "max_iters": 200 } })";
  const auto r = mgcloth::test::run_cli("run " + scene.string() + " --threads 2 -q --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(steps(out), 300);
  const std::string stats = mgcloth::read_file(out / "stats.csv");
  EXPECT_NE(stats.find(",stagnated,"), std::string::npos) << "the strip never reached its round-off floor";
}

TEST_F(HealthyRun, AClothOfATenthOfAMillimetreRunsToTheEnd) {
  // A 0.1 mm-thin cotton (E·t = 100 N/m, 30 g/m²) stopped in its first step (cycle 66) before solves fell back; a
  // strip and a hanging sheet of it, both bending models, every step to the end: each cloth solved on its own, and
  // (with the default bending model) both in one objective.
  struct Case {
    std::string bending, solve;
    int rows;  ///< stats.csv rows: one per solve
  };
  for (const Case& c : {Case{"quadratic", "separately", 120}, Case{"hinge", "separately", 120},
                        Case{"quadratic", "jointly", 60}}) {
    const std::string label = c.bending + " " + c.solve;
    const fs::path scene = dir / ("thin_" + c.bending + c.solve + ".json"), out = dir / ("out_" + c.bending + c.solve);
    std::ofstream(scene) << R"({ "frames": 60, "solve_bodies": ")" << c.solve << R"(", "cloths": [ { "name": "strip",
        "mesh": { "generator": "rectangle", "width": 0.2, "height": 0.025, "vertices": 800 },
        "material": { "thickness": 1e-4, "bending": ")" << c.bending << R"(" },
        "pins": [ { "region": { "min": [0, 0], "max": [0.0, 0.025] } } ] },
      { "name": "sheet", "mesh": { "generator": "rectangle", "width": 0.5, "height": 0.5, "vertices": 1500, "unstructured": true },
        "transform": { "translation": [0.5, 0.0, 0.0] },
        "material": { "thickness": 1e-4, "bending": ")" << c.bending << R"(" },
        "pins": [ { "points": [[0.0, 0.5], [0.5, 0.5]] } ] } ],
      "solver": { "name": "fmg", "rel_grad": 1e-5, "max_iters": 200 } })";
    const auto r = mgcloth::test::run_cli("run " + scene.string() + " --threads 1 -q --out " + out.string());
    ASSERT_EQ(r.code, 0) << label << ": " << r.out;
    EXPECT_EQ(steps(out), c.rows) << label;
    const std::string stats = mgcloth::read_file(out / "stats.csv");
    EXPECT_EQ(stats.find(",max_iters,"), std::string::npos) << label;
  }
}

}  // namespace
