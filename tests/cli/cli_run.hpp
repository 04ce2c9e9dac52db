#pragma once
// Runs the mgcloth CLI built with the tests (MGCLOTH_CLI) and captures what it prints, for the CLI's tests.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <string>
#include <unistd.h>
#include <sys/wait.h>

namespace mgcloth::test {

struct CliResult {
  int code = -1;
  std::string out;  ///< stdout and stderr together
};

/// `env`: assignments put before the command (e.g. "PATH=/nowhere").
inline CliResult run_cli(const std::string& args, const std::string& env = "") {
  const std::string cmd = env + " " + std::string(MGCLOTH_CLI) + " " + args + " 2>&1";
  CliResult r;
  FILE* p = popen(cmd.c_str(), "r");
  std::array<char, 4096> buf;
  while (size_t n = fread(buf.data(), 1, buf.size(), p)) r.out.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

/// A fixture with a folder of its own, `dir`, under the system's temporary folder (named after `prefix` and the
/// test), fresh for each test and removed afterwards.
class TempDirTest : public ::testing::Test {
 protected:
  explicit TempDirTest(std::string prefix) : m_prefix(std::move(prefix)) {}
  void SetUp() override {
    // The process id keeps two runs of the suite (a CI clone and a developer's build) out of each other's folders.
    dir = std::filesystem::temp_directory_path() /
          (m_prefix + ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  void TearDown() override { std::filesystem::remove_all(dir); }
  std::filesystem::path dir;

 private:
  std::string m_prefix;
};

}  // namespace mgcloth::test
