#include "file_server.hpp"

#include <mgcloth/core/error.hpp>

#include <fmt/format.h>
#include <httplib.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <sys/socket.h>
#include <thread>

namespace mgcloth::cli {

namespace fs = std::filesystem;

namespace {

// Browsers open several connections and keep them; one worker thread serves one connection at a time.
constexpr std::size_t kWorkerThreads = 16;
// An idle keep-alive connection holds a worker until it ends, and stopping waits for it: browsers reconnect when we
// close one, so a short wait is enough.
constexpr time_t kKeepAliveSeconds = 1;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

void set_text(httplib::Response& res, int status, const std::string& text) {
  res.status = status;
  res.set_content(text + "\n", "text/plain; charset=utf-8");
}

/// Answers and ends the connection, for a request refused with its body unread (the handler below answers before
/// cpp-httplib reads any): on an open connection that body would be read as the next request, one that could carry
/// a Host header of its choice. An answer to HEAD has no body to end on, so such a connection stays open; browsers
/// send no body with HEAD.
void refuse_and_close(httplib::Response& res, int status, const std::string& text) {
  res.status = status;
  res.set_header("Connection", "close");
  auto body = std::make_shared<std::string>(text + "\n");
  res.set_content_provider(body->size(), "text/plain; charset=utf-8",
                           [body](std::size_t offset, std::size_t, httplib::DataSink& sink) {
                             if (offset < body->size()) sink.write(body->data() + offset, body->size() - offset);
                             return false;  // a failed write is what makes cpp-httplib close the connection
                           });
}

bool has_body(const httplib::Request& req) {
  const std::string length = req.get_header_value("Content-Length");
  return (!length.empty() && length.find_first_not_of('0') != std::string::npos) || req.has_header("Transfer-Encoding");
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

/// Whether every byte range asked for lies in a file of `size` bytes. cpp-httplib 0.11 does not clamp a range that
/// runs past the end: it would promise more bytes than the file has.
bool ranges_fit(const httplib::Ranges& ranges, std::uintmax_t size) {
  const auto n = static_cast<long long>(size);
  for (const auto& [first, last] : ranges) {
    if (first < 0 && last <= 0) return false;               // "-0", or no numbers at all
    if (first >= 0 && (first >= n || last >= n)) return false;
    if (first < 0 && n == 0) return false;                  // a suffix of an empty file
  }
  return true;
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

FileServer::FileServer(int port) : m_server(std::make_unique<httplib::Server>()) {
  if (port < 0 || port > 65535) throw_input_error("--port {}: must be in 0-65535 (0 picks a free port)", port);
  httplib::Server& server = *m_server;
  server.set_address_family(AF_INET);
  // SO_REUSEADDR lets a restarted viewer reuse its port while old connections linger in TIME_WAIT, and a live
  // listener still makes bind() fail, which is what "port in use" must report. cpp-httplib's default,
  // SO_REUSEPORT, would let two viewers share a port and split the requests between them.
  server.set_socket_options([](socket_t sock) {
    const int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  server.new_task_queue = [] { return new httplib::ThreadPool(kWorkerThreads); };
  server.set_keep_alive_timeout(kKeepAliveSeconds);
  server.set_keep_alive_max_count(1000);
  // no-store: the folder of a run in progress changes between two loads of the page.
  server.set_default_headers({{"Cache-Control", "no-store"}, {"X-Content-Type-Options", "nosniff"}});
  server.set_logger([this](const httplib::Request&, const httplib::Response&) { ++m_requests; });
  // Every request is answered here, before cpp-httplib's routing (which would match the path against regular
  // expressions and read bodies that GET has no use for).
  server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (req.method != "GET" && req.method != "HEAD") {
      refuse_and_close(res, 405, "only GET and HEAD");
      res.set_header("Allow", "GET, HEAD");
    } else if (has_body(req)) {
      refuse_and_close(res, 400, "a GET or HEAD request has no body");
    } else if (!host_ok(req)) {
      set_text(res, 403, "unexpected Host header (use http://127.0.0.1:PORT/)");
    } else {
      answer(req, res);
    }
    return httplib::Server::HandlerResponse::Handled;
  });

  // cpp-httplib says only whether binding worked; bind()'s errno is still there to say why.
  errno = 0;
  bool bound = false;
  if (port == 0) {
    m_port = server.bind_to_any_port("127.0.0.1");
    bound = m_port > 0;
  } else {
    m_port = port;
    bound = server.bind_to_port("127.0.0.1", port);
  }
  if (!bound) {
    const int err = errno;
    if (err == EADDRINUSE)
      throw_input_error("--port {}: port in use on 127.0.0.1 (choose another, or --port 0 for a free one)", port);
    if (err == EACCES) throw_input_error("--port {}: not allowed (ports below 1024 need privileges)", port);
    throw_input_error("--port {}: cannot listen on 127.0.0.1:{}: {}", port, port,
                      err != 0 ? std::strerror(err) : "unknown error");
  }
}

FileServer::~FileServer() = default;

void FileServer::mount(Mount m) {
  if (m.prefix.empty() || m.prefix.front() != '/') m.prefix.insert(m.prefix.begin(), '/');
  if (m.prefix.back() != '/') m.prefix += '/';
  m_mounts.push_back(std::move(m));
  std::sort(m_mounts.begin(), m_mounts.end(), [](const Mount& a, const Mount& b) { return a.prefix.size() > b.prefix.size(); });
}

void FileServer::generate(const std::string& path, std::function<Generated()> make) { m_generated[path] = std::move(make); }

std::string FileServer::url() const { return fmt::format("http://127.0.0.1:{}/", m_port); }

void FileServer::serve(const std::function<bool()>& stop) {
  std::atomic<bool> finished{false};
  bool ok = true;
  int err = 0;
  std::thread listening([&] {
    ok = m_server->listen_after_bind();
    err = errno;
    finished = true;
  });
  while (!stop() && !finished) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  // httplib's stop() does nothing before the accept loop has started.
  while (!finished && !m_server->is_running()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  if (!finished) m_server->stop();
  listening.join();
  if (!ok) throw_error("the server on {} stopped: cannot accept connections: {}", url(), std::strerror(err));
}

bool FileServer::host_ok(const httplib::Request& req) const {
  // Only names of this machine's loopback: a page elsewhere that rebinds its DNS name to 127.0.0.1 must not read
  // DIR through the user's browser.
  const std::string host = lower(req.get_header_value("Host"));
  return host == fmt::format("127.0.0.1:{}", m_port) || host == fmt::format("localhost:{}", m_port) ||
         (req.version == "HTTP/1.0" && host.empty());
}

void FileServer::answer(const httplib::Request& req, httplib::Response& res) const {
  // The raw target, decoded once here: httplib's decoded req.path lets bad escapes through and cannot tell an
  // encoded '/' from a separator.
  std::vector<std::string> segments;
  if (!split_request_path(req.target, segments)) return set_text(res, 400, "bad path");

  std::string path = "/";
  for (std::size_t i = 0; i < segments.size(); ++i) path += (i ? "/" : "") + segments[i];
  if (const auto it = m_generated.find(path); it != m_generated.end()) {
    try {
      Generated g = it->second();
      res.set_content(std::move(g.body), g.content_type);
    } catch (const std::exception& e) {
      set_text(res, 500, e.what());
    }
    return;
  }

  for (const Mount& m : m_mounts) {
    std::vector<std::string> prefix;
    split_request_path(m.prefix, prefix);
    if (prefix.size() > segments.size() || !std::equal(prefix.begin(), prefix.end(), segments.begin())) continue;
    fs::path file = m.root;
    for (std::size_t i = prefix.size(); i < segments.size(); ++i) file /= segments[i];
    std::error_code ec;
    if (fs::is_directory(file, ec)) file /= "index.html";
    if (!fs::is_regular_file(file, ec)) return set_text(res, 404, "not found: " + path);
    if (!inside(m.root, file)) return set_text(res, 403, "outside the served folder: " + path);
    return send_file(file, req, res);
  }
  set_text(res, 404, "not found: " + path);
}

void FileServer::send_file(const fs::path& file, const httplib::Request& req, httplib::Response& res) const {
  // Opened now: a run that replaces the file (write, then rename) while it is sent does not change what is sent.
  auto in = std::make_shared<std::ifstream>(file, std::ios::binary);
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(file, ec);
  if (!*in || ec) return set_text(res, 404, "cannot read: " + file.filename().string());
  if (!req.ranges.empty() && !ranges_fit(req.ranges, size)) {
    res.status = 416;
    res.set_header("Content-Range", fmt::format("bytes */{}", size));
    return;
  }
  if (size == 0) return res.set_content(std::string(), content_type_for(file));
  res.set_content_provider(static_cast<std::size_t>(size), content_type_for(file),
                           [in](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
                             char buf[64 * 1024];
                             in->seekg(static_cast<std::streamoff>(offset));
                             in->read(buf, static_cast<std::streamsize>(std::min(length, sizeof buf)));
                             const auto n = static_cast<std::size_t>(in->gcount());
                             // A file that shrank while it was sent: end the connection rather than pad it.
                             return n > 0 && sink.write(buf, n);
                           });
}

}  // namespace mgcloth::cli
