// `mgcloth view DIR` serves the viewer page (web/viewer, copied into the build tree with three.js at build time)
// with DIR under /data/; `mgcloth render DIR` serves the same page to headless Chromium, driven by
// web/render.mjs through playwright-core, and saves what it shows as a PNG. One page draws both, so a picture in
// the README is exactly what a user sees in the viewer.
#include "commands.hpp"
#include "file_server.hpp"
#include "subprocess.hpp"

#include <mgcloth/core/error.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/json.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <thread>

namespace mgcloth::cli {

namespace fs = std::filesystem;

namespace {

struct ViewArgs {
  std::string dir;
  int port = 0;
} g_view;

struct RenderArgs {
  std::string dir, out, source = "auto";
  int frame = -1;
  int width = 960, height = 600;
  bool wireframe = false;
  double timeout = 120.0;
} g_render;

/// What a folder holds that the page can show.
struct DirContents {
  std::vector<int> frames;  ///< numbers of the frame_NNNNN.obj files, sorted
  bool glb = false, convergence = false, stats = false;
  int pngs = 0;
  bool animation() const { return !frames.empty() || glb; }
};

DirContents inspect_dir(const std::string& dir) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) throw_input_error("{}: no such folder", dir);
  if (!fs::is_directory(dir, ec)) throw_input_error("{}: not a folder (give the output folder of mgcloth run or bench)", dir);
  DirContents c;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (!entry.is_regular_file(ec)) continue;
    const std::string name = entry.path().filename().string();
    if (name.size() == 15 && name.rfind("frame_", 0) == 0 && name.substr(11) == ".obj") {
      const std::string digits = name.substr(6, 5);
      if (digits.find_first_not_of("0123456789") == std::string::npos) c.frames.push_back(std::stoi(digits));
    } else if (name == "animation.glb") {
      c.glb = true;
    } else if (name == "convergence.csv") {
      c.convergence = true;
    } else if (name == "stats.csv") {
      c.stats = true;
    } else if (entry.path().extension() == ".png") {
      ++c.pngs;
    }
  }
  if (ec) throw_input_error("{}: cannot list: {}", dir, ec.message());
  std::sort(c.frames.begin(), c.frames.end());
  if (!c.animation() && !c.convergence && c.pngs == 0)
    throw_input_error("{}: nothing to show: no frame_NNNNN.obj or animation.glb (written by mgcloth run), no "
                      "convergence.csv (mgcloth bench convergence) and no .png", dir);
  return c;
}

/// Where the viewer, render.mjs and playwright-core were put by the build: <prefix>/share/mgcloth next to
/// <prefix>/bin/mgcloth (the build tree and an install look alike), or $MGCLOTH_SHARE_DIR.
fs::path share_dir() {
  if (const char* env = std::getenv("MGCLOTH_SHARE_DIR"); env && *env) return env;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw_error("cannot locate the mgcloth executable (/proc/self/exe): {}; set MGCLOTH_SHARE_DIR", ec.message());
  return exe.parent_path().parent_path() / "share" / "mgcloth";
}

fs::path viewer_dir() {
  const fs::path dir = share_dir() / "viewer";
  if (!fs::exists(dir / "index.html"))
    throw_error("the viewer is not built: {} is missing (build the mgcloth_viewer target, or set MGCLOTH_SHARE_DIR)",
                (dir / "index.html").string());
  if (!fs::exists(dir / "vendor" / "three" / "build" / "three.module.js"))
    throw_error("the viewer has no three.js: {} is missing (run scripts/setup.sh, which runs `npm ci` in web/, then "
                "rebuild)", (dir / "vendor/three/build/three.module.js").string());
  return dir;
}

