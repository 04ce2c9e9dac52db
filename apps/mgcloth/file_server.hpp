#pragma once
// The web server of `mgcloth view` and `mgcloth render`: folders and generated documents over HTTP on 127.0.0.1,
// GET and HEAD only, on cpp-httplib (Debian's libcpp-httplib-dev). What is ours is what may be served: request
// paths are checked before they reach the file system, a link cannot lead out of a served folder, and only
// requests naming this machine's loopback in their Host header are answered.
#include <atomic>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace httplib {
class Server;
struct Request;
struct Response;
}  // namespace httplib

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

/// Percent-decodes a request target's path (the query and fragment dropped) and splits it into segments, dropping
/// empty and "." segments. Returns false for what must never reach the file system: "..", NUL, a backslash, an
/// encoded '/', a bad escape, a target not starting with '/'.
bool split_request_path(const std::string& target, std::vector<std::string>& segments);

class FileServer {
 public:
  /// Binds 127.0.0.1:`port` (0: a free port chosen by the kernel). Throws InputError naming `--port` when the
  /// port is taken or not allowed.
  explicit FileServer(int port);
  ~FileServer();
  FileServer(const FileServer&) = delete;
  FileServer& operator=(const FileServer&) = delete;

  /// Longest prefix wins; a request for a folder is answered with its index.html.
  void mount(Mount m);
  /// A URL path answered by `make` on every request (before the mounts are searched).
  void generate(const std::string& path, std::function<Generated()> make);

  int port() const { return m_port; }
  std::string url() const;

  /// Serves until `stop()` returns true (asked several times a second), then waits for the open connections to
  /// close (at most the keep-alive timeout, one second). Throws Error when the server fails on its own.
  void serve(const std::function<bool()>& stop);
  /// Requests answered so far (any status).
  long requests() const { return m_requests.load(); }

 private:
  bool host_ok(const httplib::Request& req) const;
  void answer(const httplib::Request& req, httplib::Response& res) const;
  void send_file(const std::filesystem::path& file, const httplib::Request& req, httplib::Response& res) const;

  std::unique_ptr<httplib::Server> m_server;
  int m_port = 0;
  std::vector<Mount> m_mounts;
  std::map<std::string, std::function<Generated()>> m_generated;
  std::atomic<long> m_requests{0};
};

}  // namespace mgcloth::cli
