#include "commands.hpp"
#include "progress.hpp"

#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/mesh/inspect.hpp>
#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/sim/recorder.hpp>

#include <filesystem>

namespace mgcloth::cli {

namespace {
struct RunOptions {
  std::string scene;
  std::string out;
  int frames = -1;
  std::string solver;
  int threads = 0;
  int level = 0;
  bool resume = false;
  bool quiet = false;
  bool verbose = false;
  bool trace = false;
} g_run;

struct InfoOptions {
  std::string mesh;
  double material_scale = 1.0;
} g_info;

int run() {
  if (g_run.verbose) logger().set_level(spdlog::level::debug);
  sim::Scene scene = sim::load_scene(g_run.scene);
  if (g_run.frames >= 0) scene.frames = g_run.frames;
  if (!g_run.solver.empty()) {
    const auto names = solvers::solver_names();
    if (std::find(names.begin(), names.end(), g_run.solver) == names.end())
      throw InputError(fmt::format("--solver: unknown solver \"{}\" (available: {})", g_run.solver, fmt::join(names, ", ")));
    if (g_run.solver != scene.solver.name) scene.solver.params = Json::object();
    scene.solver.name = g_run.solver;
  }
  if (g_run.threads > 0) scene.threads = g_run.threads;
  if (g_run.level > 0) {
    if (scene.shells.empty()) throw InputError("--level: the scene has no shells");
    for (auto& sh : scene.shells) sh.level = g_run.level;
  }
  if (!g_run.out.empty()) scene.output.dir = g_run.out;
  const std::filesystem::path dir = scene.output.dir;

  Timer setup;
  sim::Simulator sim(std::move(scene));
  sim.set_record_trace(g_run.trace);
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
  cmd->add_option("--out,-o", g_run.out, "Output folder (default: the scene's output.dir)");
  cmd->add_option("--frames,-n", g_run.frames, "Number of frames (default: the scene's frames)")->check(CLI::NonNegativeNumber);
  cmd->add_option("--solver,-s", g_run.solver, "Solver name (overrides the scene's solver.name)");
  cmd->add_option("--threads,-j", g_run.threads, "Worker threads (default: all cores)")->check(CLI::PositiveNumber);
  cmd->add_option("--level", g_run.level, "Subdivision level of every shell, 1-9 (default: the scene's)")->check(CLI::Range(1, 9));
  cmd->add_flag("--resume", g_run.resume, "Continue an interrupted run in --out from its last complete frame");
  cmd->add_flag("--trace", g_run.trace, "Also write trace.csv: energy, gradient norm and wall time of every solver iteration");
  cmd->add_flag("--quiet,-q", g_run.quiet, "No progress output");
  cmd->add_flag("--verbose,-v", g_run.verbose, "Log solver details");
}

void add_info_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Print a mesh's size, boundaries, area and defects");
  cmd->add_option("mesh", g_info.mesh, "OBJ file")->required();
  cmd->add_option("--material-scale", g_info.material_scale, "Metres per UV unit")->check(CLI::PositiveNumber);
}

int dispatch(CLI::App& app) {
  if (app.got_subcommand("run")) return run();
  if (app.got_subcommand("info")) return info();
  if (app.got_subcommand("hierarchy")) return run_hierarchy_command();
  return 1;
}

}  // namespace mgcloth::cli
