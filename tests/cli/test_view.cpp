// `mgcloth view`'s HTTP server and the view/render commands' input checks, driven as a user's browser and shell
// would, without a browser: the page itself is tested in headless Chromium by web/tests/viewer_e2e.mjs.
#include <mgcloth/core/file_io.hpp>

#include <fmt/format.h>

#include "cli_run.hpp"

#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <array>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <netinet/in.h>
#include <poll.h>
#include <regex>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace fs = std::filesystem;

namespace {

using Result = mgcloth::test::CliResult;

Result run(const std::string& args, const std::string& env = "") { return mgcloth::test::run_cli(args, env); }

struct Response {
  int status = 0;
  std::string head, body;
  std::string header(const std::string& name) const {
    std::smatch m;
    if (std::regex_search(head, m, std::regex("\r\n" + name + ": ([^\r]*)", std::regex::icase))) return m[1];
    return {};
  }
};

int connect_to(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = htons(static_cast<uint16_t>(port));
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

/// Reads from fd until `done(data)` holds, the peer closes, or 5 s pass without data.
template <class Done>
std::string read_until(int fd, Done done) {
  std::string data;
  char buf[8192];
  while (!done(data)) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 5000) <= 0) break;
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    data.append(buf, static_cast<size_t>(n));
  }
  return data;
}

std::string read_all(int fd) {
  return read_until(fd, [](const std::string&) { return false; });
}

/// One response with a Content-Length, read from a connection that stays open.
std::string read_response(int fd) {
  const std::regex length("\r\nContent-Length: (\\d+)\r\n", std::regex::icase);
  return read_until(fd, [&](const std::string& data) {
    const auto end = data.find("\r\n\r\n");
    std::smatch m;
    return end != std::string::npos && std::regex_search(data, m, length) &&
           data.size() >= end + 4 + std::stoul(m[1].str());
  });
}

Response parse(const std::string& raw) {
  Response r;
  const auto end = raw.find("\r\n\r\n");
  r.head = raw.substr(0, end == std::string::npos ? raw.size() : end);
  if (end != std::string::npos) r.body = raw.substr(end + 4);
  if (raw.rfind("HTTP/1.1 ", 0) == 0) r.status = std::atoi(raw.c_str() + 9);
  return r;
}

/// One request on its own connection, raw: the path goes out exactly as written (no client normalizes "..").
Response request(int port, const std::string& method, const std::string& path, const std::string& host = "") {
  const int fd = connect_to(port);
  if (fd < 0) return {};
  const std::string h = host.empty() ? fmt::format("127.0.0.1:{}", port) : host;
  const std::string req = fmt::format("{} {} HTTP/1.1\r\nHost: {}\r\nConnection: close\r\n\r\n", method, path, h);
  ::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
  Response r = parse(read_all(fd));
  ::close(fd);
  return r;
}

/// `mgcloth view DIR --port 0` in the background, with the URL it prints.
struct ViewProcess {
  pid_t pid = -1;
  int port = 0;
  std::string output;
  ViewProcess(const fs::path& dir, const fs::path& share) {
    int fds[2];
    EXPECT_EQ(::pipe(fds), 0);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&actions, fds[1], STDERR_FILENO);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    ::setenv("MGCLOTH_SHARE_DIR", share.c_str(), 1);
    const std::string d = dir.string();
    std::vector<char*> argv{const_cast<char*>(MGCLOTH_CLI), const_cast<char*>("view"), const_cast<char*>(d.c_str()),
                            const_cast<char*>("--port"), const_cast<char*>("0"), nullptr};
    EXPECT_EQ(::posix_spawn(&pid, MGCLOTH_CLI, &actions, nullptr, argv.data(), environ), 0);
    ::unsetenv("MGCLOTH_SHARE_DIR");
    posix_spawn_file_actions_destroy(&actions);
    ::close(fds[1]);
    const std::regex url("http://127\\.0\\.0\\.1:(\\d+)/");
    std::smatch m;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!std::regex_search(output, m, url) && std::chrono::steady_clock::now() < deadline) {
      pollfd p{fds[0], POLLIN, 0};
      if (::poll(&p, 1, 200) <= 0) continue;
      char buf[512];
      const ssize_t n = ::read(fds[0], buf, sizeof buf);
      if (n <= 0) break;
      output.append(buf, static_cast<size_t>(n));
    }
    ::close(fds[0]);
    if (std::regex_search(output, m, url)) port = std::stoi(m[1]);
  }
  /// Ctrl-C; returns the exit code.
  int stop() {
    if (pid < 0) return -1;
    ::kill(pid, SIGINT);
    int status = 0;
    ::waitpid(pid, &status, 0);
    pid = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  ~ViewProcess() { stop(); }
};

