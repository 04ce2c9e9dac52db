#include <mgcloth/core/error.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/solvers/line_search.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace mgcloth::solvers {

void NonlinearSolver::restore_carried_state(std::string_view state) {
  if (!state.empty())
    throw_input_error("{} bytes of solver state, which solver \"{}\" does not keep", state.size(), name());
}

std::string encode_carried_state(std::string_view tag, const std::vector<double>& values) {
  std::string out(tag);
  out += '\0';
  out.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(double));
  return out;
}

std::vector<double> decode_carried_state(std::string_view tag, std::string_view state) {
  const std::size_t head = tag.size() + 1;
  if (state.size() < head || state.substr(0, tag.size()) != tag || state[tag.size()] != '\0' ||
      (state.size() - head) % sizeof(double) != 0)
    throw_input_error("a solver state of {} bytes that solver kind \"{}\" did not write", state.size(), tag);
  std::vector<double> values((state.size() - head) / sizeof(double));
  if (!values.empty()) std::memcpy(values.data(), state.data() + head, values.size() * sizeof(double));
  return values;
}

bool NonlinearSolver::can_minimize(physics::EnergyForm form) const {
  const auto forms = energy_forms();
  return std::find(forms.begin(), forms.end(), form) != forms.end();
}

void check_energy_form(const NonlinearSolver& solver, physics::EnergyForm form, const std::string& where) {
  if (solver.can_minimize(form)) return;
  const std::string own = physics::energy_form_name(solver.energy_forms().front());
  throw InputError(fmt::format("{}: solver \"{}\" cannot minimize the {} energy form, only the {} one: set "
                               "\"energy_form\": \"{}\" in the scene, or choose another solver", where, solver.name(),
                               physics::energy_form_name(form), own, own));
}

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

bool steepest_descent_fallback(const physics::Objective& objective, const linalg::BlockMatrix3* A, VecX& x, double& e,
                               VecX& g, double& grad_norm) {
  const VecX d = -g;
  const double gg = g.squaredNorm();
  if (!(gg > 0.0)) return false;
  double alpha = 0.0;
  if (A) {
    VecX Ad;
    A->multiply(d, Ad);
    const double dAd = d.dot(Ad);
    if (dAd > 0.0) alpha = gg / dAd;
  }
  if (!(alpha > 0.0)) {
    // Secant curvature along −g from a probe a millionth of the gradient's length scale.
    const double probe = 1e-6 / std::sqrt(gg);
    VecX gp;
    objective.gradient(x + probe * d, gp);
    const double curvature = (gp - g).dot(d) / probe;
    alpha = curvature > 0.0 ? gg / curvature : probe;
  }
  const auto energy = [&](const VecX& y) { return objective.value(y); };
  LineSearchParams ls;
  ls.max_steps = 60;
  ls.expand_ratio = 0.0;
  VecX trial;
  const auto r = backtracking(energy, x, e, d, -gg, alpha, ls, trial);
  if (!r.success || !(r.energy < e)) return false;
  x.swap(trial);
  e = r.energy;
  objective.gradient(x, g);
  grad_norm = g.norm();
  return std::isfinite(grad_norm);
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
