#pragma once
// A small HTTP/1.1 static file server for `mgcloth view` and `mgcloth render`: GET and HEAD only, bound to
// 127.0.0.1, one thread per connection (browsers keep several connections open, some idle).
#include <atomic>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace mgcloth::cli {

/// A folder served under a URL prefix ("/" or "/data/").
struct Mount {
  std::string prefix;  ///< starts and ends with '/'
  std::filesystem::path root;
};

/// The response to one request, for generated content (e.g. a folder listing).
struct Generated {
  std::string content_type;
  std::string body;
};

/// The Content-Type for a file name's extension; application/octet-stream when unknown.
std::string content_type_for(const std::filesystem::path& file);

/// Percent-decodes a request path (without its query) and splits it into segments, dropping empty and "."
/// segments. Returns false for what must never reach the file system: "..", NUL, a backslash, a bad escape.
bool split_request_path(const std::string& target, std::vector<std::string>& segments);

class HttpServer {
 public:
  /// Binds 127.0.0.1:`port` (0: a free port chosen by the kernel). Throws InputError naming `--port` when the
  /// port is taken or not allowed.
  explicit HttpServer(int port);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  /// Longest prefix wins; a request for a folder of the "/" mount is answered with its index.html.
  void mount(Mount m);
  /// A URL path answered by `make` on every request (before the mounts are searched).
  void generate(const std::string& path, std::function<Generated()> make);

  int port() const { return m_port; }
  std::string url() const;

  /// Serves until `stop()` returns true (asked several times a second), then closes the open connections.
  void serve(const std::function<bool()>& stop);
  /// Requests answered so far (any status).
  long requests() const { return m_requests.load(); }

 private:
  struct Shared;
  void handle_connection(int fd);
  /// Writes one response; returns false when the connection must close.
  bool respond(int fd, const std::string& method, const std::string& target, bool keep_alive, bool host_ok);

  int m_listen_fd = -1;
  int m_port = 0;
  std::vector<Mount> m_mounts;
  std::map<std::string, std::function<Generated()>> m_generated;
  std::atomic<long> m_requests{0};
  std::shared_ptr<Shared> m_shared;
};

}  // namespace mgcloth::cli