class View : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() / ("mgcloth_view_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir);
    // A stand-in for the built viewer (share/mgcloth/viewer), so these tests need neither npm nor a browser.
    share = dir / "share";
    write(share / "viewer" / "index.html", "<!doctype html><title>viewer</title>");
    write(share / "viewer" / "vendor" / "three" / "build" / "three.module.js", "export const REVISION = '0';");
    data = dir / "run";
    write(data / "frame_00000.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    write(data / "stats.csv", "frame,step\n1,1\n");
    write(data / "scene.resolved.json", "{}");
    write(data / "animation.glb", std::string("glTF\2\0\0\0", 8));
    write(data / "levels.png", "\x89PNG");
    write(dir / "secret.txt", "not for the browser");
  }
  void TearDown() override { fs::remove_all(dir); }
  static void write(const fs::path& p, const std::string& content) {
    fs::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << content;
  }
  std::string env() const { return "MGCLOTH_SHARE_DIR=" + share.string(); }
  fs::path dir, share, data;
};

}  // namespace

TEST_F(View, ServesTheViewerAndTheFolderWithTheirContentTypes) {
  ViewProcess view(data, share);
  ASSERT_GT(view.port, 0) << view.output;
  EXPECT_NE(view.output.find("1 frame files + animation.glb"), std::string::npos) << view.output;

  const struct {
    std::string path, type, body;
  } cases[] = {
      {"/", "text/html; charset=utf-8", "<!doctype html><title>viewer</title>"},
      {"/index.html?frame=3", "text/html; charset=utf-8", "<!doctype html><title>viewer</title>"},
      {"/vendor/three/build/three.module.js", "text/javascript; charset=utf-8", "export const REVISION = '0';"},
      {"/data/frame_00000.obj", "model/obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"},
      {"/data/stats.csv", "text/csv; charset=utf-8", "frame,step\n1,1\n"},
      {"/data/scene.resolved.json", "application/json", "{}"},
      {"/data/animation.glb", "model/gltf-binary", std::string("glTF\2\0\0\0", 8)},
      {"/data/levels.png", "image/png", "\x89PNG"},
      {"/data/frame%5F00000.obj", "model/obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"},
  };
  for (const auto& c : cases) {
    const Response r = request(view.port, "GET", c.path);
    EXPECT_EQ(r.status, 200) << c.path << "\n" << r.head;
    EXPECT_EQ(r.header("Content-Type"), c.type) << c.path;
    EXPECT_EQ(r.body, c.body) << c.path;
    EXPECT_EQ(r.header("Content-Length"), std::to_string(c.body.size())) << c.path;
  }
  const Response listing = request(view.port, "GET", "/api/listing.json");
  EXPECT_EQ(listing.header("Content-Type"), "application/json");
  EXPECT_NE(listing.body.find(R"({"name":"frame_00000.obj","size":32})"), std::string::npos) << listing.body;
  const Response head = request(view.port, "HEAD", "/data/stats.csv");
  EXPECT_EQ(head.status, 200);
  EXPECT_EQ(head.header("Content-Length"), std::to_string(std::string("frame,step\n1,1\n").size()));
  EXPECT_TRUE(head.body.empty());
  EXPECT_EQ(view.stop(), 0) << "Ctrl-C ends the viewer normally";
}

