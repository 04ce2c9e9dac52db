// Running out of memory is an error that names what was being built, with exit code 1 (issue 25: a bare
// "std::bad_alloc"). The memory limit is the shell's `ulimit -v`.
#include "cli_run.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;

namespace {

class OutOfMemory : public mgcloth::test::TempDirTest {
 protected:
  OutOfMemory() : TempDirTest("mgcloth_oom_") {}
  void SetUp() override {
#if defined(__SANITIZE_ADDRESS__)
    GTEST_SKIP() << "AddressSanitizer reserves more address space than the limit allows";
#endif
    TempDirTest::SetUp();
  }
  /// `mgcloth run` of `scene` with the address space limited to `kib` KiB.
  mgcloth::test::CliResult run_limited(const std::string& scene, long kib, const std::string& extra = "") {
    std::ofstream(dir / "scene.json") << scene;
    return mgcloth::test::run_cli("run " + (dir / "scene.json").string() + " -q --threads 1 --out " +
                                      (dir / "out").string() + " " + extra,
                                  "ulimit -v " + std::to_string(kib) + ";");
  }
};

TEST_F(OutOfMemory, ALargeGeneratedClothNamesTheMeshAndTheCloth) {
  // 5 million vertices is within the scene's range; 400 MB is not enough for them.
  const auto r = run_limited(R"({ "frames": 1, "cloths": [ { "name": "big",
      "mesh": { "generator": "rectangle", "vertices": 5000000 } } ] })", 400'000);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("mgcloth: error: cloth \"big\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("cloths[0]"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("out of memory building a rectangle mesh of about 5000000 vertices"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("bad_alloc"), std::string::npos) << r.out;
}

TEST_F(OutOfMemory, ADeepShellNamesTheSubdivisionLevel) {
  const auto r = run_limited(R"({ "time_step": 1.0, "frames": 1, "shells": [ { "name": "deep",
      "control_mesh": { "generator": "rectangle", "cells_u": 4, "cells_v": 4 }, "level": 9,
      "boundary": [ { "type": "fixed", "sides": ["left"] } ] } ], "solver": { "name": "tr-dogleg" } })", 600'000);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("shell \"deep\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("out of memory building subdivision level"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("bad_alloc"), std::string::npos) << r.out;
}

}  // namespace
