#include "subprocess.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace mgcloth::cli {

namespace fs = std::filesystem;

namespace {

/// Undoes posix_spawn_file_actions_init on every path out of run_program.
struct FileActions {
  posix_spawn_file_actions_t actions;
  FileActions() { posix_spawn_file_actions_init(&actions); }
  ~FileActions() { posix_spawn_file_actions_destroy(&actions); }
};

[[noreturn]] void throw_not_started(const std::string& program, int err) {
  if (err == ENOENT)
    throw ProgramNotStarted(fmt::format("{} not found{}", program, program.find('/') == std::string::npos ? " in PATH" : ""));
  throw ProgramNotStarted(fmt::format("cannot start {}: {}", program, std::strerror(err)));
}

}  // namespace

std::string ProgramResult::status() const {
  if (signal != 0) return fmt::format("killed by signal {} ({})", signal, ::strsignal(signal));
  return fmt::format("exit {}", exit_code);
}

ProgramResult run_program(const std::vector<std::string>& argv) {
  if (argv.empty() || argv.front().empty()) throw ProgramNotStarted("run_program: no program given");
  int fds[2];
  // Close-on-exec: the child gets the write end only as its stdout and stderr (dup2 clears the flag there).
  if (::pipe2(fds, O_CLOEXEC) != 0) throw_error("cannot create a pipe to run {}: {}", argv.front(), std::strerror(errno));
  pid_t pid = 0;
  int err = 0;
  {
    FileActions fa;
    posix_spawn_file_actions_adddup2(&fa.actions, fds[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&fa.actions, fds[1], STDERR_FILENO);
    // Descriptors opened without close-on-exec (sockets accepted by a server thread, say) stay ours.
    posix_spawn_file_actions_addclosefrom_np(&fa.actions, STDERR_FILENO + 1);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    err = ::posix_spawnp(&pid, args[0], &fa.actions, nullptr, args.data(), environ);
  }
  ::close(fds[1]);
  if (err != 0) {
    ::close(fds[0]);
    throw_not_started(argv.front(), err);
  }
  ProgramResult r;
  char buf[4096];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0 || (n < 0 && errno == EINTR);)
    if (n > 0) r.output.append(buf, static_cast<std::size_t>(n));
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(status)) {
    r.signal = WTERMSIG(status);
    r.exit_code = 128 + r.signal;
  } else {
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  return r;
}

std::string find_in_path(const std::string& name) {
  const auto runnable = [](const fs::path& p) {
    std::error_code ec;
    return ::access(p.c_str(), X_OK) == 0 && !fs::is_directory(p, ec);
  };
  if (name.empty()) return {};
  if (name.find('/') != std::string::npos) return runnable(name) ? name : "";
  const char* path = std::getenv("PATH");
  const std::string p = path ? path : "/usr/local/bin:/usr/bin:/bin";
  for (std::size_t start = 0; start <= p.size();) {
    const std::size_t end = std::min(p.find(':', start), p.size());
    const std::string folder = p.substr(start, end - start);
    const fs::path candidate = fs::path(folder.empty() ? "." : folder) / name;
    if (runnable(candidate)) return candidate.string();
    start = end + 1;
  }
  return {};
}

std::string last_line(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  const auto nl = text.rfind('\n');
  return nl == std::string::npos ? text : text.substr(nl + 1);
}

}  // namespace mgcloth::cli
