#include <mgcloth/core/error.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

#include <cmath>

namespace mgcloth::solvers {

void check_finite(const std::string& solver, double energy, double grad_norm, int iteration) {
  if (!std::isfinite(energy) || !std::isfinite(grad_norm))
    throw SolveError(fmt::format("{}: solver diverged: non-finite {} at iteration {}", solver,
                                 std::isfinite(energy) ? "gradient" : "energy", iteration));
}

bool should_stop(double grad_norm, double target, double seconds, const Stop& stop, SolveReport& report) {
  if (grad_norm <= target) report.status = "converged";
  else if (seconds > stop.max_seconds) report.status = "time_limit";
  else if (stop.interruptible && interrupted()) report.status = "interrupted";
  else return false;
  return true;
}

bool update_constant_matrix(const physics::Objective& objective, const VecX& x, bool have, bool project_psd,
                            linalg::BlockMatrix3& A, linalg::BlockMatrix3& scratch) {
  if (!have) {
    objective.hessian(x, A, project_psd);
    return true;
  }
  objective.hessian(x, scratch, project_psd);
  if (scratch.blocks() == A.blocks()) return false;
  std::swap(A, scratch);
  return true;
}

void finish_report(SolveReport& report, int iterations, double energy, double grad_norm, double target, double wall_ms) {
  if (report.status == "max_iters" && grad_norm <= target) report.status = "converged";
  report.iterations = iterations;
  // (7.1) is met by either clause: the gradient, or stagnation once the trust region acts as Newton's method.
  report.converged = report.status == "converged" || report.status == "stagnated";
  report.energy = energy;
  report.grad_norm = grad_norm;
  report.wall_ms = wall_ms;
}

}  // namespace mgcloth::solvers
