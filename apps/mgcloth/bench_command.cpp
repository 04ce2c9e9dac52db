// `mgcloth bench`: the solver benchmarks of studies/convergence.hpp with their outputs — CSV, a JSON summary, a table
// on stdout and a plot drawn by the matplotlib scripts of bench/, which are embedded in the binary at build time and
// run with python3 from a temporary copy (so the command works from any folder and when installed).
#include "commands.hpp"
#include "subprocess.hpp"

#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/embedded/plot_convergence.hpp>
#include <mgcloth/embedded/plot_scalability.hpp>
#include <mgcloth/studies/convergence.hpp>
#include <mgcloth/studies/shell_bench.hpp>
#include <mgcloth/studies/timestep_bench.hpp>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <unistd.h>

namespace mgcloth::cli {

namespace fs = std::filesystem;

namespace {

struct ConvergenceArgs {
  std::string scene, solvers, out, state_cache, body, warmup, checkpoint;
  int step = 0;
  double budget = 10.0;
  double reference_seconds = 600.0;
  int max_iters = 10000;
  int threads = 0;
  int vertices = 0;
  bool quiet = false;
  CLI::Option* vertices_option = nullptr;
  CLI::Option* step_option = nullptr;
} g_conv;

struct ScalabilityArgs {
  std::string scene, vertices, solver, out;
  int steps = 3, warmup = 1, substeps = 0;
  double rel_grad = 1e-2;
  int threads = 0;
  bool quiet = false;
} g_scal;

struct ShellArgs {
  std::vector<std::string> scenes, start_from;
  std::string levels = "1,2,3,4", solvers = "tr-dogleg,tr-stcg", out;
  double time_step = 0.0, max_seconds = 0.0, checkpoint_seconds = 600.0;
  int max_iters = 0, threads = 0;
  bool quiet = false, verbose = false, resume = false;
} g_shell;

struct TimestepArgs {
  std::vector<std::string> scenes;
  std::string solvers = "tr-dogleg,rmtr,newton-ls,newton-damped,linearized", out;
  int level = 3, max_iters = 0, threads = 0;
  double max_dt = 1.0, min_dt = 1.0 / 64.0, window = 0.0, max_seconds = 0.0, max_try_seconds = 0.0;
  double stall_rel_grad = 1e-5, stall_abs_grad = 0.0;
  bool resume = false, quiet = false, verbose = false;
} g_step;

struct ProjectionArgs {
  std::string scene, out;
  int level = 0;
  bool quiet = false;
} g_proj;

/// Draws `png` from `csv` with an embedded plot script. Interpreters tried: $MGCLOTH_PYTHON alone when set;
/// otherwise python3 from PATH, then /usr/bin/python3 (Debian's python3-matplotlib lives there when PATH starts with
/// a virtual environment or pyenv). Throws Error saying why the picture could not be made.
void make_plot(std::string_view script, const std::string& script_name, const fs::path& csv, const fs::path& png,
               const std::string& title) {
  const fs::path tmp = fs::temp_directory_path() / fmt::format("mgcloth_{}_{}.py", script_name, ::getpid());
  write_file_atomic(tmp, std::string(script));
  struct Remove {
    fs::path p;
    ~Remove() {
      std::error_code ec;
      fs::remove(p, ec);
    }
  } remove_tmp{tmp};

  std::vector<std::string> interpreters;
  if (const char* env = std::getenv("MGCLOTH_PYTHON"); env && *env) {
    interpreters.push_back(env);
  } else {
    interpreters = {"python3"};
    if (fs::exists("/usr/bin/python3")) interpreters.push_back("/usr/bin/python3");
  }
  std::vector<std::string> why;
  for (const auto& python : interpreters) {
    std::vector<std::string> argv{python, tmp.string(), csv.string(), png.string()};
    if (!title.empty()) argv.insert(argv.end(), {"--title", title});
    ProgramResult r;
    try {
      r = run_program(argv);
    } catch (const ProgramNotStarted& e) {
      why.push_back(e.what());
      continue;
    }
    // 127: what a shim (pyenv's, say) exits with when the interpreter it stands for is not installed.
    if (r.exit_code == 127 && r.signal == 0) {
      why.push_back(fmt::format("{} not found", python));
      continue;
    }
    if (r.succeeded() && fs::exists(png)) return;
    if (r.exit_code == 3 && r.signal == 0) {  // the script's "matplotlib is missing"
      why.push_back(fmt::format("{} has no matplotlib", python));
      continue;
    }
    throw_error("could not make {}: {} {} failed ({}): {}", png.string(), python, script_name, r.status(),
                last_line(r.output));
  }
  throw_error("could not make {}: {} (install python3-matplotlib, or set MGCLOTH_PYTHON to a python3 that has it)",
              png.string(), fmt::join(why, "; "));
}

void check_scene_file(const std::string& scene) {
  if (!fs::exists(scene)) throw_input_error("{}: no such file", scene);
  if (fs::is_directory(scene)) throw_input_error("{}: is a folder, not a scene file", scene);
}

/// Creates --out and checks that files can be written there, before any long computation.
void prepare_out_dir(const fs::path& out) {
  std::error_code ec;
  if (fs::exists(out, ec) && !fs::is_directory(out, ec)) throw_input_error("--out: {} exists and is not a folder", out.string());
  fs::create_directories(out, ec);
  if (ec) throw_input_error("--out: cannot create {}: {}", out.string(), ec.message());
  const fs::path probe = out / fmt::format(".mgcloth_write_test{}", ::getpid());
  if (std::FILE* f = std::fopen(probe.c_str(), "w")) {
    std::fclose(f);
    fs::remove(probe, ec);
  } else {
    throw_input_error("--out: cannot write to {}", out.string());
  }
}

/// "--solvers: <message>" for a spec the factory rejects.
template <class F>
auto with_prefix(const std::string& option, F&& f) {
  try {
    return f();
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", option, e.what()));
  }
}

/// A comma-separated list of integers in [lo, hi] for `option`; `what` and `example` name them in messages.
std::vector<Index> parse_int_list(const std::string& list, const char* option, const char* what, const char* example,
                                  long long lo, long long hi) {
  std::vector<Index> out;
  size_t start = 0;
  while (true) {
    const size_t end = list.find(',', start);
    std::string item = list.substr(start, end == std::string::npos ? std::string::npos : end - start);
    item.erase(0, item.find_first_not_of(' '));
    item.erase(item.find_last_not_of(' ') + 1);
    long long n = 0;
    const auto [ptr, ec] = std::from_chars(item.data(), item.data() + item.size(), n);
    if (item.empty() || ec != std::errc() || ptr != item.data() + item.size())
      throw_input_error("{}: \"{}\" is not a {} (expected a list like {})", option, item, what, example);
    if (n < lo || n > hi) throw_input_error("{}: {} is out of range [{}, {}]", option, n, lo, hi);
    out.push_back(static_cast<Index>(n));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return out;
}

std::vector<Index> parse_vertex_list(const std::string& list) {
  return parse_int_list(list, "--vertices", "vertex count", "40000,80000", 4, 5'000'000);
}

std::string seconds_or_dash(const std::optional<double>& s) { return s ? fmt::format("{:.3f}", *s) : "-"; }

void set_log_level(bool quiet) { logger().set_level(quiet ? spdlog::level::warn : spdlog::level::info); }

int run_convergence_command() {
  check_scene_file(g_conv.scene);
  const auto specs = with_prefix("--solvers", [] { return studies::parse_solver_list(g_conv.solvers); });
  const bool step_given = g_conv.step_option->count() > 0;
  if (g_conv.checkpoint.empty() && !step_given) throw_input_error("--step is required without --from-checkpoint");
  if (step_given && g_conv.step < 1) throw_input_error("--step: must be at least 1 (got {})", g_conv.step);
  if (!g_conv.checkpoint.empty()) {
    if (g_conv.vertices_option->count() > 0)
      throw_input_error("--vertices: a checkpoint holds the state of the scene's own cloths; drop --vertices or "
                        "--from-checkpoint");
    if (!g_conv.state_cache.empty() || !g_conv.warmup.empty())
      throw_input_error("--from-checkpoint: the start state is the checkpoint's; drop --state-cache and "
                        "--warmup-solver");
  }
  if (!(g_conv.budget > 0.0) || !std::isfinite(g_conv.budget))
    throw_input_error("--budget: must be a positive number of seconds (got {})", g_conv.budget);
  if (g_conv.max_iters < 1) throw_input_error("--max-iters: must be at least 1 (got {})", g_conv.max_iters);
  if (!(g_conv.reference_seconds > 0.0) || !std::isfinite(g_conv.reference_seconds))
    throw_input_error("--reference-seconds: must be a positive number of seconds (got {})", g_conv.reference_seconds);
  if (g_conv.threads < 0) throw_input_error("--threads: must be non-negative (got {})", g_conv.threads);
  sim::Scene scene = sim::load_scene(g_conv.scene);
  if (g_conv.vertices_option->count() > 0)
    scene = with_prefix("--vertices", [&] { return studies::with_vertex_count(std::move(scene), g_conv.vertices); });
  studies::ConvergenceOptions opt;
  opt.step = g_conv.step;
  opt.checkpoint = g_conv.checkpoint;
  opt.solvers = specs;
  opt.budget_seconds = g_conv.budget;
  opt.max_iters = g_conv.max_iters;
  opt.reference_max_seconds = g_conv.reference_seconds;
  opt.threads = g_conv.threads;
  opt.state_cache = g_conv.state_cache;
  opt.body = g_conv.body;
  if (!g_conv.warmup.empty()) {
    opt.warmup = with_prefix("--warmup-solver", [] { return studies::parse_solver_spec(g_conv.warmup); });
    with_prefix("--warmup-solver", [&] { return studies::check_solver_spec(opt.warmup); });
  }
  for (size_t i = 0; i < specs.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (specs[i].label == specs[j].label) throw_input_error("--solvers: \"{}\" is listed twice", specs[i].label);
  for (const auto& s : specs) with_prefix("--solvers", [&] { return studies::check_solver_spec(s); });
  const fs::path out = g_conv.out;
  prepare_out_dir(out);
  set_log_level(g_conv.quiet);

  const studies::ConvergenceResult result = studies::run_convergence(scene, opt);
  write_file_atomic(out / "convergence.csv", studies::convergence_csv(result));
  write_file_atomic(out / "convergence.json", studies::to_json(result, opt).dump(2) + "\n");

  std::vector<std::string> bodies;
  for (const auto& b : result.bodies) bodies.push_back(fmt::format("\"{}\"", b));
  std::string table = fmt::format("{}: {} {} ({} points{}), step {} (start state {}{})\n", result.scene,
                                  bodies.size() > 1 ? "bodies" : "body", fmt::join(bodies, " + "), result.vertices,
                                  bodies.size() > 1 ? ", one joint step" : "", result.step, result.start_state,
                                  result.start_state == "simulated" ? " with " + result.warmup_solver : "");
  const auto contact_text = [](const studies::ContactCheck& c) {
    return fmt::format("{} contact pairs, min distance {:.3e} m, {} intersections", c.pairs, c.min_distance,
                       c.intersections);
  };
  if (result.cloth_contact) table += fmt::format("cloth contact at x0: {}\n", contact_text(result.start));
  for (const auto& r : result.references)
    table += fmt::format("E* ({}) = {:.12e} by {}{}: {} iterations, relative gradient {:.1e} ({})\n", r.form, r.energy,
                         r.solver,
                         r.polished_from.empty()
                             ? std::string()
                             : fmt::format(" from {}'s final iterate (from x0: {:.12e})", r.polished_from, r.unpolished_energy),
                         r.iterations, r.rel_grad, r.status);
  size_t width = 6;
  for (const auto& s : result.summaries) width = std::max(width, s.solver.size());
  table += fmt::format("{:<{}}  {:<10}  {:>10}  {:>8}  {:>8}  {:>8}  {:>8}  {:>11}  {}\n", "solver", width, "form",
                       "iterations", "time (s)", "t(1e-2)", "t(1e-3)", "t(1e-4)", "final error", "status");
  for (const auto& s : result.summaries)
    table += fmt::format("{:<{}}  {:<10}  {:>10}  {:>8.3f}  {:>8}  {:>8}  {:>8}  {:>11.2e}  {}\n", s.solver, width, s.form,
                         s.iterations, s.seconds, seconds_or_dash(s.time_to[0]), seconds_or_dash(s.time_to[1]),
                         seconds_or_dash(s.time_to[2]), s.final_error, s.status);
  if (result.cloth_contact)
    for (const auto& s : result.summaries)
      table += fmt::format("cloth contact at the end of {}: {}\n", s.solver,
                           s.contact.intersections < 0 ? std::string("- (no final iterate)") : contact_text(s.contact));
  std::fputs(table.c_str(), stdout);
  std::fflush(stdout);

  const std::string title = fmt::format("{}, {} vertices, step {}", fs::path(result.scene).filename().string(),
                                        result.vertices, result.step);
  make_plot(embedded::plot_convergence_py, "plot_convergence.py", out / "convergence.csv", out / "convergence.png", title);
  std::printf("wrote %s: convergence.csv, convergence.json, convergence.png\n", out.string().c_str());
  return 0;
}

int run_scalability_command() {
  check_scene_file(g_scal.scene);
  studies::ScalabilityOptions opt;
  opt.vertices = parse_vertex_list(g_scal.vertices);
  opt.solver = with_prefix("--solver", [] { return studies::parse_solver_spec(g_scal.solver); });
  opt.steps = g_scal.steps;
  opt.warmup = g_scal.warmup;
  opt.rel_grad = g_scal.rel_grad;
  opt.threads = g_scal.threads;
  if (opt.steps < 1) throw_input_error("--steps: must be at least 1 (got {})", opt.steps);
  if (opt.warmup < 0) throw_input_error("--warmup: must be non-negative (got {})", opt.warmup);
  if (!(opt.rel_grad > 0.0 && opt.rel_grad < 1.0)) throw_input_error("--rel-grad: must be in (0, 1) (got {})", opt.rel_grad);
  if (opt.threads < 0) throw_input_error("--threads: must be non-negative (got {})", opt.threads);
  if (g_scal.substeps < 0) throw_input_error("--substeps: must be positive (got {})", g_scal.substeps);
  with_prefix("--solver", [&] { return studies::check_solver_spec(opt.solver); });
  sim::Scene scene = sim::load_scene(g_scal.scene);
  if (g_scal.substeps > 0) scene.substeps = g_scal.substeps;
  for (Index n : opt.vertices) with_prefix("--vertices", [&] { return studies::with_vertex_count(scene, n); });
  const fs::path out = g_scal.out;
  prepare_out_dir(out);
  set_log_level(g_scal.quiet);

  const auto rows = studies::run_scalability(scene, opt);
  write_file_atomic(out / "scalability.csv", studies::scalability_csv(rows, opt));
  std::string table = fmt::format("{}: {}, dt = 1/{:g} s, {} steps after {} warm-up steps, relative gradient {:g}, {} threads\n",
                                  scene.file, opt.solver.label, 1.0 / scene.step_size(), opt.steps, opt.warmup,
                                  opt.rel_grad, opt.threads > 0 ? opt.threads : num_threads());
  table += fmt::format("{:>9}  {:>10}  {:>15}  {:>16}  {:>13}  {:>11}\n", "vertices", "ms/step", "iterations/step",
                       "solve ms/step", "ms/iteration", "unconverged");
  for (const auto& r : rows)
    table += fmt::format("{:>9}  {:>10.1f}  {:>15.2f}  {:>16.1f}  {:>13.2f}  {:>11}\n", r.vertices, r.ms_per_step,
                         r.iterations_per_step, r.solve_ms_per_step,
                         r.iterations_per_step > 0.0 ? r.solve_ms_per_step / r.iterations_per_step : 0.0,
                         r.unconverged_steps);
  std::fputs(table.c_str(), stdout);
  std::fflush(stdout);
  const std::string title = fmt::format("{}, {}", fs::path(scene.file).filename().string(), opt.solver.label);
  make_plot(embedded::plot_scalability_py, "plot_scalability.py", out / "scalability.csv", out / "scalability.png", title);
  std::printf("wrote %s: scalability.csv, scalability.png\n", out.string().c_str());
  return 0;
}

int run_shells_command() {
  studies::ShellBenchOptions opt;
  opt.levels.clear();
  for (Index v : parse_int_list(g_shell.levels, "--levels", "level", "1,2,3,4", 1, 9)) opt.levels.push_back(v);
  opt.solvers = with_prefix("--solvers", [] { return studies::parse_solver_list(g_shell.solvers); });
  for (const auto& s : opt.solvers) with_prefix("--solvers", [&] { return studies::check_solver_spec(s); });
  opt.time_step = g_shell.time_step;
  opt.max_iters = g_shell.max_iters;
  opt.max_seconds = g_shell.max_seconds;
  opt.threads = g_shell.threads;
  std::vector<sim::Scene> scenes;
  for (const auto& f : g_shell.scenes) {
    check_scene_file(f);
    scenes.push_back(sim::load_scene(f));
  }
  const fs::path out = g_shell.out;
  prepare_out_dir(out);
  opt.states_dir = (out / "states").string();
  opt.resume = g_shell.resume;
  if (!(g_shell.checkpoint_seconds >= 0.0) || !std::isfinite(g_shell.checkpoint_seconds))
    throw_input_error("--checkpoint-seconds: must be a number of seconds >= 0 (got {})", g_shell.checkpoint_seconds);
  opt.checkpoint_seconds = g_shell.checkpoint_seconds;
  for (const auto& f : g_shell.start_from) {
    if (!fs::is_regular_file(f)) throw_input_error("--start-from {}: no such file", f);
    opt.start_from.push_back(f);
  }
  set_log_level(g_shell.quiet);
  if (g_shell.verbose) logger().set_level(spdlog::level::debug);
  // Rewritten after every solve: a study of hours keeps what it has measured if it is stopped.
  const auto write = [&](const std::vector<studies::ShellBenchRow>& rows) {
    write_file_atomic(out / "shells.csv", studies::shell_bench_csv(rows));
    write_file_atomic(out / "shells.json", studies::shell_bench_json(rows, opt).dump(2) + "\n");
  };
  // Ctrl-C (or SIGTERM) ends the running solve at its next iteration with its state written; --resume goes on.
  install_interrupt_handler();
  const auto rows = studies::run_shell_bench(scenes, opt, write);
  write(rows);
  std::string table = fmt::format("{:<12} {:>5} {:>7} {:<12} {:>10} {:>11} {:>10} {:>9}\n", "shell", "level", "dofs",
                                  "solver", "iterations", "status", "rel_grad", "wall_s");
  for (const auto& r : rows)
    table += fmt::format("{:<12} {:>5} {:>7} {:<12} {:>10} {:>11} {:>10.2e} {:>9.2f}\n", r.shell, r.level, r.dofs,
                         r.solver, r.iterations, r.status,
                         r.initial_grad_norm > 0 ? r.grad_norm / r.initial_grad_norm : 0.0, r.wall_s);
  std::fputs(table.c_str(), stdout);
  std::printf("wrote %s: shells.csv, shells.json\n", out.string().c_str());
  if (interrupted()) {
    std::fprintf(stderr, "mgcloth: interrupted; continue with --resume\n");
    return 130;
  }
  return 0;
}

/// The rows of an earlier run's timestep.json, when it measured what `opt` asks for: the same level, window, caps
/// per solve and stall criterion (solvers, time steps and the try cap may differ; rows are matched one by one).
std::vector<studies::TimestepBenchRow> resumable_rows(const fs::path& file, const studies::TimestepBenchOptions& opt) {
  if (!fs::exists(file)) return {};
  const Json j = load_json(file.string());
  // A key that an older file lacks had its default then.
  const auto check = [&](const char* key, double now, const char* option,
                         double missing = std::numeric_limits<double>::quiet_NaN()) {
    const double then = !j.contains(key)         ? missing
                        : j.at(key).is_number() ? j.at(key).get<double>()
                                                : std::numeric_limits<double>::quiet_NaN();
    if (then != now)
      throw_input_error("--resume: {} was written with {} = {}, this run has {}", file.string(), option,
                        j.contains(key) ? j.at(key).dump() : "(none)", now);
  };
  check("level", opt.level, "--level");
  check("window", opt.window, "--window");
  check("max_iters", opt.max_iters, "--max-iters");
  check("max_seconds", opt.max_seconds, "--max-seconds");
  check("stall_rel_grad", opt.stall_rel_grad, "--stall-rel-grad");
  check("stall_abs_grad", opt.stall_abs_grad, "--stall-abs-grad", 0.0);
  try {
    return studies::timestep_bench_rows(j);
  } catch (const Json::exception& e) {
    throw_input_error("--resume: {}: {}", file.string(), e.what());
  }
}

int run_timestep_command() {
  studies::TimestepBenchOptions opt;
  if (g_step.level < 1 || g_step.level > 9) throw_input_error("--level: {} is out of range [1, 9]", g_step.level);
  opt.level = g_step.level;
  opt.solvers = with_prefix("--solvers", [] { return studies::parse_solver_list(g_step.solvers); });
  for (size_t i = 0; i < opt.solvers.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (opt.solvers[i].label == opt.solvers[j].label)
        throw_input_error("--solvers: \"{}\" is listed twice", opt.solvers[i].label);
  for (const auto& s : opt.solvers) with_prefix("--solvers", [&] { return studies::check_solver_spec(s); });
  const auto positive = [](const char* option, double v) {
    if (!(v > 0.0) || !std::isfinite(v)) throw_input_error("{}: must be a positive number of seconds (got {})", option, v);
  };
  positive("--max-dt", g_step.max_dt);
  positive("--min-dt", g_step.min_dt);
  if (g_step.min_dt > g_step.max_dt)
    throw_input_error("--min-dt: {} is larger than --max-dt ({})", g_step.min_dt, g_step.max_dt);
  if (!(g_step.window >= 0.0) || !std::isfinite(g_step.window))
    throw_input_error("--window: must be a positive number of seconds, or 0 for the scene's duration (got {})",
                      g_step.window);
  if (g_step.max_iters < 0) throw_input_error("--max-iters: must be at least 1, or 0 for the scenes' (got {})", g_step.max_iters);
  if (!(g_step.max_seconds >= 0.0) || std::isnan(g_step.max_seconds))
    throw_input_error("--max-seconds: must be a positive number of seconds, or 0 for no cap (got {})", g_step.max_seconds);
  if (!(g_step.max_try_seconds >= 0.0) || std::isnan(g_step.max_try_seconds))
    throw_input_error("--max-try-seconds: must be a positive number of seconds, or 0 for no cap (got {})",
                      g_step.max_try_seconds);
  if (!(g_step.stall_rel_grad >= 0.0 && g_step.stall_rel_grad < 1.0))
    throw_input_error("--stall-rel-grad: must be in [0, 1) (got {})", g_step.stall_rel_grad);
  if (!(g_step.stall_abs_grad >= 0.0) || !std::isfinite(g_step.stall_abs_grad))
    throw_input_error("--stall-abs-grad: must be non-negative (got {})", g_step.stall_abs_grad);
  if (g_step.threads < 0) throw_input_error("--threads: must be non-negative (got {})", g_step.threads);
  opt.max_dt = g_step.max_dt;
  opt.min_dt = g_step.min_dt;
  opt.window = g_step.window;
  opt.max_iters = g_step.max_iters;
  opt.max_seconds = g_step.max_seconds;
  opt.max_try_seconds = g_step.max_try_seconds;
  opt.stall_rel_grad = g_step.stall_rel_grad;
  opt.stall_abs_grad = g_step.stall_abs_grad;
  opt.threads = g_step.threads;
  std::vector<sim::Scene> scenes;
  for (const auto& f : g_step.scenes) {
    check_scene_file(f);
    scenes.push_back(sim::load_scene(f));
    if (scenes.back().shells.empty()) throw_input_error("{}: the scene has no shells", f);
  }
  const fs::path out = g_step.out;
  prepare_out_dir(out);
  const std::vector<studies::TimestepBenchRow> previous = g_step.resume ? resumable_rows(out / "timestep.json", opt)
                                                                    : std::vector<studies::TimestepBenchRow>{};
  set_log_level(g_step.quiet);
  if (g_step.verbose) logger().set_level(spdlog::level::debug);
  // Rewritten after every try: a study of an hour keeps what it has measured if it is stopped.
  const auto write = [&](const std::vector<studies::TimestepBenchRow>& rows) {
    write_file_atomic(out / "timestep.csv", studies::timestep_bench_csv(rows));
    write_file_atomic(out / "timestep.json", studies::timestep_bench_json(rows, opt).dump(2) + "\n");
  };
  const auto rows = studies::run_timestep_bench(scenes, opt, write, previous);
  write(rows);
  const auto summary = studies::timestep_bench_summary(rows);
  size_t width = 6;
  for (const auto& s : summary) width = std::max(width, s.solver.size());
  std::string table = fmt::format("{:<12} {:>6} {:<{}} {:>10} {:>10} {:>9} {:>6} {:>9}\n", "shell", "dofs", "solver",
                                  width, "largest dt", "iterations", "wall_s", "tries", "total_s");
  for (const auto& s : summary)
    table += fmt::format("{:<12} {:>6} {:<{}} {:>10} {:>10} {:>9.2f} {:>6} {:>9.2f}\n", s.shells, s.dofs, s.solver,
                         width, s.largest_dt > 0 ? fmt::format("{:g}", s.largest_dt) : "none", s.iterations, s.wall_s,
                         s.tries, s.total_wall_s);
  std::fputs(table.c_str(), stdout);
  std::printf("wrote %s: timestep.csv, timestep.json\n", out.string().c_str());
  return 0;
}

int run_projections_command() {
  check_scene_file(g_proj.scene);
  sim::Scene scene = sim::load_scene(g_proj.scene);
  if (scene.shells.empty()) throw InputError(fmt::format("{}: the scene has no shells", g_proj.scene));
  if (g_proj.level > 0) scene.shells.front().level = g_proj.level;
  const fs::path out = g_proj.out;
  prepare_out_dir(out);
  set_log_level(g_proj.quiet);
  const auto rows = studies::run_projection_bench(scene);
  write_file_atomic(out / "projections.csv", studies::projection_bench_csv(rows));
  std::string table = fmt::format("{:<20} {:>5} {:>7} {:>7} {:>10} {:>10} {:>12} {:>9} {:>10}\n", "operator", "level",
                                  "fine", "coarse", "build_ms", "apply_ms", "bytes", "entries", "|PSq-q|");
  for (const auto& r : rows)
    table += fmt::format("{:<20} {:>5} {:>7} {:>7} {:>10.3f} {:>10.4f} {:>12} {:>9} {:>10.2e}\n", r.operator_name,
                         r.fine_level, r.fine_dofs, r.coarse_dofs, r.build_ms, r.apply_ms, r.memory_bytes, r.entries,
                         r.exactness);
  std::fputs(table.c_str(), stdout);
  std::printf("wrote %s: projections.csv\n", out.string().c_str());
  return 0;
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto* bench = app.add_subcommand("bench", "Solver benchmarks: convergence on one frozen step, scalability with size");
  bench->require_subcommand(1);

  auto* conv = bench->add_subcommand(
      "convergence", "Relative energy error against time of several solvers on the same frozen step (Wang 2018, Fig. 4)");
  conv->add_option("scene", g_conv.scene, "Scene file (JSON)")->required();
  g_conv.step_option = conv->add_option("--step", g_conv.step,
                  "K: benchmark the scene's K-th step (K - 1 steps are simulated first); with --from-checkpoint, "
                  "the checkpoint's step + 1 (the default there)");
  conv->add_option("--from-checkpoint", g_conv.checkpoint,
                   "Start from a run's checkpoint.bin (`mgcloth run` of this scene) instead of simulating: benchmarks "
                   "the step after it");
  conv->add_option("--solvers", g_conv.solvers,
                   "Comma-separated solvers, each NAME or NAME@key=value@... (e.g. newton,newton@linear_solver=pcg-mg)")
      ->required();
  conv->add_option("--out,-o", g_conv.out, "Output folder (created if missing)")->required();
  conv->add_option("--body", g_conv.body,
                   "The cloth or shell whose step is benchmarked, by name (default: the first); with cloth contact, "
                   "the joint step of its contact group");
  conv->add_option("--budget", g_conv.budget, "Wall-time budget per solver, seconds")->default_val(10.0);
  conv->add_option("--max-iters", g_conv.max_iters, "Iteration cap per solver")->default_val(10000);
  conv->add_option("--reference-seconds", g_conv.reference_seconds,
                   "Wall-time cap of each E* reference solve, seconds (its final energy is used when it stops)")
      ->default_val(600.0);
  conv->add_option("--threads,-j", g_conv.threads, "Worker threads (default: the scene's)");
  g_conv.vertices_option =
      conv->add_option("--vertices", g_conv.vertices, "Target vertex count of each generated cloth (per cloth)");
  conv->add_option("--state-cache", g_conv.state_cache,
                   "File caching the state at the start of step K (reused when the scene, vertex count and K match)");
  conv->add_option("--warmup-solver", g_conv.warmup,
                   "The solver that simulates steps 1 to K - 1, NAME or NAME@key=value@... (default: the E* "
                   "reference, newton-direct)");
  conv->add_flag("--quiet,-q", g_conv.quiet, "No progress log");

  auto* scal = bench->add_subcommand("scalability", "Wall time per step of one solver against the cloth's vertex count");
  scal->add_option("scene", g_scal.scene, "Scene file (JSON)")->required();
  scal->add_option("--vertices", g_scal.vertices, "Comma-separated target vertex counts (every generated cloth)")->required();
  scal->add_option("--solver", g_scal.solver, "Solver, NAME or NAME@key=value@...")->required();
  scal->add_option("--out,-o", g_scal.out, "Output folder (created if missing)")->required();
  scal->add_option("--steps", g_scal.steps, "Measured steps per size")->default_val(3);
  scal->add_option("--warmup", g_scal.warmup, "Steps simulated before the measurement")->default_val(1);
  scal->add_option("--rel-grad", g_scal.rel_grad, "Stop each step at this relative gradient norm")->default_val(1e-2);
  scal->add_option("--threads,-j", g_scal.threads, "Worker threads (default: the scene's)");
  scal->add_option("--substeps", g_scal.substeps, "Steps per frame instead of the scene's (the step is frame time / N)");
  scal->add_flag("--quiet,-q", g_scal.quiet, "No progress log");

  auto* sh = bench->add_subcommand(
      "shells", "Iterations and wall time of shell solvers on the first step of shell scenes per level (Kopanicakova 2019, Table 3)");
  sh->add_option("scenes", g_shell.scenes, "Shell scene files (JSON)")->required();
  sh->add_option("--levels", g_shell.levels, "Comma-separated subdivision levels")->default_val("1,2,3,4");
  sh->add_option("--solvers", g_shell.solvers, "Comma-separated solvers, NAME or NAME@key=value@...")->default_val("tr-dogleg,tr-stcg");
  sh->add_option("--out,-o", g_shell.out, "Output folder (created if missing)")->required();
  sh->add_option("--time-step", g_shell.time_step, "Step size (default: the scenes' time_step)");
  sh->add_option("--max-iters", g_shell.max_iters, "Iteration cap per solve (default: the scenes' solver.max_iters)");
  sh->add_option("--max-seconds", g_shell.max_seconds, "Wall-time cap per solve, seconds");
  sh->add_option("--threads,-j", g_shell.threads, "Worker threads (default: all cores)");
  sh->add_flag("--quiet,-q", g_shell.quiet, "No progress log");
  sh->add_flag("--verbose,-v", g_shell.verbose, "Log solver details (every V-cycle and coarse correction)");
  sh->add_flag("--resume", g_shell.resume,
               "Go on from the iterates an earlier run left in OUT/states (solves stopped by a cap continue, "
               "converged ones are kept)");
  sh->add_option("--checkpoint-seconds", g_shell.checkpoint_seconds,
                 "Write each tr-*/rmtr solve's state to OUT/states at most this often (0: only at its end)")
      ->default_val(600.0);
  sh->add_option("--start-from", g_shell.start_from,
                 "A state file of a solve at a coarser level (OUT/states/*.state.json of an earlier run): finer solves "
                 "of its shell start from its solution, prolongated (repeat for other shells)");

  auto* ts = bench->add_subcommand(
      "timestep", "Largest time step at which each shell solver converges at every step (Kopanicakova 2019, Fig. 10)");
  ts->add_option("scenes", g_step.scenes, "Shell scene files (JSON)")->required();
  ts->add_option("--level", g_step.level, "Subdivision level of every shell (3: 1,083 dofs)")->default_val(3);
  ts->add_option("--solvers", g_step.solvers, "Comma-separated solvers, NAME or NAME@key=value@...")
      ->default_val("tr-dogleg,rmtr,newton-ls,newton-damped,linearized");
  ts->add_option("--out,-o", g_step.out, "Output folder (created if missing)")->required();
  ts->add_option("--max-dt", g_step.max_dt, "Largest time step tried, seconds")->default_val(1.0);
  ts->add_option("--min-dt", g_step.min_dt, "Smallest time step tried (dt is halved from --max-dt down to it), seconds")
      ->default_val(1.0 / 64.0);
  ts->add_option("--window", g_step.window,
                 "Simulated seconds per try (default: the scene's duration, at most 2 s)");
  ts->add_option("--max-iters", g_step.max_iters, "Iteration cap per solve (default: the scenes' solver.max_iters)");
  ts->add_option("--max-seconds", g_step.max_seconds, "Wall-time cap per solve, seconds (default: none)");
  ts->add_option("--max-try-seconds", g_step.max_try_seconds,
                 "Wall-time cap per (scene, solver, dt) try, checked between steps, seconds (default: none)");
  ts->add_option("--stall-rel-grad", g_step.stall_rel_grad,
                 "A solve stopped as stalled passes at |g| <= this times |g0| (or --stall-abs-grad)")
      ->default_val(1e-5);
  ts->add_option("--stall-abs-grad", g_step.stall_abs_grad,
                 "A solve stopped as stalled passes at |g| <= this (the paper's 'in practice |g| <= 5e-5')")
      ->default_val(0.0);
  ts->add_flag("--resume", g_step.resume, "Keep the tries of an interrupted run with the same options in --out");
  ts->add_option("--threads,-j", g_step.threads, "Worker threads (default: all cores)");
  ts->add_flag("--quiet,-q", g_step.quiet, "No progress log");
  ts->add_flag("--verbose,-v", g_step.verbose, "Log solver details");

  auto* pj = bench->add_subcommand(
      "projections", "Build time, memory and exactness of reverse subdivision vs least squares per level (Kopanicakova 2019, Table 8)");
  pj->add_option("scene", g_proj.scene, "Shell scene file (JSON); its first shell")->required();
  pj->add_option("--level", g_proj.level, "Subdivision level (default: the scene's)")->check(requires_number([](double l) { return l >= 1 && l <= 9; }, "a level in [1, 9]"));
  pj->add_option("--out,-o", g_proj.out, "Output folder (created if missing)")->required();
  pj->add_flag("--quiet,-q", g_proj.quiet, "No progress log");
}

int run_bench_command(CLI::App& bench) {
  if (bench.got_subcommand("convergence")) return run_convergence_command();
  if (bench.got_subcommand("scalability")) return run_scalability_command();
  if (bench.got_subcommand("shells")) return run_shells_command();
  if (bench.got_subcommand("timestep")) return run_timestep_command();
  if (bench.got_subcommand("projections")) return run_projections_command();
  return 1;
}

}  // namespace mgcloth::cli
