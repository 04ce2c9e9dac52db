// The limiting accuracy of a subdivision-shell time step at a given iterate (Kopaničáková 2019 §7.2): how much the
// gradient of the objective changes when every coordinate of x moves by at most one ulp. A solve cannot drive ‖g‖
// below that, since x itself is only known to an ulp; criterion (7.1)'s second clause stops there. Prints ‖g‖ and,
// per term, the gradient's norm at x and the norm of its change under random one-ulp perturbations (median and
// largest of --samples draws), so that a solve's final ‖g‖ can be read against the floor of its own problem.
//   mgcloth_bench_shell_roundoff SCENE STATE [--samples K] [--seed S] [--threads T]
// STATE is a `mgcloth bench shells` state file (states/*.state.json); its level sets the shell's level.
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/json.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <CLI/CLI.hpp>

#include <cstdio>
#include <vector>

using namespace mgcloth;

namespace {

int run(const std::string& scene_file, const std::string& state_file, int samples, unsigned seed) {
  const Json st = load_json(state_file);
  if (!st.is_object() || !st.contains("x") || !st.contains("level") || !st.contains("shell"))
    throw_input_error("{}: not a shell bench state (needs \"x\", \"level\" and \"shell\")", state_file);
  if (!st.at("level").is_number_integer() || st.at("level").get<int>() < 1 || st.at("level").get<int>() > 9)
    throw_input_error("{}: \"level\" must be an integer from 1 to 9, as a scene's shell level", state_file);
  if (!st.at("shell").is_string() || !st.at("x").is_array())
    throw_input_error("{}: \"shell\" must be a string and \"x\" an array", state_file);
  sim::Scene scene = sim::load_scene(scene_file);
  const std::string shell = st.at("shell").get<std::string>();
  size_t s = scene.shells.size();
  for (size_t k = 0; k < scene.shells.size(); ++k)
    if (scene.shells[k].name == shell) s = k;
  if (s == scene.shells.size()) throw_input_error("{}: no shell named \"{}\" (from {})", scene_file, shell, state_file);
  for (auto& sh : scene.shells) sh.level = st.at("level").get<int>();
  scene.cloths.clear();
  scene.frames = 1;
  sim::Simulator sim(scene);
  VecX x0;
  const solvers::Problem problem = sim.prepare_shell_problem(s, x0);
  std::vector<double> values;
  try {
    values = st.at("x").get<std::vector<double>>();
  } catch (const Json::exception&) {
    throw_input_error("{}: \"x\" must be an array of numbers", state_file);
  }
  if (static_cast<Index>(values.size()) != x0.size())
    throw_input_error("{}: \"x\" has {} entries, shell \"{}\" at level {} has {} dofs", state_file, values.size(), shell,
                      st.at("level").get<int>(), x0.size());
  const VecX x = Eigen::Map<const VecX>(values.data(), static_cast<Index>(values.size()));
  if (!x.allFinite()) throw_input_error("{}: \"x\" has a non-finite entry", state_file);

  VecX g;
  problem.objective->gradient(x, g);
  std::printf("# %s, shell \"%s\", level %d, %td dofs: E = %.12e, |g| = %.3e\n", state_file.c_str(), shell.c_str(),
              st.at("level").get<int>(), x.size(), problem.objective->value(x), g.norm());
  std::printf("term,grad_norm,change_median,change_max\n");
  for (const auto& r : physics::gradient_roundoff(*problem.objective, x, samples, seed))
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
