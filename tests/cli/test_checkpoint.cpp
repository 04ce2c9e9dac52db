// A damaged checkpoint is refused by --resume with the file named, and the run's outputs stay as they were.
#include <mgcloth/core/file_io.hpp>

#include "cli_run.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;

namespace {

class Checkpoint : public mgcloth::test::TempDirTest {
 protected:
  Checkpoint() : TempDirTest("mgcloth_checkpoint_") {}
  void SetUp() override {
    TempDirTest::SetUp();
    std::ofstream(dir / "scene.json") << R"({ "frames": 4, "cloths": [ { "mesh": { "generator": "rectangle",
      "vertices": 120 }, "pins": [ { "points": [[0, 1], [1, 1]] } ] } ], "solver": { "name": "newton-direct" } })";
    out = dir / "out";
    const auto r = run("--frames 2");
    ASSERT_EQ(r.code, 0) << r.out;
  }
  mgcloth::test::CliResult run(const std::string& extra) {
    return mgcloth::test::run_cli("run " + (dir / "scene.json").string() + " -q --out " + out.string() + " " + extra);
  }
  /// Resuming the damaged checkpoint fails naming the file and `why`, and leaves every output as it was.
  void expect_refused(const std::string& why) {
    const std::string frame = mgcloth::read_file(out / "frame_00002.obj"), stats = mgcloth::read_file(out / "stats.csv");
    const auto r = run("--resume");
    EXPECT_NE(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("checkpoint.bin"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(why), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(out / "frame_00003.obj"));
    EXPECT_EQ(mgcloth::read_file(out / "frame_00002.obj"), frame);
    EXPECT_EQ(mgcloth::read_file(out / "stats.csv"), stats);
  }
  fs::path out;
};

TEST_F(Checkpoint, ResumesAnIntactOne) {
  const auto r = run("--resume");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::exists(out / "frame_00004.obj"));
}

TEST_F(Checkpoint, AFlippedByteIsAChecksumMismatch) {
  std::string bytes = mgcloth::read_file(out / "checkpoint.bin");
  bytes[bytes.size() / 2] ^= 0x10;  // inside the positions: a plausible number, which only the checksum catches
  mgcloth::write_file_atomic(out / "checkpoint.bin", [&](std::ostream& o) { o << bytes; }, true);
  expect_refused("checksum mismatch");
}

TEST_F(Checkpoint, ATruncatedOneIsRefused) {
  std::string bytes = mgcloth::read_file(out / "checkpoint.bin");
  bytes.resize(bytes.size() - 100);
  mgcloth::write_file_atomic(out / "checkpoint.bin", [&](std::ostream& o) { o << bytes; }, true);
  expect_refused("checksum mismatch");
}

TEST_F(Checkpoint, AnotherFormatVersionIsNamed) {
  std::string bytes = mgcloth::read_file(out / "checkpoint.bin");
  bytes.replace(6, 2, "04");
  mgcloth::write_file_atomic(out / "checkpoint.bin", [&](std::ostream& o) { o << bytes; }, true);
  expect_refused("checkpoint format version 04, written by a newer mgcloth");
}

TEST_F(Checkpoint, AnotherFileIsNotACheckpoint) {
  mgcloth::write_file_atomic(out / "checkpoint.bin", [&](std::ostream& o) { o << "hello, this is not one"; }, true);
  expect_refused("not an mgcloth checkpoint");
}

/// The names in `dir` that look like write_file_atomic's temporaries.
std::vector<std::string> temporaries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp") != std::string::npos) names.push_back(e.path().filename().string());
  return names;
}

// A file-size limit makes the writes fail with EFBIG as a full disk does (root included); the ignored SIGXFSZ is
// inherited, so mgcloth sees the failed write instead of being killed.
TEST_F(Checkpoint, AFailedWriteLeavesNoTemporary) {
  const auto r = mgcloth::test::run_cli("run " + (dir / "scene.json").string() + " -q --resume --out " + out.string(),
                                        "trap '' XFSZ; ulimit -f 8;");
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("frame_00003.obj: cannot write: File too large"), std::string::npos) << r.out;
  EXPECT_EQ(temporaries(out), std::vector<std::string>{});
  // The checkpoint is still the last complete frame's, so the run goes on once there is room.
  const auto resumed = run("--resume");
  ASSERT_EQ(resumed.code, 0) << resumed.out;
  EXPECT_TRUE(fs::exists(out / "frame_00004.obj"));
}

TEST_F(Checkpoint, ResumeRemovesStaleTemporaries) {
  for (const char* name : {"checkpoint.bin.tmp4242", "stats.csv.tmp17", "frame_00001.obj.tmp99", "notes.txt.tmp5"})
    std::ofstream(out / name) << "left by a killed run";
  const auto r = run("--resume");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(temporaries(out), std::vector<std::string>{"notes.txt.tmp5"});  // not a name mgcloth writes
}

}  // namespace
