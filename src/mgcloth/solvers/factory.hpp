#pragma once
#include <mgcloth/core/json.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

namespace mgcloth::solvers {

/// Solver settings as given in a scene's "solver" block (or on the command line); parsed strictly.
struct SolverConfig {
  std::string name = "fmg";
  /// A scene's stop rule where it sets none: the accuracy of the shipped scenes, which FMG reaches in a few cycles
  /// per step. The library's Stop (1e-6, 100 iterations) let fmg run into its iteration limit on a plain hanging
  /// cloth (bench/RESULTS.md, "Solver defaults").
  Stop stop = [] {
    Stop s;
    s.rel_grad = 1e-3;
    s.max_iters = 200;
    return s;
  }();
  Json params = Json::object();  ///< solver-specific parameters, validated when the solver is built
  /// Stop a step also once no vertex's velocity is estimated to be off by more than this (m/s; 0: off): the
  /// simulator sets Stop::step_tol = velocity_tol · h for each step of length h.
  double velocity_tol = 0.0;
  /// Stop a step also once the mass-weighted RMS of the velocity error, from the model's Newton decrement, is at most
  /// this (m/s; 0: off): the simulator sets Stop::decrement_tol = M·velocity_rms_tol² with M the step's cloth mass.
  double velocity_rms_tol = 0.0;
};

/// Names of the solvers this build provides.
std::vector<std::string> solver_names();
/// Builds a solver by name from its parameters; unknown names and keys are InputError naming `path` (the JSON path
/// of the params object, e.g. "solver.params").
std::unique_ptr<NonlinearSolver> make_solver(const SolverConfig& config, const std::string& file, const std::string& path);
/// The parameters with every default filled in, for the resolved scene.
Json resolved_params(const SolverConfig& config, const std::string& file, const std::string& path);

}  // namespace mgcloth::solvers