// A browser sends its next request on a connection once the previous response is in: none pipelines requests, and
// the server (cpp-httplib 0.11) does not read a second request sent before the first is answered.
TEST_F(View, KeepsAConnectionOpenForSeveralRequests) {
  ViewProcess view(data, share);
  ASSERT_GT(view.port, 0) << view.output;
  const int fd = connect_to(view.port);
  ASSERT_GE(fd, 0);
  const std::string host = fmt::format("Host: 127.0.0.1:{}\r\n", view.port);
  const std::string first = "GET /data/stats.csv HTTP/1.1\r\n" + host + "\r\n";
  ::send(fd, first.data(), first.size(), MSG_NOSIGNAL);
  const Response one = parse(read_response(fd));
  EXPECT_EQ(one.status, 200) << one.head;
  EXPECT_EQ(one.body, "frame,step\n1,1\n");
  EXPECT_NE(one.header("Connection"), "close");
  const std::string second = "GET /data/scene.resolved.json HTTP/1.1\r\n" + host + "Connection: close\r\n\r\n";
  ASSERT_EQ(::send(fd, second.data(), second.size(), MSG_NOSIGNAL), static_cast<ssize_t>(second.size()));
  const Response two = parse(read_all(fd));
  ::close(fd);
  EXPECT_EQ(two.status, 200) << two.head;
  EXPECT_EQ(two.body, "{}");
}

TEST_F(View, RefusesPathsOutsideTheServedFoldersAndOtherMethods) {
  fs::create_symlink(dir / "secret.txt", data / "link.txt");
  ViewProcess view(data, share);
  ASSERT_GT(view.port, 0) << view.output;
  for (const std::string path : {"/data/../secret.txt", "/data/%2e%2e/secret.txt", "/data/..%2fsecret.txt",
                                 "/data/%2E%2E/%2E%2E/etc/passwd", "/../../etc/passwd", "/data/a%00b", "/data/%zz",
                                 "/data/..\\secret.txt", "secret.txt"}) {
    const Response r = request(view.port, "GET", path);
    EXPECT_EQ(r.status, 400) << path;
    EXPECT_EQ(r.body.find("not for the browser"), std::string::npos) << path;
  }
  const Response link = request(view.port, "GET", "/data/link.txt");
  EXPECT_EQ(link.status, 403) << "a link out of DIR";
  EXPECT_EQ(link.body.find("not for the browser"), std::string::npos);
  EXPECT_EQ(request(view.port, "GET", "/data/missing.obj").status, 404);
  EXPECT_EQ(request(view.port, "GET", "/data").status, 404) << "no folder listing";
  const Response post = request(view.port, "POST", "/data/stats.csv");
  EXPECT_EQ(post.status, 405);
  EXPECT_EQ(post.header("Allow"), "GET, HEAD");
  EXPECT_EQ(request(view.port, "DELETE", "/data/stats.csv").status, 405);
  EXPECT_TRUE(fs::exists(data / "stats.csv"));
  // A page of another site whose name resolves to 127.0.0.1 (DNS rebinding) must not read DIR.
  EXPECT_EQ(request(view.port, "GET", "/data/stats.csv", "attacker.example:80").status, 403);
  EXPECT_EQ(request(view.port, "GET", "/data/stats.csv", fmt::format("localhost:{}", view.port)).status, 200);
}

TEST_F(View, AnswersByteRangesThatLieInTheFile) {
  ViewProcess view(data, share);
  ASSERT_GT(view.port, 0) << view.output;
  const auto ranged = [&](const std::string& range) {
    const int fd = connect_to(view.port);
    const std::string req = fmt::format("GET /data/stats.csv HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nRange: {}\r\n"
                                        "Connection: close\r\n\r\n", view.port, range);
    ::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
    Response r = parse(read_all(fd));
    ::close(fd);
    return r;
  };
  Response r = ranged("bytes=0-4");  // stats.csv is "frame,step\n1,1\n", 15 bytes
  EXPECT_EQ(r.status, 206) << r.head;
  EXPECT_EQ(r.body, "frame");
  EXPECT_EQ(r.header("Content-Range"), "bytes 0-4/15");
  r = ranged("bytes=-4");
  EXPECT_EQ(r.status, 206) << r.head;
  EXPECT_EQ(r.body, "1,1\n");
  for (const std::string past_the_end : {"bytes=15-", "bytes=10-20", "bytes=-0"}) {
    r = ranged(past_the_end);
    EXPECT_EQ(r.status, 416) << past_the_end << "\n" << r.head;
    EXPECT_EQ(r.header("Content-Range"), "bytes */15") << past_the_end;
    EXPECT_TRUE(r.body.empty()) << past_the_end;
  }
}

