#include <mgcloth/core/error.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/solvers/cpu_backend.hpp>
#include <mgcloth/solvers/factory.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace mgcloth::solvers {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}

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

std::vector<std::string> step_limiting_solvers() {
  std::vector<std::string> out;
  for (const std::string& name : solver_names()) {
    SolverConfig c;
    c.name = name;
    try {
      if (make_solver(c, "", "")->supports_step_limits()) out.push_back(name);
    } catch (const std::exception&) {  // a solver this build or machine cannot make (no device) limits nothing
    }
  }
  return out;
}

void check_step_limits(const NonlinearSolver& solver, const physics::Objective& objective, const std::string& where) {
  if (solver.supports_step_limits() || !objective.limits_steps()) return;
  throw InputError(fmt::format("{}: solver \"{}\" does not keep its trial points intersection-free, which cloth "
                               "contact needs; choose one that does: {}", where, solver.name(),
                               fmt::join(step_limiting_solvers(), ", ")));
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

namespace {
/// The objective's vectors without a multigrid: what steepest_descent() needs.
class PlainVectors final : public CpuVectors {
 public:
  using CpuVectors::CpuVectors;
  bool update_matrix(Vec) override { return false; }
  double correction(Index, bool, int, Vec, Vec) override { throw_error("no multigrid in this solve"); }
  void newton_step(Vec, Vec, double) override { throw_error("no multigrid in this solve"); }
  std::vector<std::pair<std::string, double>> counters() const override { return {}; }
};
}  // namespace

bool steepest_descent_fallback(const physics::Objective& objective, const linalg::BlockMatrix3* A, VecX& x, double& e,
                               VecX& g, double& grad_norm) {
  PlainVectors v(objective, {}, A);
  v[FmgBackend::X].swap(x);
  v[FmgBackend::G] = g;
  const bool ok = steepest_descent(v, A != nullptr, e);
  x.swap(v[FmgBackend::X]);
  if (!ok) return false;
  objective.gradient(x, g);
  grad_norm = g.norm();
  return std::isfinite(grad_norm);
}

double max_vertex_distance(const VecX& a, const VecX& b) {
  double m = 0.0;
  for (Index i = 0; i + 2 < a.size(); i += 3) m = std::max(m, (a.segment<3>(i) - b.segment<3>(i)).squaredNorm());
  return std::sqrt(m);
}

double StepErrorEstimate::record(double step, bool cut) {
  if (!(step > 0.0)) return m_error;
  const double ratio = cut || m_previous_cut ? kNaN : step / m_previous;
  // Θ is the larger of the last two ratios: a first step that takes out what the iteration resolves at once (a
  // smoother's rough error, the start's stretched edges) is followed by a much smaller one whose ratio to it says
  // nothing about how slowly the rest goes (with one ratio every solver stopped after 2 iterations, gs-chebyshev
  // with 33x the tolerance left). Eq. 8.10: η = Θ/(1 − Θ); an iteration that does not contract (Θ ≥ 1) gives no bound.
  const double theta = std::isnan(ratio) || std::isnan(m_ratio) ? kNaN : std::max(ratio, m_ratio);
  m_error = theta < 1.0 ? theta / (1.0 - theta) * step : kInf;  // NaN compares false: no bound
  m_ratio = ratio;
  m_previous = step;
  m_previous_cut = cut;
  return m_error;
}

bool StepTracker::converged(const VecX& x, bool cut) {
  if (m_marked) m_estimate.record(max_vertex_distance(x, m_mark), cut);
  m_marked = !m_estimate.met();
  if (m_marked) m_mark = x;
  return !m_marked;
}

void StepTracker::finish(const VecX& x, SolveReport& report, bool cut) {
  if (m_marked) m_estimate.record(max_vertex_distance(x, m_mark), cut);
  m_marked = false;
  report.step_error = m_estimate.error();
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
