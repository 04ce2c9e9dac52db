#pragma once
// Runs the mgcloth CLI built with the tests (MGCLOTH_CLI) and captures what it prints, for the CLI's tests.
#include <array>
#include <cstdio>
#include <string>
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

}  // namespace mgcloth::test
