#pragma once
// Starting the helper programs of the CLI (python3 for `bench`'s plots, node for `render`) with their output
// captured: one place for posix_spawn, pipes, PATH lookup and exit statuses.
#include <mgcloth/core/error.hpp>

#include <string>
#include <vector>

namespace mgcloth::cli {

/// A program that could not be started (not found, not executable); the message names it and says why.
class ProgramNotStarted : public Error {
 public:
  using Error::Error;
};

/// How a program ended, with what it printed.
struct ProgramResult {
  /// The exit code; for a program killed by a signal, 128 + the signal number (as a shell reports it).
  int exit_code = -1;
  /// The signal that killed the program, 0 when it exited.
  int signal = 0;
  /// stdout and stderr together, in the order written.
  std::string output;

  bool succeeded() const { return signal == 0 && exit_code == 0; }
  /// "exit 3", or "killed by signal 11 (Segmentation fault)".
  std::string status() const;
};

/// Runs `argv` (argv[0] looked up in PATH unless it contains a '/') without a shell, so arguments need no quoting,
/// with stdin inherited and stdout + stderr captured, and waits for it. The program gets none of our other open
/// files (a connection of `mgcloth render`'s server must not live on in it). Throws ProgramNotStarted when argv[0]
/// cannot be started ("NAME not found", "cannot start NAME: <reason>"), Error when no pipe can be made.
ProgramResult run_program(const std::vector<std::string>& argv);

/// `name` as found in PATH (or `name` itself when it contains a '/'), when it is an executable file; else empty.
std::string find_in_path(const std::string& name);

/// The last line of a program's output once trailing line ends are removed: its error message, usually.
std::string last_line(std::string text);

}  // namespace mgcloth::cli
