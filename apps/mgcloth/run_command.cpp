#include "commands.hpp"
#include "progress.hpp"

#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/mesh/inspect.hpp>
#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/sim/recorder.hpp>
#include <mgcloth/sim/solver_fit.hpp>

#include <algorithm>
#include <filesystem>

namespace mgcloth::cli {

namespace {
struct RunOptions {
  std::string scene;
  std::string out;
  long long frames = 0;
  std::string solver;
  std::string energy_form;
  long long threads = 0;
  long long level = 0;
  bool resume = false;
  bool quiet = false;
  bool verbose = false;
  bool trace = false;
  bool check_accuracy = false;
  // Whether each override was given: 0 and "" are values to check, not "absent".
  CLI::Option* out_option = nullptr;
  CLI::Option* frames_option = nullptr;
  CLI::Option* solver_option = nullptr;
  CLI::Option* energy_form_option = nullptr;
  CLI::Option* threads_option = nullptr;
  CLI::Option* level_option = nullptr;
} g_run;

struct InfoOptions {
  std::string mesh;
  double material_scale = 1.0;
} g_info;

/// A command-line value that replaces one of the scene's, at a JSON path of the scene.
struct Override {
  std::string option;
  std::string value;  ///< as given, for messages
  std::string path;   ///< "frames", "shells[0].level"
  Json::json_pointer pointer;
  Json json;
};

/// The scene with the overrides written into its JSON before it is parsed, so that they pass the scene's own
/// checks and ranges (and scene.resolved.json is a scene that mgcloth reads back); an error about an overridden
/// field names the option instead of the file.
sim::Scene load_scene_with(const std::string& file, Json j, const std::vector<Override>& overrides) {
  const std::filesystem::path path(file);
  const std::filesystem::path base = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  try {
    for (const Override& o : overrides) j[o.pointer] = o.json;
  } catch (const Json::exception&) {
    return sim::parse_scene(j, file, base);  // the file has a non-object where an override goes: its error
  }
  try {
    return sim::parse_scene(j, file, base);
  } catch (const InputError& e) {
    const std::string what = e.what();
    for (const Override& o : overrides) {
      const std::string prefix = fmt::format("{}: {}: ", file, o.path);
      if (what.rfind(prefix, 0) == 0)
        throw InputError(fmt::format("{} {}: {}", o.option, o.value, what.substr(prefix.size())));
    }
    throw;
  }
}

sim::Scene scene_of_run() {
  const std::string& file = g_run.scene;
  if (!std::filesystem::exists(file)) throw InputError(fmt::format("{}: no such scene file", file));
  const Json j = load_json(file);
  std::vector<Override> overrides;
  const auto add = [&](const std::string& option, const std::string& path, const std::string& pointer, Json value) {
    const std::string text = value.is_string() ? value.get<std::string>() : value.dump();
    overrides.push_back({option, text, path, Json::json_pointer(pointer), std::move(value)});
  };
  if (g_run.frames_option->count()) add("--frames", "frames", "/frames", g_run.frames);
  if (g_run.threads_option->count()) add("--threads", "threads", "/threads", g_run.threads);
  if (g_run.out_option->count()) {
    if (g_run.out.empty()) throw InputError("--out: must not be empty (leave it out for the scene's output.dir)");
    add("--out", "output.dir", "/output/dir", g_run.out);
  }
  if (g_run.level_option->count()) {
    const Json* shells = j.contains("shells") && j["shells"].is_array() ? &j["shells"] : nullptr;
    if (!shells || shells->empty()) throw InputError("--level: the scene has no shells");
    for (size_t i = 0; i < shells->size(); ++i)
      add("--level", fmt::format("shells[{}].level", i), fmt::format("/shells/{}/level", i), g_run.level);
  }
  if (g_run.solver_option->count()) {
    const auto names = solvers::solver_names();
    if (std::find(names.begin(), names.end(), g_run.solver) == names.end())
      throw InputError(fmt::format("--solver: {} (available: {})",
                                   g_run.solver.empty() ? "must not be empty"
                                                        : fmt::format("unknown solver \"{}\"", g_run.solver),
                                   fmt::join(names, ", ")));
    // The scene's solver parameters belong to its own solver: another one starts from its defaults.
    const std::string before = load_scene_with(file, j, {}).solver.name;
    if (g_run.solver != before && j.contains("solver") && j["solver"].is_object() && j["solver"].contains("params"))
      add("--solver", "solver.params", "/solver/params", Json::object());
    add("--solver", "solver.name", "/solver/name", g_run.solver);
  }
  if (g_run.energy_form_option->count()) add("--energy-form", "energy_form", "/energy_form", g_run.energy_form);
  return load_scene_with(file, j, overrides);
}

int run() {
  if (g_run.verbose) logger().set_level(spdlog::level::debug);
  sim::Scene scene = scene_of_run();
  const std::filesystem::path dir = scene.output.dir;

  Timer setup;
  sim::Simulator sim(std::move(scene));
  sim::check_solver_fits(sim);  // before anything is written
  sim.set_record_trace(g_run.trace);
  sim.set_accuracy_check(g_run.check_accuracy);
  sim::Recorder rec(dir, sim, g_run.trace);
  if (g_run.resume) {
    rec.resume(sim);
  } else {
    rec.start(sim);
  }
  const int total = sim.scene().frames;
  Index vertices = 0, control_points = 0;
  for (const auto& c : sim.cloths()) vertices += c->mesh().num_vertices();
  for (const auto& sh : sim.shells()) control_points += sh->hierarchy().finest().num_vertices();
  Progress progress(total, sim.frame(), g_run.quiet);
  const std::string bodies =
      control_points > 0 ? fmt::format("{} cloth vertices, {} shell control points ({} dofs)", vertices, control_points, 3 * control_points)
                         : fmt::format("{} cloth vertices", vertices);
  progress.message(fmt::format("{}: {}, {} obstacles, solver {}, {} frames x {} steps of {:.4g} s -> {}{}",
                               sim.scene().file, bodies, sim.obstacles().size(), sim.scene().solver.name, total,
                               sim.scene().substeps, sim.scene().step_size(), dir.string(),
                               g_run.resume ? fmt::format(" (resuming after frame {})", sim.frame()) : ""));
  // The scene's solves are not interruptible: a signal ends the run after the frame in progress.
  install_interrupt_handler();
  while (sim.frame() < total) {
    if (interrupted()) {
      rec.finish(sim);  // the animation so far stays viewable; --resume extends it
      progress.finish();
      std::fprintf(stderr, "mgcloth: interrupted after frame %d; continue with --resume\n", sim.frame());
      return 130;
    }
    Timer frame_timer;
    const auto stats = sim.advance_frame();
    rec.record_frame(sim, stats);
    int iterations = 0;
    for (const auto& s : stats) iterations += s.report.iterations;
    progress.update(sim.frame(), frame_timer.seconds(), iterations, stats.back().report.energy);
  }
  rec.finish(sim);
  progress.finish();
  progress.message(fmt::format("done: frames 0-{} in {}", sim.frame(), dir.string()));
  return 0;
}

int info() {
  const auto m = mesh::read_obj(g_info.mesh, g_info.material_scale, /*check=*/false);
  const auto report = mesh::inspect(m);
  std::fputs(mesh::format_report(report, g_info.mesh).c_str(), stdout);
  return 0;
}
}  // namespace

void add_run_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("run", "Simulate a scene and write its animation");
  cmd->add_option("scene", g_run.scene, "Scene file (JSON; see docs/scene-format.md)")->required()->check(CLI::ExistingFile);
  // Ranges are the scene's (docs/scene-format.md): the values are checked as the scene's fields they replace.
  g_run.out_option = cmd->add_option("--out,-o", g_run.out, "Output folder (default: the scene's output.dir)");
  g_run.frames_option =
      cmd->add_option("--frames,-n", g_run.frames, "Number of frames, 0-10000000 (default: the scene's frames)");
  g_run.solver_option =
      cmd->add_option("--solver,-s", g_run.solver, "Solver name (overrides the scene's solver.name)");
  g_run.energy_form_option = cmd->add_option("--energy-form", g_run.energy_form,
                                             "elastic or projective (overrides the scene's energy_form)");
  g_run.threads_option = cmd->add_option("--threads,-j", g_run.threads,
                                         "Worker threads, 0-1024; 0: all cores (default: the scene's threads)");
  g_run.level_option =
      cmd->add_option("--level", g_run.level, "Subdivision level of every shell, 1-9 (default: the scene's)");
  cmd->add_flag("--resume", g_run.resume, "Continue an interrupted run in --out from its last complete frame");
  cmd->add_flag("--trace", g_run.trace, "Also write trace.csv: energy, gradient norm and wall time of every solver iteration");
  cmd->add_flag("--check-accuracy", g_run.check_accuracy,
                "Measure every step's error: Newton + CHOLMOD solves the step on from the result, and stats.csv's "
                "true_velocity_error and true_velocity_rms give the distance (m/s; costs a Newton solve per step)");
  cmd->add_flag("--quiet,-q", g_run.quiet, "No progress output");
  cmd->add_flag("--verbose,-v", g_run.verbose, "Log solver details");
}

void add_info_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Print a mesh's size, boundaries, area and defects");
  cmd->add_option("mesh", g_info.mesh, "OBJ file")->required();
  cmd->add_option("--material-scale", g_info.material_scale, "Metres per UV unit, 1e-9 to 1e9")
      ->check(requires_number([](double m) { return m >= 1e-9 && m <= 1e9; }, "in [1e-9, 1e9] (the scene's range)"));
}

int dispatch(CLI::App& app) {
  if (app.got_subcommand("run")) return run();
  if (app.got_subcommand("info")) return info();
  if (app.got_subcommand("hierarchy")) return run_hierarchy_command();
  return 1;
}

}  // namespace mgcloth::cli
