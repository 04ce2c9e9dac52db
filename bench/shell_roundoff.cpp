// The limiting accuracy of a subdivision-shell time step at a given iterate (Kopaničáková 2019 §7.2): how much the
// gradient of the objective changes when every coordinate of x moves by at most one ulp. A solve cannot drive ‖g‖
// below that, since x itself is only known to an ulp; criterion (7.1)'s second clause stops there. Prints ‖g‖ and,
// per term, the gradient's norm at x and the norm of its change under random one-ulp perturbations (median and
// largest of --samples draws), so that a solve's final ‖g‖ can be read against the floor of its own problem.
//   mgcloth_bench_shell_roundoff SCENE STATE [--samples K] [--seed S] [--threads T]
// STATE is a `mgcloth bench shells` state file (states/*.state.json); its level sets the shell's level.
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/studies/shell_bench.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <CLI/CLI.hpp>

#include <cstdio>

using namespace mgcloth;

namespace {

int run(const std::string& scene_file, const std::string& state_file, int samples, unsigned seed) {
  const studies::ShellBenchState st = studies::read_shell_bench_state(state_file);
  if (st.level < 1 || st.level > 9)
    throw_input_error("{}: level {} is not a shell level (1 to 9)", state_file, st.level);
  sim::Scene scene = sim::load_scene(scene_file);
  size_t s = scene.shells.size();
  for (size_t k = 0; k < scene.shells.size(); ++k)
    if (scene.shells[k].name == st.shell) s = k;
  if (s == scene.shells.size())
    throw_input_error("{}: no shell named \"{}\" (from {})", scene_file, st.shell, state_file);
  for (auto& sh : scene.shells) sh.level = st.level;
  scene.cloths.clear();
  scene.frames = 1;
  scene.solve_jointly = false;  // the shell's own objective
  sim::Simulator sim(scene);
  VecX x0;
  const solvers::Problem problem = sim.prepare_problem(sim.group_of(s), x0);
  if (st.x.size() != x0.size())
    throw_input_error("{}: {} dofs, shell \"{}\" of {} at level {} has {}", state_file, st.x.size(), st.shell,
                      scene_file, st.level, x0.size());
  const auto rows = physics::gradient_roundoff(*problem.objective, st.x, samples, seed);
  std::printf("# %s, shell \"%s\", level %d, %td dofs: E = %.12e, |g| = %.3e\n", state_file.c_str(),
              st.shell.c_str(), st.level, st.x.size(), problem.objective->value(st.x), rows.back().grad_norm);
  std::printf("term,grad_norm,change_median,change_max\n");
  for (const auto& r : rows)
    std::printf("%s,%.3e,%.3e,%.3e\n", r.term.c_str(), r.grad_norm, r.change_median, r.change_max);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"mgcloth shell round-off floor: the gradient's change under one-ulp perturbations of a state"};
  std::string scene_file, state_file;
  int samples = 8, threads = 1;
  unsigned seed = 1;
  app.add_option("scene", scene_file, "shell scene (JSON)")->required();
  app.add_option("state", state_file, "state file of `mgcloth bench shells`")->required();
  app.add_option("--samples", samples, "random one-ulp perturbations")->check(CLI::Range(1, 1000));
  app.add_option("--seed", seed, "random seed");
  app.add_option("--threads", threads, "threads")->check(CLI::Range(1, 1024));
  CLI11_PARSE(app, argc, argv);
  set_num_threads(threads);
  try {
    return run(scene_file, state_file, samples, seed);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
