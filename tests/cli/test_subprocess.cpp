// The one helper that starts the CLI's helper programs (python3 for bench plots, node for render).
#include "subprocess.hpp"

#include <gtest/gtest.h>

#include <csignal>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace mgcloth::cli {
namespace {

namespace fs = std::filesystem;

TEST(Subprocess, CapturesStdoutAndStderrAndTheExitCode) {
  const ProgramResult r = run_program({"sh", "-c", "echo out; echo err >&2; exit 3"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.signal, 0);
  EXPECT_FALSE(r.succeeded());
  EXPECT_EQ(r.output, "out\nerr\n");
  EXPECT_EQ(r.status(), "exit 3");
  EXPECT_EQ(last_line(r.output), "err");
  EXPECT_TRUE(run_program({"true"}).succeeded());
}

TEST(Subprocess, PassesArgumentsWithoutAShell) {
  const ProgramResult r = run_program({"printf", "%s|", "a b", "$HOME", "'q'", "*"});
  EXPECT_TRUE(r.succeeded()) << r.status();
  EXPECT_EQ(r.output, "a b|$HOME|'q'|*|");
}

TEST(Subprocess, AProgramThatCannotStartIsNamed) {
  try {
    run_program({"/nonexistent/tool", "--flag"});
    ADD_FAILURE() << "no exception";
  } catch (const ProgramNotStarted& e) {
    EXPECT_STREQ(e.what(), "/nonexistent/tool not found");
  }
  try {
    run_program({"mgcloth-no-such-program"});
    ADD_FAILURE() << "no exception";
  } catch (const ProgramNotStarted& e) {
    EXPECT_STREQ(e.what(), "mgcloth-no-such-program not found in PATH");
  }
  const fs::path not_executable = fs::temp_directory_path() / "mgcloth_subprocess_not_executable.sh";
  std::ofstream(not_executable) << "#!/bin/sh\necho hello\n";
  fs::permissions(not_executable, fs::perms::owner_read | fs::perms::owner_write);
  try {
    run_program({not_executable.string()});
    // root may run what it cannot execute only when some execute bit is set: none is.
    ADD_FAILURE() << "no exception";
  } catch (const ProgramNotStarted& e) {
    EXPECT_EQ(std::string(e.what()), "cannot start " + not_executable.string() + ": Permission denied");
  }
  fs::remove(not_executable);
}

TEST(Subprocess, SaysWhichSignalKilledTheProgram) {
  const ProgramResult r = run_program({"sh", "-c", "kill -TERM $$"});
  EXPECT_EQ(r.signal, SIGTERM);
  EXPECT_EQ(r.exit_code, 128 + SIGTERM);
  EXPECT_FALSE(r.succeeded());
  EXPECT_EQ(r.status(), "killed by signal 15 (Terminated)");
}

TEST(Subprocess, TheProgramGetsNoneOfOurOtherOpenFiles) {
  const int fd = ::open("/dev/null", O_RDONLY);  // inheritable: no O_CLOEXEC
  ASSERT_GE(fd, 3);
  const ProgramResult r =
      run_program({"sh", "-c", "if [ -e /proc/self/fd/" + std::to_string(fd) + " ]; then echo open; else echo closed; fi"});
  ::close(fd);
  EXPECT_EQ(r.output, "closed\n");
}

TEST(Subprocess, FindsProgramsInPath) {
  const std::string sh = find_in_path("sh");
  ASSERT_FALSE(sh.empty());
  EXPECT_EQ(fs::path(sh).filename(), "sh");
  EXPECT_TRUE(fs::path(sh).is_absolute()) << sh;
  EXPECT_EQ(find_in_path(sh), sh) << "a path is taken as it is";
  EXPECT_EQ(find_in_path("mgcloth-no-such-program"), "");
  EXPECT_EQ(find_in_path("/nonexistent/tool"), "");
  EXPECT_EQ(find_in_path("/usr/bin"), "") << "a folder is no program";
  EXPECT_EQ(find_in_path(""), "");
}

TEST(Subprocess, LastLineIgnoresTrailingLineEnds) {
  EXPECT_EQ(last_line("a\nb\r\n\n"), "b");
  EXPECT_EQ(last_line("only"), "only");
  EXPECT_EQ(last_line(""), "");
}

}  // namespace
}  // namespace mgcloth::cli