/// The file names of DIR, asked by the page on every load: a run in progress gains frames between two loads.
Generated listing(const fs::path& dir, const std::string& shown_as) {
  Json files = Json::array();
  std::error_code ec;
  std::vector<std::pair<std::string, std::uintmax_t>> entries;
  for (const auto& entry : fs::directory_iterator(dir, ec))
    if (entry.is_regular_file(ec)) entries.emplace_back(entry.path().filename().string(), entry.file_size(ec));
  std::sort(entries.begin(), entries.end());
  for (const auto& [name, size] : entries) files.push_back({{"name", name}, {"size", size}});
  const Json j = {{"dir", shown_as}, {"files", files}};
  return {"application/json", j.dump()};
}

std::unique_ptr<FileServer> make_server(int port, const std::string& dir) {
  auto server = std::make_unique<FileServer>(port);
  server->mount({"/", viewer_dir()});
  server->mount({"/data/", fs::path(dir)});
  server->generate("/api/listing.json", [root = fs::path(dir), dir] { return listing(root, dir); });
  return server;
}

int view() {
  const DirContents contents = inspect_dir(g_view.dir);
  auto server = make_server(g_view.port, g_view.dir);
  const std::string what =
      contents.animation() ? fmt::format("{} frame files{}", contents.frames.size(), contents.glb ? " + animation.glb" : "")
                           : (contents.convergence ? std::string("convergence.csv") : fmt::format("{} pictures", contents.pngs));
  std::printf("mgcloth view: %s (%s) at %s  (Ctrl-C stops)\n", g_view.dir.c_str(), what.c_str(), server->url().c_str());
  std::fflush(stdout);  // a script waiting for the URL reads it through a pipe
  install_interrupt_handler();
  // Whoever started us may stop reading our output (a script that only wanted the URL): that must not end us.
  std::signal(SIGPIPE, SIG_IGN);
  server->serve([] { return interrupted(); });
  std::printf("mgcloth view: stopped after %ld requests\n", server->requests());
  return 0;
}

std::string find_program(const char* env_name, const std::vector<std::string>& names, const std::string& how_to_get) {
  if (const char* env = std::getenv(env_name); env && *env) {
    const std::string found = find_in_path(env);
    if (found.empty()) throw_input_error("{}={}: not an executable program", env_name, env);
    return found;
  }
  for (const auto& n : names)
    if (std::string found = find_in_path(n); !found.empty()) return found;
  throw_input_error("render: {} not found ({}, or set {})", names.front(), how_to_get, env_name);
}

