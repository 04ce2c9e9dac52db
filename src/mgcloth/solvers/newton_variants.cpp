#include <mgcloth/core/error.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/linalg/trust_region_qp.hpp>
#include <mgcloth/solvers/newton_variants.hpp>

#include <cmath>

namespace mgcloth::solvers {

namespace {
std::string default_name(ExactNewtonMode mode) {
  switch (mode) {
    case ExactNewtonMode::LineSearch: return "newton-ls";
    case ExactNewtonMode::Damped: return "newton-damped";
    case ExactNewtonMode::Linearized: return "linearized";
  }
  return "exact-newton";
}
}  // namespace

ExactNewton::ExactNewton(ExactNewtonParams params, std::string name)
    : m_params(std::move(params)), m_name(name.empty() ? default_name(m_params.mode) : std::move(name)) {}

void ExactNewton::direction(const physics::Objective& objective, const VecX& x, const VecX& g, VecX& p) {
  objective.hessian(x, m_hessian, /*project_psd=*/false);
  ++m_hessian_assemblies;
  linalg::ShiftedFactorization f;
  try {
    f = linalg::factorize_shifted(m_cholmod, m_hessian, 40, m_last_shift);
  } catch (const SolveError& e) {
    throw SolveError(fmt::format("{}: {}", m_name, e.what()));
  }
  m_factorizations += f.attempts;
  if (f.shift > 0.0) ++m_fallbacks;
  m_max_shift = std::max(m_max_shift, f.shift);
  m_last_shift = f.shift;
  m_cholmod.solve(-g, p);
  // With H + λI positive definite p is a descent direction in exact arithmetic; round-off in a nearly singular
  // system can still break that.
  if (!p.allFinite() || !(g.dot(p) < 0.0)) {
    p = -g;
    ++m_steepest;
  }
}

std::string ExactNewton::carried_state() const {
  return m_last_shift > 0.0 ? encode_carried_state("exact-newton", {m_last_shift}) : std::string();
}

void ExactNewton::restore_carried_state(std::string_view state) {
  m_last_shift = 0.0;
  if (state.empty()) return;
  const std::vector<double> v = decode_carried_state("exact-newton", state);
  if (v.size() != 1 || !(v[0] > 0.0 && std::isfinite(v[0])))
    throw_input_error("{}: a solver state that is not a positive shift", m_name);
  m_last_shift = v[0];
}

SolveReport ExactNewton::minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) {
  const physics::Objective& obj = *problem.objective;
  Timer timer;
  SolveReport rep;
  m_hessian_assemblies = m_factorizations = m_fallbacks = m_steepest = 0;
  m_max_shift = 0.0;
  int ls_evaluations = 0;
  VecX g, p, trial, g_trial;
  double e = obj.value_and_gradient(x, g);
  double gnorm = g.norm();
  check_finite(m_name, e, gnorm, 0);
  rep.initial_grad_norm = gnorm;
  if (trace) trace->push_back({0, e, gnorm, timer.ms(), 0.0});
  const double target = std::max(stop.abs_grad, stop.rel_grad * gnorm);
  const auto energy = [&](const VecX& y) {
    ++ls_evaluations;
    return obj.value(y);
  };
  // After an update of x: the feasibility projection, then energy and gradient at the new x, and its trace row.
  const auto advance = [&](int k, double step) {
    if (problem.project) problem.project(x);
    e = obj.value_and_gradient(x, g);
    gnorm = g.norm();
    check_finite(m_name, e, gnorm, k + 1);
    if (trace) trace->push_back({k + 1, e, gnorm, timer.ms(), step});
  };
  const bool linearized = m_params.mode == ExactNewtonMode::Linearized;
  const int max_iters = linearized ? 1 : stop.max_iters;
  rep.status = "max_iters";
  int k = 0;
  StepTracker steps(stop);
  bool cut = false;  // the last step was cut short by the objective's max_step (contact)
  bool decrement_met = false;
  for (; k < max_iters; ++k) {
    if (should_stop(gnorm, target, timer.seconds(), stop, rep)) break;
    if (steps.converged(x, cut) || decrement_met) {
      rep.status = "converged";
      break;
    }
    cut = false;
    direction(obj, x, g, p);
    if (const double slope = g.dot(p); slope < 0.0) {
      rep.decrement = -slope;
      decrement_met = stop.decrement_tol > 0.0 && -slope <= stop.decrement_tol;
    }
    if (m_params.mode != ExactNewtonMode::LineSearch) {
      const double full = linearized ? 1.0 : m_params.alpha;
      const double alpha = obj.max_step(x, p, full);
      cut = alpha < full;
      x += alpha * p;
      advance(k, alpha);
      continue;
    }
    const double slope = g.dot(p);
    // Once the predicted decrease is below the round-off of the energy itself, the Armijo test compares noise;
    // there a full step is judged by the gradient norm instead (as Newton does, but relative to |E| alone, which
    // for cloth energies of a few centijoules is where the noise is).
    if (-slope < 1e-13 * std::abs(e)) {
      const double alpha = obj.max_step(x, p, 1.0);
      cut = alpha < 1.0;
      trial = x + alpha * p;
      obj.gradient(trial, g_trial);
      if (!(g_trial.norm() < gnorm)) {
        rep.status = at_roundoff_floor(obj, x, gnorm) ? "stagnated" : "stalled";
        break;
      }
      x.swap(trial);
      advance(k, 1.0);
      continue;
    }
    const double limit = obj.limits_steps() ? obj.max_step(x, p, m_params.line_search.max_alpha) : kInf;
    const auto ls = backtracking(energy, x, e, p, slope, 1.0, m_params.line_search, trial, 0.0, limit);
    cut = limit < 1.0;
    if (!ls.success) {
      // Near a minimum the Armijo test can fail only because energy differences drop below round-off.
      double floor = 0.0;
      if (at_roundoff_floor(obj, x, gnorm, &floor)) {
        rep.status = "stagnated";
        break;
      }
      if (steepest_descent_fallback(obj, nullptr, x, e, g, gnorm)) {
        advance(k, 0.0);
        continue;
      }
      if (gnorm <= 1e-5 * rep.initial_grad_norm) {
        rep.status = "stalled";
        break;
      }
      throw SolveError(fmt::format("{}: line search failed at iteration {} (|g| = {:.3e}, relative {:.3e}, {:.0f}x the "
                                   "gradient's round-off floor); tried: the Newton step, a steepest-descent step",
                                   m_name, k, gnorm, gnorm / rep.initial_grad_norm, floor > 0 ? gnorm / floor : 0.0));
    }
    x.swap(trial);
    advance(k, ls.alpha);
    logger().debug("{} {:3d}: E = {:.12e}  |g| = {:.3e}  alpha = {:.3g}", m_name, k + 1, e, gnorm, ls.alpha);
  }
  finish_report(rep, k, e, gnorm, target, timer.ms());
  steps.finish(x, rep, cut);
  if (linearized && k == 1) {
    rep.status = gnorm <= target ? "converged" : "linearized";
    rep.converged = gnorm <= target;
  }
  rep.counters = {{"hessian_assemblies", m_hessian_assemblies},
                  {"factorizations", m_factorizations},
                  {"cholmod_fallbacks", m_fallbacks},
                  {"max_shift", m_max_shift},
                  {"steepest_descent_steps", m_steepest},
                  {"line_search_evaluations", ls_evaluations}};
  return rep;
}

}  // namespace mgcloth::solvers
