// The glb output format's 4 GiB limit is checked when the run starts, not after it has run.
#include "cli_run.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;

namespace {

class GlbOutput : public mgcloth::test::TempDirTest {
 protected:
  GlbOutput() : TempDirTest("mgcloth_glb_output_") {}
};

#ifdef MGCLOTH_HAVE_GLTF
// 40,001 frames of 16 vertices: 12 bytes per vertex and frame of morph targets, but 4 bytes per frame squared of
// morph weights (6.4 GB), which the run would have found out only at its end.
TEST_F(GlbOutput, TooManyFramesAreRefusedBeforeTheRun) {
  std::ofstream(dir / "scene.json") << R"({ "frames": 40000, "output": { "format": "glb" },
    "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 16 } } ] })";
  const auto r = mgcloth::test::run_cli("run " + (dir / "scene.json").string() + " -q --out " + (dir / "out").string());
  EXPECT_EQ(r.code, 1) << r.out;
  for (const char* part : {"scene.json: output.format \"glb\": 40001 frames of 16 vertices (frames 40000 / output.every 1, plus frame 0) need 5.97 GiB of data",
                           "(0.01 GiB of morph targets, 12 bytes per vertex and frame, and 5.96 GiB of their weights",
                           "more than the 3.94 GiB a .glb can hold", "at most 32486 frames fit: set output.every to 2 or more"})
    EXPECT_NE(r.out.find(part), std::string::npos) << part << "\n" << r.out;
  EXPECT_FALSE(fs::exists(dir / "out"));
}
#endif

}  // namespace