int render() {
  const DirContents contents = inspect_dir(g_render.dir);
  const fs::path out = g_render.out;
  if (out.extension() != ".png") throw_input_error("--out {}: must name a .png file", g_render.out);
  if (!contents.animation() && !contents.convergence)
    throw_input_error("{}: nothing to render: no frame_NNNNN.obj, animation.glb or convergence.csv", g_render.dir);
  if (g_render.source == "obj" && contents.frames.empty()) throw_input_error("--source obj: {} has no frame_NNNNN.obj", g_render.dir);
  if (g_render.source == "glb" && !contents.glb) throw_input_error("--source glb: {} has no animation.glb", g_render.dir);
  // The page checks the frame against the animation; OBJ frames can be checked here with a clearer message.
  const bool obj_only = !contents.frames.empty() && (!contents.glb || g_render.source == "obj");
  if (g_render.frame >= 0 && obj_only &&
      !std::binary_search(contents.frames.begin(), contents.frames.end(), g_render.frame))
    throw_input_error("--frame {}: {} has no frame_{:05d}.obj (frames {}-{}, {} files)", g_render.frame, g_render.dir,
                      g_render.frame, contents.frames.front(), contents.frames.back(), contents.frames.size());

  const fs::path share = share_dir();
  const fs::path script = share / "render.mjs";
  if (!fs::exists(script)) throw_error("render: {} is missing (build the mgcloth_viewer target)", script.string());
  if (!fs::exists(share / "node_modules" / "playwright-core" / "package.json"))
    throw_error("render: playwright-core is missing from {} (run scripts/setup.sh, which runs `npm ci` in web/, then "
                "rebuild)", (share / "node_modules").string());
  const std::string node = find_program("MGCLOTH_NODE", {"node", "nodejs"}, "install Debian's nodejs");
  const std::string chromium = find_program("MGCLOTH_CHROMIUM", {"chromium", "chromium-browser"},
                                            "install Debian's chromium: scripts/setup.sh does");
  std::error_code ec;
  if (out.has_parent_path()) fs::create_directories(out.parent_path(), ec);
  if (ec) throw_input_error("--out {}: cannot create its folder: {}", g_render.out, ec.message());

  auto server = make_server(0, g_render.dir);
  std::atomic<bool> stop{false};
  std::thread serving([&] { server->serve([&] { return stop.load(); }); });
  std::string query = fmt::format("?render=1&mode={}", g_render.wireframe ? "wire" : "shaded");
  if (g_render.frame >= 0) query += fmt::format("&frame={}", g_render.frame);
  if (g_render.source != "auto") query += "&source=" + g_render.source;
  ProgramResult child;
  try {
    child = run_program({node, script.string(), "--url", server->url() + query, "--out", out.string(),
                       "--width", std::to_string(g_render.width), "--height", std::to_string(g_render.height),
                       "--chromium", chromium, "--timeout", fmt::format("{}", g_render.timeout)});
  } catch (const ProgramNotStarted& e) {
    stop = true;
    serving.join();
    throw_error("render: {}", e.what());
  } catch (...) {
    stop = true;
    serving.join();
    throw;
  }
  stop = true;
  serving.join();
  if (!child.succeeded()) {
    std::string why = child.output.empty() ? "render.mjs failed" : last_line(child.output);
    if (why.rfind("render: ", 0) == 0) why.erase(0, 8);
    throw_error("render {}: {} ({})", g_render.dir, why, child.status());
  }
  if (!fs::exists(out)) throw_error("render {}: render.mjs ended without writing {}", g_render.dir, g_render.out);
  std::fputs(child.output.c_str(), stdout);
  return 0;
}

}  // namespace

void add_view_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("view", "Serve a run's animation and stats (or a bench folder's plot) to a browser");
  cmd->add_option("dir", g_view.dir, "Output folder of mgcloth run or mgcloth bench")->required();
  cmd->add_option("--port,-p", g_view.port, "Port on 127.0.0.1 (0: a free one; the URL is printed)")
      ->check(requires_number([](double p) { return p >= 0 && p <= 65535; }, "a port in [0, 65535]"));
}

void add_render_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("render", "Render a frame of a run (or a bench folder's plot) to PNG in headless Chromium");
  cmd->add_option("dir", g_render.dir, "Output folder of mgcloth run or mgcloth bench convergence")->required();
  cmd->add_option("--out,-o", g_render.out, "PNG file to write")->required();
  cmd->add_option("--frame,-f", g_render.frame, "Frame number (default: the last)")
      ->check(requires_number([](double f) { return f >= 0; }, "a frame number >= 0"));
  cmd->add_option("--width", g_render.width, "Picture width, px")
      ->check(requires_number([](double w) { return w >= 64 && w <= 8192; }, "in [64, 8192]"));
  cmd->add_option("--height", g_render.height, "Picture height, px")
      ->check(requires_number([](double h) { return h >= 64 && h <= 8192; }, "in [64, 8192]"));
  cmd->add_flag("--wireframe", g_render.wireframe, "Draw the cloth's triangle edges instead of shading it");
  cmd->add_option("--source", g_render.source, "Frames from animation.glb or the OBJ files (auto: glb when present)")
      ->check(CLI::IsMember({"auto", "glb", "obj"}));
  cmd->add_option("--timeout", g_render.timeout, "Seconds to wait for the page")
      ->check(requires_number([](double t) { return t > 0; }, "a positive number of seconds"));
}

int run_view_command() { return view(); }
int run_render_command() { return render(); }

}  // namespace mgcloth::cli
