#include <mgcloth/core/error.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/solvers/newton.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth::solvers {

Newton::Newton(NewtonParams params) : m_params(std::move(params)) {
  if (!solvers::needs_hierarchy(m_params.linear.method))
    m_linear = make_newton_linear_solver(m_params.linear, {}, linalg::BlockMatrix3());
}


std::string Newton::carried_state() const {
  if (!m_linear) return {};
  const std::vector<double> v = m_linear->carried();
  if (std::all_of(v.begin(), v.end(), [](double r) { return r == 0.0; })) return {};  // as a fresh solver
  return encode_carried_state("newton", v);
}

void Newton::restore_carried_state(std::string_view state) {
  m_restore.clear();
  if (state.empty()) {
    m_linear.reset();
    return;
  }
  m_restore = decode_carried_state("newton", state);
}

SolveReport Newton::minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) {
  const physics::Objective& obj = *problem.objective;
  Timer timer;
  SolveReport rep;
  VecX g, d, trial;
  double e = obj.value_and_gradient(x, g);
  double gnorm = g.norm();
  check_finite(m_name, e, gnorm, 0);
  rep.initial_grad_norm = gnorm;
  if (trace) trace->push_back({0, e, gnorm, timer.ms(), 0.0});
  const double target = std::max(stop.abs_grad, stop.rel_grad * gnorm);
  const auto prolongations = problem.hierarchy.prolongations();
  if (!m_linear || (needs_hierarchy() && m_linear_for != prolongations)) {
    m_linear = make_newton_linear_solver(m_params.linear, prolongations, obj.hessian_pattern());
    m_linear_for = prolongations;
    m_have_constant = false;
  }
  if (!m_restore.empty()) {
    const std::vector<double> state = std::move(m_restore);
    m_restore.clear();
    m_linear->restore(state);
  }
  m_linear_iterations = 0;
  // Solves with the matrix just computed; false when it turned out not positive definite.
  const auto solve = [&](double rel_tol) {
    if (!m_linear->solve(-g, d, rel_tol)) return false;
    m_linear_iterations += m_linear->iterations();
    return true;
  };
  const auto energy = [&](const VecX& y) { return obj.value(y); };
  double shift = 0.0;
  bool try_exact = true;
  rep.status = "max_iters";
  int k = 0;
  StepTracker steps(stop);
  bool cut = false;  // the last step was cut short by the objective's max_step (contact)
  bool decrement_met = false;
  for (; k < stop.max_iters; ++k) {
    if (should_stop(gnorm, target, timer.seconds(), stop, rep)) break;
    if (steps.converged(x, cut) || decrement_met) {
      rep.status = "converged";
      break;
    }
    cut = false;
    const double forcing = m_params.linear.rel_tol > 0.0 ? m_params.linear.rel_tol
                                                          : std::min(0.01, gnorm / rep.initial_grad_norm);
    bool factored = false;
    if (m_params.constant_matrix) {
      // Projective Dynamics: the prefactored global matrix, refactored only when it changed.
      const bool changed = (k == 0 || !m_have_constant) &&
                           update_constant_matrix(obj, x, m_have_constant, false, m_hessian, m_scratch);
      if (changed && !m_linear->compute(m_hessian, 0.0))
        throw SolveError(fmt::format("{}: the global matrix is not positive definite", m_name));
      m_have_constant = true;
      if (!solve(forcing)) throw SolveError(fmt::format("{}: the global solve failed at iteration {}", m_name, k));
      factored = true;
    }
    if (!factored && m_params.project_psd && try_exact && gnorm < m_params.exact_hessian_below * rep.initial_grad_norm) {
      obj.hessian(x, m_hessian, false);
      factored = m_linear->compute(m_hessian, 0.0) && solve(forcing) && g.dot(d) < 0.0;
      // An indefinite exact Hessian means the iterate is not yet in a convex basin; retrying every iteration
      // would double the cost of each one, so the rest of this solve stays projected.
      try_exact = factored;
      if (factored) shift = 0.0;
    }
    if (!factored) {
      obj.hessian(x, m_hessian, m_params.project_psd);
      // Levenberg fallback for a Hessian that is singular or indefinite (unprojected, or pins-only constraints).
      double mean_diag = 0.0;
      for (Index i = 0; i < m_hessian.rows(); ++i) mean_diag += m_hessian.block(m_hessian.diagonal(i)).trace();
      mean_diag /= std::max<Index>(1, 3 * m_hessian.rows());
      shift = shift > 0.0 ? shift * 0.25 : 0.0;
      if (shift < 1e-10 * mean_diag) shift = 0.0;
      int tries = 0;
      while (!(m_linear->compute(m_hessian, shift) && solve(forcing))) {
        shift = shift > 0.0 ? 10.0 * shift : 1e-8 * mean_diag;
        if (++tries > 20) throw SolveError(fmt::format("Newton: Hessian could not be made positive definite at iteration {}", k));
      }
    }
    double slope = g.dot(d);
    if (estimates_decrement() && slope < 0.0) {
      rep.decrement = -slope;
      decrement_met = stop.decrement_tol > 0.0 && -slope <= stop.decrement_tol;
    }
    if (!m_params.use_line_search) {
      const double alpha = obj.max_step(x, d, 1.0);
      cut = alpha < 1.0;
      x += alpha * d;
      if (problem.project) problem.project(x);
      e = obj.value_and_gradient(x, g);
      gnorm = g.norm();
      check_finite(m_name, e, gnorm, k + 1);
      if (trace) trace->push_back({k + 1, e, gnorm, timer.ms(), 1.0});
      continue;
    }
    if (!(slope < 0.0)) {  // not a descent direction (numerical trouble): fall back to steepest descent
      d = -g;
      slope = -gnorm * gnorm;
    }
    // Once the predicted decrease is below the round-off of the energy itself, the Armijo test compares noise;
    // there, a full step is judged by the gradient norm instead.
    if (-slope < 1e-13 * std::max(1.0, std::abs(e))) {
      const double alpha = obj.max_step(x, d, 1.0);
      cut = alpha < 1.0;
      trial = x + alpha * d;
      VecX g_trial;
      obj.gradient(trial, g_trial);
      const double gn = g_trial.norm();
      if (!(gn < gnorm)) {
        rep.status = at_roundoff_floor(obj, x, gnorm) ? "stagnated" : "stalled";
        break;
      }
      x.swap(trial);
      g.swap(g_trial);
      gnorm = gn;
      e = obj.value(x);
      check_finite(m_name, e, gnorm, k + 1);
      if (trace) trace->push_back({k + 1, e, gnorm, timer.ms(), 1.0});
      continue;
    }
    const double limit = obj.limits_steps() ? obj.max_step(x, d, m_params.line_search.max_alpha) : kInf;
    const auto ls = backtracking(energy, x, e, d, slope, 1.0, m_params.line_search, trial, -0.5 * slope, limit);
    cut = limit < 1.0;
    if (!ls.success) {
      // Near a minimum the Armijo test can fail only because energy differences drop below round-off.
      double floor = 0.0;
      if (at_roundoff_floor(obj, x, gnorm, &floor)) {
        rep.status = "stagnated";
        break;
      }
      if (steepest_descent_fallback(obj, &m_hessian, x, e, g, gnorm)) {
        check_finite(m_name, e, gnorm, k + 1);
        if (trace) trace->push_back({k + 1, e, gnorm, timer.ms(), 0.0});
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
    const double decrease = e - ls.energy;
    e = ls.energy;
    obj.gradient(x, g);
    gnorm = g.norm();
    check_finite(m_name, e, gnorm, k + 1);
    if (trace) trace->push_back({k + 1, e, gnorm, timer.ms(), ls.alpha});
    logger().debug("newton {:3d}: E = {:.12e}  |g| = {:.3e}  alpha = {:.3g}  shift = {:.2e}  dE/model = {:.3f}", k + 1, e, gnorm, ls.alpha, shift, decrease / (-0.5 * slope * ls.alpha));
  }
  finish_report(rep, k, e, gnorm, target, timer.ms());
  steps.finish(x, rep, cut);
  return rep;
}

}  // namespace mgcloth::solvers
