#include <mgcloth/core/error.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/solvers/trust_region.hpp>

#include <cmath>

namespace mgcloth::solvers {

LevelModel::LevelModel(const physics::Objective& f, VecX delta_g, const VecX& x0)
    : m_f(&f), m_delta_g(std::move(delta_g)), m_offset(-m_delta_g.dot(x0)) {
  if (m_delta_g.size() != x0.size() || m_delta_g.size() != f.num_dofs())
    throw_error("LevelModel: δg has {} entries, x₀ {}, the objective {} dofs", m_delta_g.size(), x0.size(),
                f.num_dofs());
}

LevelModel::LevelModel(const physics::Objective& f, VecX delta_g, const VecX& x0, const linalg::BlockMatrix3* delta_h)
    : LevelModel(f, std::move(delta_g), x0) {
  m_delta_h = delta_h;
  if (m_delta_h) {
    if (3 * m_delta_h->rows() != x0.size())
      throw_error("LevelModel: δH has {} rows of blocks, x₀ {} entries", m_delta_h->rows(), x0.size());
    m_x0 = x0;
  }
}

double LevelModel::value(const VecX& x) const {
  double e = m_f->value(x);
  if (has_linear_term()) e += m_delta_g.dot(x) + m_offset;
  if (m_delta_h) {
    const VecX d = x - m_x0;
    e += 0.5 * d.dot(*m_delta_h * d);
  }
  return e;
}

void LevelModel::gradient(const VecX& x, VecX& g) const {
  m_f->gradient(x, g);
  if (has_linear_term()) g += m_delta_g;
  if (m_delta_h) g += *m_delta_h * VecX(x - m_x0);
}

void LevelModel::hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const {
  m_f->hessian(x, H, project_psd);
  if (!m_delta_h) return;
  if (!H.same_pattern(*m_delta_h)) throw_error("LevelModel: δH does not have the pattern of the objective's Hessian");
  for (Index k = 0; k < H.num_blocks(); ++k) H.block(k) += m_delta_h->block(k);
}

double radius_update(const TrustRegionParams& p, double rho, double radius, double step_norm) {
  // With the radius shift an interior step of an indefinite H is the exact step of the ball of its own norm, so a
  // rejection shrinks from that norm: from γ1·Δ alone a radius of 1e20 would return the same step tens of times.
  const bool from_step = p.shrink_from_step || p.radius_shift;
  if (rho < p.eta1) return p.gamma1 * (from_step ? std::min(radius, step_norm) : radius);
  if (rho > p.eta2) return std::min(p.gamma2 * radius, p.delta_max);
  return radius;
}

LocalTrustRegion::LocalTrustRegion(TrustRegionParams params, std::string name)
    : m_params(std::move(params)), m_name(std::move(name)) {}

void LocalTrustRegion::set_patches(std::vector<std::vector<Index>> patches) {
  m_patches = std::make_unique<linalg::PatchSmoother>(std::move(patches));
}

void LocalTrustRegion::reset() {
  m_counters = {};
  m_history.clear();
}

linalg::QpResult LocalTrustRegion::solve_qp(double radius, double initial_grad_norm, const linalg::NormMetric* metric) {
  ++m_counters.qp_calls;
  if (m_params.qp == TrQp::Dogleg) {
    const int before = m_dogleg.factorizations();  // the radius shift refactorizes
    auto r = m_dogleg.step(radius);
    m_counters.factorizations += m_dogleg.factorizations() - before;
    return r;
  }
  if (m_params.qp == TrQp::Exact) return m_exact.step(radius);
  if (m_params.qp == TrQp::GaussSeidel) return linalg::gauss_seidel_step(m_hessian, m_g, radius, m_params.gs_sweeps, *m_gs, metric);
  if (m_params.qp == TrQp::Schwarz) return linalg::patch_step(m_hessian, m_g, radius, m_params.gs_sweeps, *m_patches, metric);
  const double tol = m_params.stcg_rel_tol > 0.0
                         ? m_params.stcg_rel_tol
                         : std::min(0.5, std::sqrt(m_g.norm() / std::max(initial_grad_norm, 1e-300)));
  auto r = linalg::steihaug_cg(m_hessian, m_g, radius, m_params.stcg_max_iters, tol, metric);
  m_counters.cg_iterations += r.iterations;
  return r;
}

/// One run's state: the model, its control and clock, the current energy and gradient norm, and what the stopping
/// tests need to know of the last iteration.
struct LocalTrustRegion::Run {
  const LevelModel& h;
  const LocalTrControl& control;
  const Timer& clock;
  LocalTrResult res{};
  double f = 0.0, gnorm = 0.0;
  bool have_hessian = false;  ///< m_hessian (and the QP solver's preparation) is at the current x
  // |Δf|, ‖Δx‖ and Δ of the last iteration, for the second part of criterion (7.1), and whether it was a Newton step.
  double last_df = kInf, last_dx = kInf, last_radius = 0.0;
  bool last_newton = false;
  double last_checkpoint = 0.0;
};

/// How one trial point x + s was judged.
struct LocalTrustRegion::Verdict {
  bool stalled = false;              ///< no decrease left in floating point: the run ends
  double f_trial = 0.0;
  double next_radius = 0.0;
  bool have_trial_gradient = false;  ///< m_g_trial is ∇h(x + s)
  bool newton_step = false;
  bool limiting_accuracy = false;    ///< an accepted Newton step whose decrease is round-off: the run ends
};

void LocalTrustRegion::start(Run& r, const VecX& x) {
  const LocalTrControl& control = r.control;
  if (control.start_energy) {
    r.f = *control.start_energy;
  } else {
    r.f = r.h.value(x);
    ++m_counters.energy_evaluations;
  }
  if (control.start_gradient) {
    if (control.start_gradient != &m_g) m_g = *control.start_gradient;
  } else {
    r.h.gradient(x, m_g);
    ++m_counters.gradient_assemblies;
  }
  r.gnorm = m_g.norm();
  check_finite(m_name, r.f, r.gnorm, 0);
  r.res.initial_grad_norm = r.gnorm;
  r.res.initial_energy = r.f;
  r.res.grad_target = std::max(control.abs_grad, control.rel_grad * r.gnorm);
  if (control.trace) control.trace->push_back({0, r.f, r.gnorm, r.clock.ms(), 0.0});
  r.last_checkpoint = r.clock.seconds();
  r.res.status = "max_iters";
}

bool LocalTrustRegion::stops(Run& r, const VecX& x, double radius) const {
  const TrustRegionParams& p = m_params;
  if (r.gnorm <= r.res.grad_target) r.res.status = "converged";
  else if (r.clock.seconds() > r.control.max_seconds) r.res.status = "time_limit";
  else if (r.control.interruptible && interrupted()) r.res.status = "interrupted";
  else if ((r.last_radius > p.stagnation_delta || r.last_newton) &&
           (r.last_df < p.stagnation_tol || r.last_dx < p.stagnation_tol))
    r.res.status = "stagnated";
  // A radius below the round-off of x cannot move it: no decrease is possible in floating point.
  else if (!(radius > 1e-15 * x.lpNorm<Eigen::Infinity>()) || radius < std::numeric_limits<double>::min())
    r.res.status = "stalled";
  return r.res.status != "max_iters";
}

void LocalTrustRegion::prepare_model(Run& r, const VecX& x, int i) {
  const TrustRegionParams& p = m_params;
  const linalg::NormMetric* metric = r.control.metric;
  r.h.hessian(x, m_hessian, p.psd_hessian);
  ++m_counters.hessian_assemblies;
  m_model_exact = !p.psd_hessian;
  if (p.qp == TrQp::Dogleg) {
    const int before = m_dogleg.factorizations(), fallbacks = m_dogleg.fallbacks();
    try {
      m_dogleg.set_shift_bisections(p.shift_bisections);
      m_dogleg.set_radius_shift(p.radius_shift);
      if (!p.hybrid_hessian || p.psd_hessian) {
        m_dogleg.prepare(m_hessian, m_g, metric);
      } else if (!m_dogleg.prepare_definite(m_hessian, m_g, metric)) {
        // Indefinite: every element Hessian projected to positive semidefinite convexifies only where the
        // energy is concave, where H + λI damps every direction alike by λ.
        r.h.hessian(x, m_hessian, true);
        ++m_counters.hessian_assemblies;
        ++m_counters.projected_models;
        m_model_exact = false;
        m_dogleg.prepare(m_hessian, m_g, metric);
      }
    } catch (const SolveError& e) {
      throw SolveError(fmt::format("{}: iteration {}: {}", m_name, i, e.what()));
    }
    m_counters.factorizations += m_dogleg.factorizations() - before;
    m_counters.cholmod_fallbacks += m_dogleg.fallbacks() - fallbacks;
  }
  if (p.qp == TrQp::Exact) {
    try {
      m_exact.prepare(m_hessian, m_g, metric);
    } catch (const SolveError& e) {  // a failed decomposition; a level too large for it stays a usage Error
      throw SolveError(fmt::format("{}: iteration {}: {}", m_name, i, e.what()));
    }
  }
  if (p.qp == TrQp::Schwarz) {
    if (!m_patches) throw Error(fmt::format("{}: the Schwarz smoother has no patches", m_name));
    m_patches->set_matrix(m_hessian);
  }
  if (p.qp == TrQp::GaussSeidel) {
    if (!m_gs) m_gs = std::make_unique<linalg::MultiColorGaussSeidel>(m_hessian);
    try {
      m_gs->set_matrix(m_hessian);
    } catch (const SolveError& e) {
      throw SolveError(fmt::format("{}: iteration {}: {}", m_name, i, e.what()));
    }
  }
  r.have_hessian = true;
}

LocalTrustRegion::Verdict LocalTrustRegion::judge_trial(Run& r, const VecX& x, const linalg::QpResult& qp,
                                                       TrIteration& it, double radius) {
  const TrustRegionParams& p = m_params;
  Verdict v;
  m_trial = x + qp.s;
  v.f_trial = r.h.value(m_trial);
  ++m_counters.energy_evaluations;
  it.actual = r.f - v.f_trial;
  it.rho = std::isfinite(v.f_trial) ? it.actual / qp.model_decrease : -kInf;
  v.next_radius = radius;
  v.newton_step = qp.reason == linalg::QpStop::Converged && m_model_exact &&
                  ((p.qp == TrQp::Dogleg && m_dogleg.shift() == 0.0) || p.qp == TrQp::Exact);
  if (std::isfinite(v.f_trial) && qp.model_decrease < p.roundoff_tol * std::abs(r.f)) {
    // The energy difference is round-off, so ρ is noise: the step is judged by the gradient norm, and Δ kept.
    // Where even the gradient no longer decreases, the limiting accuracy is reached. A Newton step is taken and
    // ends the solve as "stagnated", the limiting accuracy of (7.1)'s second clause: its predicted decrease is
    // the Newton decrement ½gᵀH⁻¹g of a positive definite H, so no more than round-off of the energy is left
    // to gain (a scale-free form of |Δf| < 1e-12, which the coarse levels' energies of 1e6 J never meet).
    r.h.gradient(m_trial, m_g_trial);
    ++m_counters.gradient_assemblies;
    v.have_trial_gradient = true;
    if (!(m_g_trial.norm() < r.gnorm) && !v.newton_step) {
      v.stalled = true;
      return v;
    }
    it.accepted = true;
    v.limiting_accuracy = v.newton_step;
  } else {
    // A non-finite trial energy (an exploded or inverted state) has ρ = −∞: rejected, the radius shrinks.
    it.accepted = it.rho > p.eta1;  // Alg. 4.1, line 4
    v.next_radius = radius_update(p, it.rho, radius, it.step_norm);
  }
  return v;
}

void LocalTrustRegion::extrapolate(Run& r, VecX& x, const VecX& s, TrIteration& it) {
  double scale = 1.0;
  for (int j = 0; j < m_params.extrapolate; ++j) {
    m_trial = x + scale * s;  // doubles the total step
    const double fe = r.h.value(m_trial);
    ++m_counters.energy_evaluations;
    if (!(std::isfinite(fe) && fe < r.f)) break;
    x.swap(m_trial);
    it.actual += r.f - fe;
    r.f = fe;
    scale *= 2.0;
    ++m_counters.extrapolations;
  }
  it.step_norm *= scale;
}

void LocalTrustRegion::accept(Run& r, VecX& x, const linalg::QpResult& qp, TrIteration& it, const Verdict& v, int i) {
  const LocalTrControl& control = r.control;
  ++m_counters.accepted;
  x.swap(m_trial);
  r.f = v.f_trial;
  if (m_params.extrapolate > 0 && it.rho > 1.0 && !v.have_trial_gradient) extrapolate(r, x, qp.s, it);
  const bool moved = control.project && control.project(x) > 0;
  if (moved) {
    r.f = r.h.value(x);
    ++m_counters.energy_evaluations;
  }
  if (v.have_trial_gradient && !moved) {
    m_g.swap(m_g_trial);
  } else {
    r.h.gradient(x, m_g);
    ++m_counters.gradient_assemblies;
  }
  r.gnorm = m_g.norm();
  check_finite(m_name, r.f, r.gnorm, i + 1);
  r.have_hessian = false;
  if (control.checkpoint && r.clock.seconds() - r.last_checkpoint >= control.checkpoint_seconds) {
    control.checkpoint(x, i + 1, r.f, r.gnorm);
    r.last_checkpoint = r.clock.seconds();
  }
  r.last_df = std::abs(it.actual);
  r.last_dx = it.step_norm;
  it.newton = v.newton_step;
  r.last_newton = it.newton;
}

void LocalTrustRegion::reject(Run& r) {
  // (7.1)'s second clause guards against meandering by tiny accepted steps; a rejected step leaves x as it was
  // but says nothing about convergence (far from a minimum it is a step into an infeasible or badly modelled
  // region), so it does not trigger the clause.
  ++m_counters.rejected;
  r.last_df = r.last_dx = kInf;
  r.last_newton = false;
}

LocalTrResult LocalTrustRegion::run(const LevelModel& h, VecX& x, double& radius, const LocalTrControl& control) {
  Timer own_clock;
  Run r{.h = h, .control = control, .clock = control.timer ? *control.timer : own_clock};
  start(r, x);
  int i = 0;
  StepTracker steps(control.step_tol);
  bool cut = false;  // the last accepted step lay on the trust region's boundary
  for (; i < control.max_iters; ++i) {
    if (stops(r, x, radius)) break;
    if (steps.converged(x, cut)) {
      r.res.status = "converged";
      break;
    }
    if (!r.have_hessian) prepare_model(r, x, i);
    const auto qp = solve_qp(radius, r.res.initial_grad_norm, control.metric);
    TrIteration it;
    it.radius = radius;
    it.predicted = qp.model_decrease;
    it.step_norm = control.metric ? control.metric->norm(qp.s) : qp.s.norm();
    it.qp = qp.reason;
    it.cg_iterations = qp.iterations;
    if (!std::isfinite(qp.model_decrease))
      throw SolveError(fmt::format("{}: non-finite model decrease at iteration {} (Hessian not finite?)", m_name, i));
    // SDC makes the predicted decrease positive whenever g ≠ 0; a non-positive one is all round-off.
    if (!(qp.model_decrease > 0.0)) {
      r.res.status = "stalled";
      break;
    }
    const Verdict v = judge_trial(r, x, qp, it, radius);
    if (v.stalled) {
      r.res.status = "stalled";
      break;
    }
    if (it.accepted) {
      accept(r, x, qp, it, v, i);
      cut = !(it.step_norm < (1.0 - 1e-9) * radius);
    } else {
      reject(r);
    }
    const double next = control.radius_cap ? control.radius_cap(x, v.next_radius) : v.next_radius;
    r.last_radius = radius;
    it.next_radius = next;
    m_history.push_back(it);
    if (control.trace) control.trace->push_back({i + 1, r.f, r.gnorm, r.clock.ms(), it.accepted ? it.step_norm : 0.0});
    logger().debug("tr {:4d}: {} rho = {:+.3e}  E = {:.12e}  |g| = {:.3e}  radius {:.3e} -> {:.3e}  |s| = {:.3e} ({}){}",
                   i + 1, it.accepted ? "accept" : "reject", it.rho, r.f, r.gnorm, radius, next, it.step_norm,
                   linalg::to_string(qp.reason),
                   m_params.qp == TrQp::Dogleg && m_dogleg.shift() > 0.0 ? fmt::format("  shift {:.2e}", m_dogleg.shift())
                                                                        : "");
    radius = next;
    if (v.limiting_accuracy) {
      ++i;
      r.res.status = "stagnated";
      break;
    }
    if (!(radius > 0.0)) {
      ++i;
      r.res.status = "radius_exhausted";
      break;
    }
  }
  SolveReport tracked;
  steps.finish(x, tracked, cut);
  r.res.step_error = tracked.step_error;
  r.res.iterations = i;
  r.res.energy = r.f;
  r.res.grad_norm = r.gnorm;
  return r.res;
}

TrustRegion::TrustRegion(TrustRegionParams params, std::string name)
    : m_name(!name.empty() ? std::move(name) : params.qp == TrQp::Dogleg ? "tr-dogleg" : "tr-stcg"),
      m_core(std::move(params), m_name) {}

namespace {
/// A shift restored from a checkpoint: finite and not negative.
double restored_shift(double shift, const std::string& solver) {
  if (!(shift >= 0.0 && std::isfinite(shift))) throw_input_error("{}: a solver state with the shift {}", solver, shift);
  return shift;
}
}  // namespace

std::string TrustRegion::carried_state() const {
  return m_core.dogleg_shift() > 0.0 ? encode_carried_state("tr", {m_core.dogleg_shift()}) : std::string();
}

void TrustRegion::restore_carried_state(std::string_view state) {
  if (state.empty()) {
    m_core.set_dogleg_shift(0.0);
    return;
  }
  const std::vector<double> v = decode_carried_state("tr", state);
  if (v.size() != 1) throw_input_error("{}: a solver state of {} values, not one shift", m_name, v.size());
  m_core.set_dogleg_shift(restored_shift(v[0], m_name));
}

SolveReport TrustRegion::minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) {
  Timer timer;
  m_core.reset();
  LocalTrControl control;
  control.max_iters = stop.max_iters;
  control.rel_grad = stop.rel_grad;
  control.abs_grad = stop.abs_grad;
  control.step_tol = stop.step_tol;
  control.max_seconds = stop.max_seconds;
  control.interruptible = stop.interruptible;
  control.checkpoint = stop.checkpoint;
  control.checkpoint_seconds = stop.checkpoint_seconds;
  control.timer = &timer;
  control.trace = trace;
  control.project = problem.project;
  double radius = m_core.params().delta0;
  const LocalTrResult r = m_core.run(LevelModel(*problem.objective), x, radius, control);
  SolveReport rep;
  rep.status = r.status;
  rep.initial_grad_norm = r.initial_grad_norm;
  finish_report(rep, r.iterations, r.energy, r.grad_norm, r.grad_target, timer.ms());
  rep.step_error = r.step_error;
  const TrCounters& c = m_core.counters();
  rep.counters = {{"accepted", c.accepted},
                  {"rejected", c.rejected},
                  {"hessian_assemblies", c.hessian_assemblies},
                  {"gradient_assemblies", c.gradient_assemblies},
                  {"energy_evaluations", c.energy_evaluations},
                  {"qp_calls", c.qp_calls},
                  {"cg_iterations", static_cast<double>(c.cg_iterations)},
                  {"factorizations", c.factorizations},
                  {"cholmod_fallbacks", c.cholmod_fallbacks},
                  {"projected_models", c.projected_models},
                  {"extrapolations", c.extrapolations},
                  {"final_radius", radius}};
  return rep;
}

}  // namespace mgcloth::solvers
