#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>

#include <fstream>
#include <sstream>
#include <unistd.h>

namespace mgcloth {

void write_file_atomic(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write,
                       bool binary) {
  namespace fs = std::filesystem;
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  fs::path tmp = path;
  tmp += fmt::format(".tmp{}", ::getpid());
  {
    std::ofstream out(tmp, binary ? std::ios::binary : std::ios::out);
    if (!out) throw_error("{}: cannot open for writing", tmp.string());
    write(out);
    out.flush();
    if (!out) throw_error("{}: write failed (disk full?)", tmp.string());
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp);
    throw_error("{}: cannot rename into place: {}", path.string(), ec.message());
  }
}

void write_file_atomic(const std::filesystem::path& path, const std::string& content) {
  write_file_atomic(path, [&](std::ostream& o) { o << content; });
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error("{}: cannot open file", path.string());
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace mgcloth
