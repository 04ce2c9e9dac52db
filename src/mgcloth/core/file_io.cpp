#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unistd.h>

namespace mgcloth {

namespace fs = std::filesystem;

namespace {
constexpr std::string_view kTemporaryInfix = ".tmp";

/// Why the last write failed, as the system said it (errno is cleared before writing, so 0 means it said nothing).
std::string write_failure() {
  const int err = errno;
  return err != 0 ? std::strerror(err) : "write failed (disk full?)";
}
}  // namespace

void write_file_atomic(const fs::path& path, const std::function<void(std::ostream&)>& write, bool binary) {
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  fs::path tmp = path;
  tmp += fmt::format("{}{}", kTemporaryInfix, ::getpid());
  // A full disk must not leave the temporary behind: nothing else would ever remove it.
  try {
    errno = 0;
    std::ofstream out(tmp, binary ? std::ios::binary : std::ios::out);
    if (!out) throw_error("{}: cannot open {} for writing: {}", path.string(), tmp.filename().string(), write_failure());
    write(out);
    out.flush();
    if (!out) throw_error("{}: cannot write: {}", path.string(), write_failure());
    out.close();
    if (!out) throw_error("{}: cannot write: {}", path.string(), write_failure());
  } catch (...) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw;
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw_error("{}: cannot rename into place: {}", path.string(), ec.message());
  }
}

void write_file_atomic(const fs::path& path, const std::string& content) {
  write_file_atomic(path, [&](std::ostream& o) { o << content; });
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error("{}: cannot open file", path.string());
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::optional<std::string> atomic_write_target(const std::string& name) {
  const std::size_t at = name.rfind(kTemporaryInfix);
  if (at == std::string::npos || at == 0) return std::nullopt;
  const std::size_t digits = at + kTemporaryInfix.size();
  if (digits == name.size()) return std::nullopt;
  for (std::size_t i = digits; i < name.size(); ++i)
    if (name[i] < '0' || name[i] > '9') return std::nullopt;
  return name.substr(0, at);
}

std::vector<fs::path> remove_atomic_temporaries(const fs::path& dir, const std::function<bool(const std::string&)>& ours) {
  std::vector<fs::path> removed;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const auto target = atomic_write_target(entry.path().filename().string());
    if (!target || !ours(*target) || entry.is_directory(ec)) continue;
    if (fs::remove(entry.path(), ec)) removed.push_back(entry.path());
  }
  return removed;
}

}  // namespace mgcloth
