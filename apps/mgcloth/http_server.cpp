#include "http_server.hpp"

#include <mgcloth/core/error.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <arpa/inet.h>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <fstream>
#include <mutex>
#include <netinet/in.h>
#include <poll.h>
#include <set>
#include <sys/socket.h>
#include <thread>
#include <unistd.h>

namespace mgcloth::cli {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kMaxHeaderBytes = 16 * 1024;
// An idle keep-alive connection holds a thread; browsers reconnect when we close it, so a short wait is enough.
constexpr int kIdleTimeoutMs = 5000;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

/// Sends all of `data`; false when the peer went away. MSG_NOSIGNAL: a closed tab must not kill the server.
bool send_all(int fd, const char* data, std::size_t size) {
  while (size > 0) {
    const ssize_t n = ::send(fd, data, size, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    data += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

const char* reason(int status) {
  switch (status) {
    case 200: return "OK";
    case 400: return "Bad Request";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 431: return "Request Header Fields Too Large";
    case 500: return "Internal Server Error";
    case 505: return "HTTP Version Not Supported";
    default: return "Error";
  }
}

std::string head(int status, const std::string& type, std::uintmax_t length, bool keep_alive) {
  // no-store: the folder of a run in progress changes between two loads of the page.
  std::string h = fmt::format(
      "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\n"
      "X-Content-Type-Options: nosniff\r\nConnection: {}\r\n",
      status, reason(status), type, length, keep_alive ? "keep-alive" : "close");
  if (status == 405) h += "Allow: GET, HEAD\r\n";
  return h + "\r\n";
}

bool send_text(int fd, int status, const std::string& text, bool keep_alive, bool with_body) {
  const std::string body = text + "\n";
  const std::string h = head(status, "text/plain; charset=utf-8", body.size(), keep_alive);
  if (!send_all(fd, h.data(), h.size())) return false;
  return !with_body || send_all(fd, body.data(), body.size());
}

/// Whether `file` lies inside `root` once symbolic links are resolved, so that a link in DIR cannot expose the
/// rest of the file system.
bool inside(const fs::path& root, const fs::path& file) {
  std::error_code ec;
  const fs::path r = fs::canonical(root, ec);
  if (ec) return false;
  const fs::path f = fs::canonical(file, ec);
  if (ec) return false;
  auto [ri, fi] = std::mismatch(r.begin(), r.end(), f.begin(), f.end());
  return ri == r.end();
}

}  // namespace

std::string content_type_for(const fs::path& file) {
  static const std::map<std::string, std::string> types = {
      {".html", "text/html; charset=utf-8"},      {".htm", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},  {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},        {".json", "application/json"},
      {".csv", "text/csv; charset=utf-8"},        {".obj", "model/obj"},
      {".glb", "model/gltf-binary"},              {".gltf", "model/gltf+json"},
      {".png", "image/png"},                      {".svg", "image/svg+xml"},
      {".txt", "text/plain; charset=utf-8"},      {".md", "text/markdown; charset=utf-8"},
      {".ico", "image/x-icon"},
  };
  const auto it = types.find(lower(file.extension().string()));
  return it == types.end() ? "application/octet-stream" : it->second;
}

bool split_request_path(const std::string& target, std::vector<std::string>& segments) {
  segments.clear();
  std::string path = target.substr(0, target.find_first_of("?#"));
  if (path.empty() || path[0] != '/') return false;
  std::string segment;
  auto finish_segment = [&]() {
    if (segment == "..") return false;
    if (!segment.empty() && segment != ".") segments.push_back(segment);
    segment.clear();
    return true;
  };
  for (std::size_t i = 1; i < path.size(); ++i) {
    char c = path[i];
    if (c == '%') {
      if (i + 2 >= path.size()) return false;
      const int hi = hex_value(path[i + 1]), lo = hex_value(path[i + 2]);
      if (hi < 0 || lo < 0) return false;
      c = static_cast<char>(hi * 16 + lo);
      i += 2;
      // An encoded '/' would let a segment hide a separator from the ".." check.
      if (c == '/') return false;
    } else if (c == '/') {
      if (!finish_segment()) return false;
      continue;
    }
    if (c == '\0' || c == '\\') return false;
    segment += c;
  }
  return finish_segment();
}

struct HttpServer::Shared {
  std::mutex mutex;
  std::condition_variable idle;
  std::set<int> open_fds;
};

HttpServer::HttpServer(int port) : m_shared(std::make_shared<Shared>()) {
  if (port < 0 || port > 65535) throw_input_error("--port {}: must be in 0-65535 (0 picks a free port)", port);
  m_listen_fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (m_listen_fd < 0) throw_error("cannot create a socket: {}", std::strerror(errno));
  // Lets a restarted viewer reuse its port while old connections linger in TIME_WAIT; a live listener still
  // makes bind() fail, which is what "port in use" must report.
  const int yes = 1;
  ::setsockopt(m_listen_fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = htons(static_cast<uint16_t>(port));
  if (::bind(m_listen_fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    const int err = errno;
    ::close(m_listen_fd);
    if (err == EADDRINUSE)
      throw_input_error("--port {}: port in use on 127.0.0.1 (choose another, or --port 0 for a free one)", port);
    if (err == EACCES) throw_input_error("--port {}: not allowed (ports below 1024 need privileges)", port);
    throw_input_error("--port {}: cannot bind 127.0.0.1:{}: {}", port, port, std::strerror(err));
  }
  if (::listen(m_listen_fd, 64) != 0) {
    const int err = errno;
    ::close(m_listen_fd);
    throw_error("cannot listen on 127.0.0.1:{}: {}", port, std::strerror(err));
  }
  socklen_t len = sizeof addr;
  ::getsockname(m_listen_fd, reinterpret_cast<sockaddr*>(&addr), &len);
  m_port = ntohs(addr.sin_port);
}

HttpServer::~HttpServer() {
  if (m_listen_fd >= 0) ::close(m_listen_fd);
}

void HttpServer::mount(Mount m) {
  if (m.prefix.empty() || m.prefix.front() != '/') m.prefix.insert(m.prefix.begin(), '/');
  if (m.prefix.back() != '/') m.prefix += '/';
  m_mounts.push_back(std::move(m));
  std::sort(m_mounts.begin(), m_mounts.end(), [](const Mount& a, const Mount& b) { return a.prefix.size() > b.prefix.size(); });
}

void HttpServer::generate(const std::string& path, std::function<Generated()> make) { m_generated[path] = std::move(make); }

std::string HttpServer::url() const { return fmt::format("http://127.0.0.1:{}/", m_port); }

void HttpServer::serve(const std::function<bool()>& stop) {
  while (!stop()) {
    pollfd p{m_listen_fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, 200);
    if (ready <= 0) continue;  // timeout, or EINTR from Ctrl-C: look at stop() again
    const int fd = ::accept4(m_listen_fd, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd < 0) continue;
    {
      std::lock_guard lock(m_shared->mutex);
      m_shared->open_fds.insert(fd);
    }
    std::thread([this, fd, shared = m_shared] {
      handle_connection(fd);
      std::lock_guard lock(shared->mutex);
      shared->open_fds.erase(fd);
      ::close(fd);
      shared->idle.notify_all();
    }).detach();
  }
  // Wakes the threads blocked in recv() on idle keep-alive connections, so that stopping takes no time.
  std::unique_lock lock(m_shared->mutex);
  for (int fd : m_shared->open_fds) ::shutdown(fd, SHUT_RDWR);
  m_shared->idle.wait(lock, [&] { return m_shared->open_fds.empty(); });
}

void HttpServer::handle_connection(int fd) {
  std::string buffer;
  char chunk[4096];
  for (;;) {
    std::size_t end;
    while ((end = buffer.find("\r\n\r\n")) == std::string::npos) {
      if (buffer.size() > kMaxHeaderBytes) {
        send_text(fd, 431, "request headers too large", false, true);
        return;
      }
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, kIdleTimeoutMs) <= 0) return;
      const ssize_t n = ::recv(fd, chunk, sizeof chunk, 0);
      if (n <= 0) return;
      buffer.append(chunk, static_cast<std::size_t>(n));
    }
    const std::string header = buffer.substr(0, end);
    buffer.erase(0, end + 4);

    const auto line_end = header.find("\r\n");
    const std::string request_line = header.substr(0, line_end);
    const auto sp1 = request_line.find(' ');
    const auto sp2 = request_line.rfind(' ');
    if (sp1 == std::string::npos || sp2 == sp1) {
      send_text(fd, 400, "malformed request line", false, true);
      return;
    }
    const std::string method = request_line.substr(0, sp1);
    const std::string target = request_line.substr(sp1 + 1, sp2 - sp1 - 1);
    const std::string version = request_line.substr(sp2 + 1);
    if (version != "HTTP/1.1" && version != "HTTP/1.0") {
      send_text(fd, 505, "only HTTP/1.0 and HTTP/1.1", false, true);
      return;
    }

    std::string host, connection;
    long content_length = 0;
    for (std::size_t pos = line_end; pos != std::string::npos && pos < header.size();) {
      const std::size_t start = pos + 2;
      const std::size_t next = header.find("\r\n", start);
      const std::string field = header.substr(start, next == std::string::npos ? std::string::npos : next - start);
      pos = next;
      const auto colon = field.find(':');
      if (colon == std::string::npos) continue;
      const std::string name = lower(trim(field.substr(0, colon)));
      const std::string value = trim(field.substr(colon + 1));
      if (name == "host") host = lower(value);
      else if (name == "connection") connection = lower(value);
      else if (name == "content-length") content_length = std::strtol(value.c_str(), nullptr, 10);
    }
    bool keep_alive = version == "HTTP/1.1" ? connection.find("close") == std::string::npos
                                            : connection.find("keep-alive") != std::string::npos;
    // A request body would be read as the next request: GET has none, so close rather than parse one.
    if (content_length != 0 || lower(header).find("\r\ntransfer-encoding:") != std::string::npos) keep_alive = false;
    // Only names of this machine's loopback: a page elsewhere that rebinds its DNS name to 127.0.0.1 must not
    // read DIR through the user's browser.
    const bool host_ok = host == fmt::format("127.0.0.1:{}", m_port) || host == fmt::format("localhost:{}", m_port) ||
                         (version == "HTTP/1.0" && host.empty());
    if (!respond(fd, method, target, keep_alive, host_ok) || !keep_alive) return;
  }
}

bool HttpServer::respond(int fd, const std::string& method, const std::string& target, bool keep_alive, bool host_ok) {
  ++m_requests;
  const bool with_body = method != "HEAD";
  if (method != "GET" && method != "HEAD") {
    send_text(fd, 405, "only GET and HEAD", false, true);
    return false;  // its body, if any, is unread
  }
  if (!host_ok) return send_text(fd, 403, "unexpected Host header (use http://127.0.0.1:PORT/)", keep_alive, with_body);
  std::vector<std::string> segments;
  if (!split_request_path(target, segments)) return send_text(fd, 400, "bad path", keep_alive, with_body);

  std::string path = "/";
  for (std::size_t i = 0; i < segments.size(); ++i) path += (i ? "/" : "") + segments[i];
  if (const auto it = m_generated.find(path); it != m_generated.end()) {
    Generated g;
    try {
      g = it->second();
    } catch (const std::exception& e) {
      return send_text(fd, 500, e.what(), keep_alive, with_body);
    }
    const std::string h = head(200, g.content_type, g.body.size(), keep_alive);
    return send_all(fd, h.data(), h.size()) && (!with_body || send_all(fd, g.body.data(), g.body.size()));
  }

  for (const Mount& m : m_mounts) {
    std::vector<std::string> prefix;
    split_request_path(m.prefix, prefix);
    if (prefix.size() > segments.size() || !std::equal(prefix.begin(), prefix.end(), segments.begin())) continue;
    fs::path file = m.root;
    for (std::size_t i = prefix.size(); i < segments.size(); ++i) file /= segments[i];
    std::error_code ec;
    if (fs::is_directory(file, ec)) file /= "index.html";
    if (!fs::is_regular_file(file, ec)) return send_text(fd, 404, "not found: " + path, keep_alive, with_body);
    if (!inside(m.root, file)) return send_text(fd, 403, "outside the served folder: " + path, keep_alive, with_body);
    std::ifstream in(file, std::ios::binary);
    const std::uintmax_t size = fs::file_size(file, ec);
    if (!in || ec) return send_text(fd, 404, "cannot read: " + path, keep_alive, with_body);
    const std::string h = head(200, content_type_for(file), size, keep_alive);
    if (!send_all(fd, h.data(), h.size())) return false;
    if (!with_body) return true;
    char buf[64 * 1024];
    std::uintmax_t left = size;
    // A file that shrinks while it is sent (a run rewriting it) would leave the length promised unmet: close.
    while (left > 0) {
      in.read(buf, static_cast<std::streamsize>(std::min<std::uintmax_t>(left, sizeof buf)));
      const auto n = static_cast<std::size_t>(in.gcount());
      if (n == 0) break;
      if (!send_all(fd, buf, n)) return false;
      left -= n;
    }
    return left == 0;
  }
  return send_text(fd, 404, "not found: " + path, keep_alive, with_body);
}

}  // namespace mgcloth::cli
