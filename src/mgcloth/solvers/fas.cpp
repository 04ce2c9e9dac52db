#include <mgcloth/core/error.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/solvers/fas.hpp>

#include <cmath>

namespace mgcloth::solvers {

double Fas::shifted_value(Index l, const VecX& x, const VecX& tau) const {
  const double e = m_levels[l].objective->value(x);
  return tau.size() ? e - tau.dot(x) : e;
}

void Fas::shifted_gradient(Index l, const VecX& x, const VecX& tau, VecX& g) const {
  m_levels[l].objective->gradient(x, g);
  if (tau.size()) g -= tau;
}

bool Fas::smooth(Index l, VecX& x, const VecX& tau, bool direct) {
  Level& level = m_levels[l];
  VecX g, d, trial;
  shifted_gradient(l, x, tau, g);
  level.objective->hessian(x, level.H, m_params.project_psd);
  if (direct) {
    double shift = 0.0, mean_diag = 0.0;
    for (Index i = 0; i < level.H.rows(); ++i) mean_diag += level.H.block(level.H.diagonal(i)).trace();
    mean_diag /= std::max<Index>(1, 3 * level.H.rows());
    for (int tries = 0; !m_coarse.factorize(level.H, shift); ++tries) {
      if (tries > 20) throw SolveError("fas: the coarsest Hessian could not be made positive definite");
      shift = shift > 0.0 ? 10.0 * shift : 1e-8 * mean_diag;
    }
    m_coarse.solve(-g, d);
  } else {
    level.gs.set_matrix(level.H);
    d = VecX::Zero(x.size());
    level.gs.symmetric_sweeps(-g, d, m_params.sweeps);
  }
  const double slope = g.dot(d);
  if (!(slope < 0.0)) return false;
  const double e0 = shifted_value(l, x, tau);
  const auto ls = backtracking([&](const VecX& y) { return shifted_value(l, y, tau); }, x, e0, d, slope, 1.0,
                               m_params.line_search, trial);
  if (!ls.success) return false;
  x.swap(trial);
  if (l == 0 && m_problem->project) m_problem->project(x);
  return true;
}

void Fas::cycle(Index l, VecX& x, const VecX& tau) {
  const Index last = static_cast<Index>(m_levels.size()) - 1;
  if (l == last) {
    for (int k = 0; k < m_params.coarse_iters; ++k)
      if (!smooth(l, x, tau, true)) break;
    return;
  }
  for (int k = 0; k < m_params.pre_smooth; ++k) smooth(l, x, tau, false);
  // Coarse problem: E_c(y) − τ_cᵀ y with τ_c = ∇E_c(x̂) − Pᵀ(∇E_l(x) − τ_l), x̂ the projected iterate (the
  // injected one for nested vertex sets).
  VecX xc0;
  m_problem->hierarchy.levels[static_cast<size_t>(l)].project(x, xc0);
  VecX g, rg, tau_c;
  shifted_gradient(l, x, tau, g);
  m_p[l]->apply_transpose(g, rg);
  m_levels[l + 1].objective->gradient(xc0, tau_c);
  tau_c -= rg;
  VecX xc = xc0;
  cycle(l + 1, xc, tau_c);
  // The coarse correction, line-searched on this level's objective.
  VecX d, trial;
  m_p[l]->apply(xc - xc0, d);
  const double slope = g.dot(d);
  if (slope < 0.0) {
    const double e0 = shifted_value(l, x, tau);
    const auto ls = backtracking([&](const VecX& y) { return shifted_value(l, y, tau); }, x, e0, d, slope, 1.0,
                                 m_params.line_search, trial);
    if (ls.success) {
      x.swap(trial);
      if (l == 0 && m_problem->project) m_problem->project(x);
    }
  }
  for (int k = 0; k < m_params.post_smooth; ++k) smooth(l, x, tau, false);
}

SolveReport Fas::minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) {
  const hierarchy::Hierarchy& H = problem.hierarchy;
  if (H.num_levels() < 2 || !H.has_objectives() || !H.has_projections())
    throw Error("fas: the problem has no coarse objectives and projections of iterates (the simulation must "
                "rediscretize the step on every level of the hierarchy)");
  Timer timer;
  m_problem = &problem;
  std::vector<const physics::Objective*> objectives{problem.objective};
  for (size_t l = 1; l < H.num_levels(); ++l) objectives.push_back(H.levels[l].objective);
  bool rebuild = objectives.size() != m_levels.size();
  for (size_t l = 0; !rebuild && l < objectives.size(); ++l) rebuild = m_levels[l].objective != objectives[l];
  if (rebuild) {
    m_levels.assign(objectives.size(), Level{});
    for (size_t l = 0; l < objectives.size(); ++l) {
      m_levels[l].objective = objectives[l];
      if (l + 1 < objectives.size()) m_levels[l].gs = linalg::MultiColorGaussSeidel(objectives[l]->hessian_pattern());
    }
  }
  m_p = H.prolongations();

  const physics::Objective& obj = *problem.objective;
  SolveReport rep;
  VecX g;
  double e = obj.value_and_gradient(x, g);
  double gnorm = g.norm();
  check_finite("fas", e, gnorm, 0);
  rep.initial_grad_norm = gnorm;
  if (trace) trace->push_back({0, e, gnorm, timer.ms(), 0.0});
  const double target = std::max(stop.abs_grad, stop.rel_grad * gnorm);
  rep.status = "max_iters";
  int k = 0;
  const VecX none;
  StepTracker steps(stop);
  for (; k < stop.max_iters; ++k) {
    if (should_stop(gnorm, target, timer.seconds(), stop, rep)) break;
    if (steps.converged(x)) {
      rep.status = "converged";
      break;
    }
    const double e_before = e;
    cycle(0, x, none);
    e = obj.value_and_gradient(x, g);
    gnorm = g.norm();
    check_finite("fas", e, gnorm, k + 1);
    if (trace) trace->push_back({k + 1, e, gnorm, timer.ms(), 1.0});
    logger().debug("fas cycle {:3d}: E = {:.12e}  |g| = {:.3e}", k + 1, e, gnorm);
    if (!(e < e_before) && gnorm > target) {
      double floor = 0.0;
      if (at_roundoff_floor(obj, x, gnorm, &floor)) {
        rep.status = "stagnated";
        ++k;
        break;
      }
      if (steepest_descent_fallback(obj, nullptr, x, e, g, gnorm)) continue;
      if (gnorm <= 1e-5 * rep.initial_grad_norm) {
        rep.status = "stalled";
        ++k;
        break;
      }
      throw SolveError(fmt::format("fas: a V-cycle did not decrease the energy in cycle {} (|g| = {:.3e}, {:.0f}x the "
                                   "gradient's round-off floor); tried: the V-cycle, a steepest-descent step",
                                   k + 1, gnorm, floor > 0 ? gnorm / floor : 0.0));
    }
  }
  finish_report(rep, k, e, gnorm, target, timer.ms());
  steps.finish(x, rep);
  return rep;
}

}  // namespace mgcloth::solvers
