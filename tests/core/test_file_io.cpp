// Atomic writes: a write that fails (a full disk, a writer that throws) leaves the target as it was and no
// temporary file; stale temporaries are recognized by their name.
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>

#include <gtest/gtest.h>

#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <unistd.h>

namespace mgcloth {
namespace {

namespace fs = std::filesystem;

class AtomicWrite : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() /
          ("mgcloth_file_io_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
           std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    target = dir / "checkpoint.bin";
    write_file_atomic(target, "the previous content\n");
  }
  void TearDown() override { fs::remove_all(dir); }
  /// Everything in the folder but the target.
  std::vector<std::string> others() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir))
      if (e.path() != target) names.push_back(e.path().filename().string());
    return names;
  }
  fs::path dir, target;
};

TEST_F(AtomicWrite, AWriterThatThrowsLeavesNoTemporary) {
  EXPECT_THROW(write_file_atomic(target,
                                 [](std::ostream& o) {
                                   o << "half of it";
                                   throw Error("the writer failed");
                                 }),
               Error);
  EXPECT_EQ(read_file(target), "the previous content\n");
  EXPECT_EQ(others(), std::vector<std::string>{});
}

// /dev/full fails every write with ENOSPC, as a full disk does, for root as for anyone: the temporary's name is
// made a link to it.
TEST_F(AtomicWrite, AFullDiskLeavesNoTemporaryAndNamesTheTarget) {
  ASSERT_TRUE(fs::exists("/dev/full"));
  const fs::path tmp = dir / fmt::format("checkpoint.bin.tmp{}", ::getpid());
  fs::create_symlink("/dev/full", tmp);
  try {
    write_file_atomic(target, [](std::ostream& o) { o << std::string(100000, 'x'); }, true);
    FAIL() << "the write to a full disk succeeded";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(target.string() + ": cannot write: No space left on device", 0), 0u) << msg;
  }
  EXPECT_EQ(read_file(target), "the previous content\n");
  EXPECT_FALSE(fs::exists(fs::symlink_status(tmp)));
  EXPECT_EQ(others(), std::vector<std::string>{});
}

TEST(AtomicWriteTemporaries, AreRecognizedByName) {
  EXPECT_EQ(atomic_write_target("checkpoint.bin.tmp4242"), "checkpoint.bin");
  EXPECT_EQ(atomic_write_target("frame_00001.obj.tmp7"), "frame_00001.obj");
  EXPECT_EQ(atomic_write_target("a.tmp1.tmp2"), "a.tmp1");
  for (const char* name : {"checkpoint.bin", "checkpoint.bin.tmp", "checkpoint.bin.tmpx", "checkpoint.bin.tmp12a",
                           ".tmp12", "notes.tmp"})
    EXPECT_EQ(atomic_write_target(name), std::nullopt) << name;
}

TEST(AtomicWriteTemporaries, OnlyOursAreRemoved) {
  const fs::path dir = fs::temp_directory_path() / ("mgcloth_file_io_remove_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const char* name : {"stats.csv.tmp12", "stats.csv", "notes.txt.tmp3", "stats.csv.tmpx"}) std::ofstream(dir / name) << "x";
  const auto removed = remove_atomic_temporaries(dir, [](const std::string& target) { return target == "stats.csv"; });
  EXPECT_EQ(removed, std::vector<fs::path>{dir / "stats.csv.tmp12"});
  EXPECT_FALSE(fs::exists(dir / "stats.csv.tmp12"));
  for (const char* name : {"stats.csv", "notes.txt.tmp3", "stats.csv.tmpx"}) EXPECT_TRUE(fs::exists(dir / name)) << name;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mgcloth