// A body the server does not read would be read as the next request on the connection, with a Host header of the
// sender's choice: such requests are refused and their connection closed.
TEST_F(View, ClosesTheConnectionOfARequestWhoseBodyItDoesNotRead) {
  ViewProcess view(data, share);
  ASSERT_GT(view.port, 0) << view.output;
  const std::string inner =
      fmt::format("GET /data/scene.resolved.json HTTP/1.1\r\nHost: 127.0.0.1:{}\r\n\r\n", view.port);
  for (const std::string method : {"GET", "POST", "OPTIONS"}) {
    const int fd = connect_to(view.port);
    ASSERT_GE(fd, 0);
    const std::string req = fmt::format("{} /data/stats.csv HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nContent-Length: {}\r\n\r\n{}",
                                        method, view.port, inner.size(), inner);
    ::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
    const std::string raw = read_all(fd);
    ::close(fd);
    const Response r = parse(raw);
    EXPECT_EQ(r.status, method == "GET" ? 400 : 405) << method << "\n" << raw;
    EXPECT_EQ(r.header("Connection"), "close") << method;
    EXPECT_EQ(raw.find("HTTP/1.1", 1), std::string::npos) << method << ": a second response\n" << raw;
  }
}

TEST_F(View, CtrlCEndsTheViewerWhileABrowserKeepsAConnectionOpen) {
  ViewProcess view(data, share);
  ASSERT_GT(view.port, 0) << view.output;
  const int fd = connect_to(view.port);
  ASSERT_GE(fd, 0);
  const std::string req = fmt::format("GET /data/stats.csv HTTP/1.1\r\nHost: 127.0.0.1:{}\r\n\r\n", view.port);
  ::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
  EXPECT_EQ(parse(read_response(fd)).status, 200);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(view.stop(), 0);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(3));
  ::close(fd);
}

TEST_F(View, ASecondViewerOnTheSamePortIsRefused) {
  ViewProcess view(data, share);
  ASSERT_GT(view.port, 0) << view.output;
  // Under `timeout`: a second viewer that did get the port would serve until stopped.
  const Result r = run(fmt::format("view {} --port {}", data.string(), view.port), env() + " timeout 10");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(fmt::format("--port {}: port in use", view.port)), std::string::npos) << r.out;
  EXPECT_EQ(request(view.port, "GET", "/data/stats.csv").status, 200) << "the first one still serves";
}

TEST_F(View, BadFoldersAndPortsFailWithAMessage) {
  Result r = run("view " + (dir / "nowhere").string(), env());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("nowhere: no such folder"), std::string::npos) << r.out;

  r = run("view " + (data / "stats.csv").string(), env());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("not a folder"), std::string::npos) << r.out;

  fs::create_directories(dir / "empty");
  r = run("view " + (dir / "empty").string(), env());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("nothing to show"), std::string::npos) << r.out;

  r = run("view " + data.string(), "MGCLOTH_SHARE_DIR=" + (dir / "empty").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("the viewer is not built"), std::string::npos) << r.out;

  // A port another program listens on.
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(fd, 1), 0);
  socklen_t len = sizeof addr;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  const int port = ntohs(addr.sin_port);
  r = run(fmt::format("view {} --port {}", data.string(), port), env());
  ::close(fd);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(fmt::format("--port {}: port in use", port)), std::string::npos) << r.out;

  r = run("view " + data.string() + " --port 70000", env());
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("--port"), std::string::npos) << r.out;
}

TEST_F(View, RenderChecksItsArgumentsBeforeStartingABrowser) {
  fs::remove(data / "animation.glb");
  Result r = run("render " + data.string() + " --out " + (dir / "a.jpg").string(), env());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("must name a .png file"), std::string::npos) << r.out;

  r = run("render " + data.string() + " --frame 9 --out " + (dir / "a.png").string(), env());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--frame 9: " + data.string() + " has no frame_00009.obj (frames 0-0, 1 files)"), std::string::npos)
      << r.out;

  r = run("render " + data.string() + " --source glb --out " + (dir / "a.png").string(), env());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("has no animation.glb"), std::string::npos) << r.out;

  r = run("render " + (dir / "nowhere").string() + " --out " + (dir / "a.png").string(), env());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("no such folder"), std::string::npos) << r.out;

  // The stand-in share folder has no render.mjs.
  r = run("render " + data.string() + " --out " + (dir / "a.png").string(), env());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("render.mjs is missing"), std::string::npos) << r.out;
}
