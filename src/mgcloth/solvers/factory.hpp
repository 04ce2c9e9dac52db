#pragma once
#include <mgcloth/core/json.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

namespace mgcloth::solvers {

/// Solver settings as given in a scene's "solver" block (or on the command line); parsed strictly.
struct SolverConfig {
  std::string name = "fmg";
  Stop stop;
  Json params = Json::object();  ///< solver-specific parameters, validated when the solver is built
};

/// Names of the solvers this build provides.
std::vector<std::string> solver_names();
/// Builds a solver by name from its parameters; unknown names and keys are InputError naming `path` (the JSON path
/// of the params object, e.g. "solver.params").
std::unique_ptr<NonlinearSolver> make_solver(const SolverConfig& config, const std::string& file, const std::string& path);
/// The parameters with every default filled in, for the resolved scene.
Json resolved_params(const SolverConfig& config, const std::string& file, const std::string& path);

}  // namespace mgcloth::solvers
