#include <mgcloth/core/error.hpp>
#include <mgcloth/core/backtracking.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/solvers/nonlinear_fmg.hpp>

#include <bit>
#include <cassert>
#include <cmath>

namespace mgcloth::solvers {

std::vector<std::string> matrix_update_names() { return {"direction", "cycle", "step", "constant"}; }

std::string to_string(MatrixUpdate u) { return matrix_update_names()[static_cast<size_t>(u)]; }

MatrixUpdate matrix_update_from_string(const std::string& s) {
  const auto names = matrix_update_names();
  for (size_t i = 0; i < names.size(); ++i)
    if (names[i] == s) return static_cast<MatrixUpdate>(i);
  throw InputError(fmt::format("unknown matrix update \"{}\" (available: {})", s, fmt::join(names, ", ")));
}

NonlinearFMG::NonlinearFMG(FmgParams params, std::string name) : m_params(std::move(params)), m_name(std::move(name)) {
  if (m_params.single_level) m_params.multigrid.factorize_coarsest = false;
  m_params.multigrid.adaptive_threshold = m_params.adaptive_threshold;
}

std::vector<NonlinearFMG::Stage> NonlinearFMG::schedule(Index L) const {
  const int pre = m_params.multigrid.pre_smooth, post = m_params.multigrid.post_smooth;
  if (m_params.single_level) return {{0, Move::Smooth, pre}};
  std::vector<Stage> out;
  // One V-cycle from every level, coarsest first (Fig. 2b with one V-cycle per level, §4.2.1).
  for (Index top = m_params.interleave ? L - 1 : 0; top >= 0; --top) {
    const Index linear_from = std::max<Index>(top, std::min<Index>(m_params.residual_levels, L - 1));
    for (Index h = top; h < linear_from; ++h) out.push_back({h, Move::Smooth, pre});
    out.push_back({linear_from, Move::Linear, 0});
    for (Index h = linear_from - 1; h >= top; --h) out.push_back({h, Move::Smooth, post});
  }
  return out;
}


namespace {
/// FNV-1a of a matrix's values, −0 counted as +0 (as the == that update_constant_matrix compares with does).
std::uint64_t constant_matrix_hash(const linalg::BlockMatrix3& A) {
  std::uint64_t h = 1469598103934665603ull;
  for (const Mat3& b : A.blocks())
    for (Index i = 0; i < 9; ++i) {
      const auto bits = std::bit_cast<std::uint64_t>(b.data()[i] + 0.0);
      for (int k = 0; k < 8; ++k) h = (h ^ ((bits >> (8 * k)) & 0xffu)) * 1099511628211ull;
    }
  return h;
}

constexpr std::string_view kStateTag = "fmg";
}  // namespace

// Layout: L, the L radii, the L line-search scales, 1 and the matrix hash's bits (a constant matrix) or 0 and 0.
std::string NonlinearFMG::carried_state() const {
  if (!m_mg) return {};  // no solve yet: a fresh solver
  std::vector<double> v{static_cast<double>(m_mg->num_levels())};
  for (double rho : m_mg->smoother_rhos()) v.push_back(rho);
  v.insert(v.end(), m_beta.begin(), m_beta.end());
  const bool constant = m_params.matrix_update == MatrixUpdate::Constant && m_have_matrix;
  v.push_back(constant ? 1.0 : 0.0);
  v.push_back(constant ? std::bit_cast<double>(constant_matrix_hash(m_A)) : 0.0);
  return encode_carried_state(kStateTag, v);
}

void NonlinearFMG::restore_carried_state(std::string_view state) {
  m_restore.clear();
  if (state.empty()) {
    m_mg.reset();  // as a fresh solver: the radii are estimated on the next matrix
    return;
  }
  std::vector<double> v = decode_carried_state(kStateTag, state);
  const bool fits = v.size() >= 3 && v[0] >= 1.0 && v[0] <= 64.0 && v[0] == std::floor(v[0]) &&
                    v.size() == 2 * static_cast<size_t>(v[0]) + 3;
  if (!fits) throw_input_error("{}: a solver state of {} values that does not describe a multigrid", m_name, v.size());
  for (size_t l = 0; l < static_cast<size_t>(v[0]); ++l) {
    const double beta = v[1 + static_cast<size_t>(v[0]) + l];
    if (!(beta > 0.0 && beta <= 1.0)) throw_input_error("{}: line-search scale {} is not in (0, 1]", m_name, beta);
  }
  m_restore = std::move(v);
}

SolveReport NonlinearFMG::minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) {
  const physics::Objective& obj = *problem.objective;
  Timer timer;
  m_stats = Stats{};
  const auto prolongations = problem.hierarchy.prolongations();
  if (!m_mg || m_mg_for != prolongations) {
    const auto& levels = m_params.single_level ? std::vector<const linalg::StencilTable*>{} : prolongations;
    m_mg = std::make_unique<LinearMultigrid>(levels, obj.hessian_pattern(), m_params.multigrid);
    m_mg_for = prolongations;
    m_have_matrix = false;
    m_beta.assign(static_cast<size_t>(m_mg->num_levels()), 1.0);
  }
  const Index L = m_mg->num_levels();
  if (!m_restore.empty()) {
    const std::vector<double> state = std::move(m_restore);
    m_restore.clear();
    if (state[0] != static_cast<double>(L))
      throw_input_error("{}: a solver state for {} levels, the cloth's hierarchy has {}", m_name, state[0], L);
    m_mg->set_smoother_rhos({state.begin() + 1, state.begin() + 1 + L});
    m_beta.assign(state.begin() + 1 + L, state.begin() + 1 + 2 * L);
    m_have_matrix = false;
    m_restored_matrix.reset();
    if (state[1 + 2 * L] != 0.0) m_restored_matrix = std::bit_cast<std::uint64_t>(state[2 + 2 * L]);
  }
  const std::vector<Stage> stages = schedule(L);
  m_mg->reset_adaptive_stats();

  SolveReport rep;
  VecX g, r, d, trial, x_prev;
  std::vector<VecX> rl(static_cast<size_t>(L)), cl(static_cast<size_t>(L));
  std::vector<char> mask;
  double e = obj.value(x);
  {
    Timer t;
    obj.gradient(x, g);
    m_stats.gradient_ms += t.ms();
  }
  r = -g;
  double gnorm = g.norm();
  check_finite(m_name, e, gnorm, 0);
  rep.initial_grad_norm = gnorm;
  if (trace) trace->push_back({0, e, gnorm, timer.ms(), 0.0});
  const double target = std::max(stop.abs_grad, stop.rel_grad * gnorm);

  VecX Ad, p, Ap, sv, As;  // A_0 d, the search direction and A_0 p, the previous step s and A_0 s
  bool have_s = false, as_stale = false, model_poor = false;
  const auto update_matrix = [&] {
    Timer t;
    bool changed = true;
    if (m_params.matrix_update == MatrixUpdate::Constant) {
      changed = update_constant_matrix(obj, x, m_have_matrix, m_params.project_psd, m_A, m_scratch);
      m_stats.assembly_ms += t.ms();
      const bool restored = m_restored_matrix.has_value();
      if (restored) {
        // The hierarchy must be built either way; whether the model is new is what the writer's matrix says.
        changed = constant_matrix_hash(m_A) != *m_restored_matrix;
        m_restored_matrix.reset();
      }
      logger().debug("{}: constant matrix {}{}", m_name, changed ? "changed" : "unchanged", restored ? " (restored)" : "");
      if (!changed && !restored) return;  // e.g. the same contact set: keep the hierarchy and its factors
    } else {
      obj.hessian(x, m_A, m_params.project_psd);
      m_stats.assembly_ms += t.ms();
    }
    if (changed) {
      as_stale = true;
      std::fill(m_beta.begin(), m_beta.end(), 1.0);  // a fresh model is trusted again
    }
    Timer tg;
    m_mg->set_matrix(m_A);
    m_stats.galerkin_ms += tg.ms();
    m_have_matrix = true;
    if (changed) ++m_stats.matrix_updates;
  };

  // Chebyshev weights across corrections (Wang 2015): ω_1 = 1, ω_2 = 2/(2 − ρ²), ω_{k+1} = 4/(4 − ρ² ω_k).
  const double rho = m_params.chebyshev_rho;
  long cheb_k = 0;
  double omega = 1.0;
  const auto next_omega = [&] {
    ++cheb_k;
    const long k = cheb_k - m_params.chebyshev_delay;
    omega = k <= 0 ? 1.0 : k == 1 ? 2.0 / (2.0 - rho * rho) : 4.0 / (4.0 - rho * rho * omega);
    return omega;
  };
  if (rho > 0.0) x_prev = x;

  const auto energy = [&](const VecX& y) {
    Timer t;
    ++m_stats.energy_evals;
    const double v = obj.value(y);
    m_stats.line_search_ms += t.ms();
    return v;
  };
  // After x changed: projection, then the new residual (and energy when needed).
  const auto refresh = [&](bool energy_known, double e_new) {
    Index moved = problem.project ? problem.project(x) : 0;
    e = (energy_known && moved == 0) ? e_new : (m_params.line_search || moved ? energy(x) : e);
    Timer t;
    obj.gradient(x, g);
    m_stats.gradient_ms += t.ms();
    r = -g;
    gnorm = g.norm();
  };

  // One search direction from level h; returns whether x moved.
  double last_alpha = 0.0;
  const auto direction = [&](const Stage& st) -> bool {
    ++m_stats.directions;
    Timer tt;
    const VecX* rh = &r;
    for (Index l = 0; l < st.level; ++l) {
      m_mg->restrict_to(l, *rh, rl[l + 1]);
      rh = &rl[l + 1];
    }
    m_stats.transfer_ms += tt.ms();
    VecX& c = cl[st.level];
    c.setZero(rh->size());
    Timer ts;
    if (st.move == Move::Smooth) {
      const std::vector<char>* m = nullptr;
      const Index n = m_mg->level_size(st.level);
      if (m_params.adaptive_threshold > 0.0) {
        const double rms = rh->norm() / std::sqrt(static_cast<double>(std::max<Index>(1, n)));
        const Index active = linalg::adaptive_mask(*rh, m_params.adaptive_threshold * rms, mask);
        m_stats.rows_skipped += static_cast<double>(n - active) * 2.0 * st.sweeps;
        m_stats.rows_relaxed += static_cast<double>(active) * 2.0 * st.sweeps;
        m = &mask;
      } else {
        m_stats.rows_relaxed += static_cast<double>(n) * 2.0 * st.sweeps;
      }
      m_mg->smooth(st.level, *rh, c, st.sweeps, m);
      m_stats.smoothing_ms += ts.ms();
    } else {
      m_mg->vcycle(st.level, *rh, c);
      m_stats.linear_ms += ts.ms();
    }
    // Theorem 4.1/4.2: the smoothing operator is SPD, so c·r > 0 unless the (masked) residual vanishes.
    const double cr = c.dot(*rh);
    assert(!(cr < 0.0));
    if (!(cr > 0.0)) {
      ++m_stats.rejected;
      return false;
    }
    Timer tp;
    const VecX* dh = &c;
    for (Index l = st.level - 1; l >= 0; --l) {
      m_mg->prolong(l, *dh, l == 0 ? d : rl[l]);
      dh = l == 0 ? &d : &rl[l];
    }
    if (st.level == 0) d = c;
    m_stats.transfer_ms += tp.ms();
    const double slope = -cr;  // ∇E · d = −r_0 · I c = −(Iᵀ r_0) · c
    // The quadratic model E + ∇E·d + ½ dᵀA_0 d gives the step length: exactly 1 for the coarse solve, near 1 for
    // smoothed corrections under a fresh matrix, smaller for coarse corrections under a stale one (§4.2.3).
    Timer tm;
    m_A.multiply(d, Ad);
    const double dAd = d.dot(Ad);
    const double model_alpha = dAd > 0.0 ? cr / dAd : 1.0;
    m_stats.model_ms += tm.ms();

    if (!m_params.line_search) {
      // Projective Dynamics (§4.4): the full correction, Chebyshev-weighted, no line search.
      if (rho > 0.0) {
        const double w = next_omega();
        trial = x + d;
        trial = w * (trial - x_prev) + x_prev;
        x_prev.swap(x);
        x.swap(trial);
      } else {
        x += d;
      }
      last_alpha = 1.0;
      refresh(false, 0.0);
      return true;
    }
    if (rho > 0.0) {
      const double w = next_omega();
      if (w != 1.0) {
        trial = x + model_alpha * d;
        trial = w * (trial - x_prev) + x_prev;
        const double et = energy(trial);
        if (std::isfinite(et) && et < e) {
          x_prev.swap(x);
          x.swap(trial);
          have_s = false;
          last_alpha = model_alpha;
          refresh(true, et);
          return true;
        }
        cheb_k = 0;  // the weighted step overshot: restart the weights
        omega = 1.0;
      }
    }
    // The search direction p, scaled so that α = 1 minimizes the model. With momentum, p minimizes the model over
    // span{d, s} for s the previous step (beyond the paper: conjugacy across directions, as in flexible PCG, which
    // removes the slow tail of bending-dominated modes that the linear coarse correction resolves poorly).
    double p_slope = model_alpha * slope;
    p = model_alpha * d;
    Ap = model_alpha * Ad;
    if (m_params.momentum && have_s) {
      Timer tmm;
      if (as_stale) {
        m_A.multiply(sv, As);
        as_stale = false;
      }
      const double sAs = sv.dot(As), dAs = d.dot(As), sr = sv.dot(r);
      const double det = dAd * sAs - dAs * dAs;
      if (dAd > 0.0 && sAs > 0.0 && det > 1e-10 * dAd * sAs) {
        const double a = (cr * sAs - sr * dAs) / det, b = (dAd * sr - dAs * cr) / det;
        p = a * d + b * sv;
        Ap = a * Ad + b * As;
        p_slope = -(a * cr + b * sr);  // < 0: the 2x2 model matrix is SPD
      }
      m_stats.model_ms += tmm.ms();
    }
    // Takes the model step when it reduces the gradient norm: where the predicted decrease is below the round-off
    // of the energy sum, the Armijo test compares noise (as in Newton), and the gradient is the reliable measure.
    const auto accept_by_gradient = [&]() -> bool {
      trial = x + p;
      VecX g_trial;
      obj.gradient(trial, g_trial);
      if (!(g_trial.norm() < gnorm)) return false;
      if (rho > 0.0) x_prev = x;
      sv = p;
      As = Ap;
      have_s = true;
      x.swap(trial);
      last_alpha = 1.0;
      refresh(false, 0.0);
      return true;
    };
    const bool in_round_off = -p_slope < 1e-13 * std::max(1.0, std::abs(e));
    if (in_round_off) {
      if (accept_by_gradient()) return true;
      ++m_stats.rejected;
      return false;
    }
    // Backtracking from the model step scaled by what this level needed last time (§4.2.3), with safeguarded
    // quadratic interpolation between trials.
    const auto& lp = m_params.line_search_params;
    double alpha = m_beta[st.level];
    double et = 0.0;
    bool ok = false;
    int tries = 0;
    for (; tries < lp.max_steps; ++tries) {
      trial = x + alpha * p;
      // Trial points are made feasible first (§4.5): a direction that would push a few vertices into an obstacle
      // is not cut short for all the others by the penalty's steep wall.
      if (problem.project) problem.project(trial);
      et = energy(trial);
      if (std::isfinite(et) && et <= e + lp.armijo * alpha * p_slope) {
        ok = true;
        break;
      }
      alpha = backtracking_step(alpha, et, e, p_slope, lp.shrink);
    }
    if (!ok) {
      m_beta[st.level] = std::max(1e-3, 0.5 * m_beta[st.level]);
      // Close to round-off the energy differences are noisy well above the model's own threshold.
      if (-p_slope < 1e-9 * std::max(1.0, std::abs(e)) && accept_by_gradient()) return true;
      ++m_stats.rejected;
      return false;
    }
    // A first-trial acceptance lets the next start probe twice as far (never beyond the model step).
    if (alpha < m_params.refresh_below) model_poor = true;
    m_beta[st.level] = std::min(1.0, tries == 0 ? 2.0 * alpha : alpha);
    if (rho > 0.0) x_prev = x;
    sv = alpha * p;
    As = alpha * Ap;
    have_s = true;
    x.swap(trial);
    last_alpha = alpha;
    refresh(true, et);
    return true;
  };

  rep.status = "max_iters";
  int k = 0;
  bool done = false, force_update = false;
  for (; k < stop.max_iters && !done; ++k) {
    if (should_stop(gnorm, target, timer.seconds(), stop, rep)) break;
    const bool per_solve = m_params.matrix_update == MatrixUpdate::Step || m_params.matrix_update == MatrixUpdate::Constant;
    if (!m_have_matrix || !per_solve || k == 0 || force_update) update_matrix();
    const bool fresh_matrix = !per_solve || k == 0 || force_update;
    force_update = false;
    int moved = 0;
    bool stale = false;
    for (const Stage& st : stages) {
      // The matrix is also refreshed within a cycle when the line search found the model far off (a large move,
      // e.g. the coarse correction bringing the cloth into contact, whose stiffness the old matrix lacks).
      const bool refreshable = m_params.matrix_update == MatrixUpdate::Direction || m_params.matrix_update == MatrixUpdate::Cycle;
      if (stale && refreshable && (m_params.matrix_update == MatrixUpdate::Direction || model_poor)) {
        update_matrix();
        ++m_stats.refreshes;
      }
      model_poor = false;
      stale = direction(st);
      if (stale) ++moved;
      check_finite(m_name, e, gnorm, k + 1);
      if (gnorm <= target) {
        rep.status = "converged";
        done = true;
        break;
      }
      const bool late = timer.seconds() > stop.max_seconds;
      if (late || (stop.interruptible && interrupted())) {
        rep.status = late ? "time_limit" : "interrupted";
        done = true;
        break;
      }
    }
    if (!m_params.line_search) e = obj.value(x);
    ++m_stats.cycles;
    if (trace) trace->push_back({k + 1, e, gnorm, timer.ms(), last_alpha});
    logger().debug("{} cycle {:3d}: E = {:.12e}  |g| = {:.3e}  directions {} rejected {}", m_name, k + 1, e, gnorm,
                   m_stats.directions, m_stats.rejected);
    if (moved == 0 && !done) {
      // No direction decreased the energy: a matrix too stale to help (retry with a fresh one), the limiting
      // accuracy (round-off), or a model that misleads every direction (fall back to steepest descent and go on).
      if (!fresh_matrix && m_params.line_search) {
        force_update = true;
        continue;
      }
      double floor = 0.0;
      if (at_roundoff_floor(obj, x, gnorm, &floor)) {
        rep.status = "stagnated";
        ++k;
        break;
      }
      if (m_params.line_search && steepest_descent_fallback(obj, &m_A, x, e, g, gnorm)) {
        if (problem.project && problem.project(x) > 0) refresh(false, 0.0);
        r = -g;
        have_s = false;
        std::fill(m_beta.begin(), m_beta.end(), 1.0);
        ++m_stats.fallbacks;
        force_update = true;
        check_finite(m_name, e, gnorm, k + 1);
        if (rho > 0.0) x_prev = x;
        continue;
      }
      // The Newton step of the model, solved by V-cycles to a residual of 1e-3. Where even its predicted decrease is
      // below the round-off of the energy sum, the energy cannot tell better from worse (the limiting accuracy of
      // a line search): the step is judged by the gradient norm, and if that fails too the solve has stagnated.
      {
        VecX c = VecX::Zero(x.size()), Ac;
        for (int it = 0; it < 30; ++it) {
          if (m_params.single_level) m_mg->smooth(0, r, c, 20);  // no coarse levels to cycle through
          else m_mg->vcycle(r, c);
          m_A.multiply(c, Ac);
          if ((r - Ac).norm() <= 1e-3 * gnorm) break;
        }
        const double predicted = 0.5 * c.dot(r);
        double magnitude = 0.0;
        for (const auto& [name, value] : obj.term_values(x)) magnitude += std::abs(value);
        const bool below_noise = !(predicted > 1e-13 * magnitude);
        trial = x + c;
        if (problem.project) problem.project(trial);
        const double et = energy(trial);
        VecX g_trial;
        obj.gradient(trial, g_trial);
        if (std::isfinite(et) && (et < e || (below_noise && g_trial.norm() < gnorm))) {
          x.swap(trial);
          e = et;
          g.swap(g_trial);
          gnorm = g.norm();
          r = -g;
          have_s = false;
          ++m_stats.fallbacks;
          force_update = true;
          check_finite(m_name, e, gnorm, k + 1);
          if (rho > 0.0) x_prev = x;
          continue;
        }
        if (below_noise) {
          rep.status = "stagnated";
          ++k;
          break;
        }
      }
      if (gnorm <= 1e-3 * rep.initial_grad_norm) {
        rep.status = "stalled";
        ++k;
        break;
      }
      throw SolveError(fmt::format("{}: no search direction decreased the energy in cycle {} (|g| = {:.3e}, relative "
                                   "{:.3e}, {:.0f}x the gradient's round-off floor); tried: a fresh Hessian, every "
                                   "level's correction, a steepest-descent step, the model's Newton step",
                                   m_name, k + 1, gnorm, gnorm / rep.initial_grad_norm, floor > 0 ? gnorm / floor : 0.0));
    }
  }
  finish_report(rep, k, e, gnorm, target, timer.ms());
  // Relaxations inside the linear V-cycles (counted only when the adaptive smoother is on).
  m_stats.rows_relaxed += m_mg->rows_active();
  m_stats.rows_skipped += m_mg->rows_total() - m_mg->rows_active();
  const double relaxations = m_stats.rows_relaxed + m_stats.rows_skipped;
  rep.counters = {{"directions", static_cast<double>(m_stats.directions)},
                  {"rejected_directions", static_cast<double>(m_stats.rejected)},
                  {"energy_evals", static_cast<double>(m_stats.energy_evals)},
                  {"matrix_updates", static_cast<double>(m_stats.matrix_updates)},
                  {"refreshes", static_cast<double>(m_stats.refreshes)},
                  {"fallbacks", static_cast<double>(m_stats.fallbacks)},
                  {"skipped_fraction", relaxations > 0.0 ? m_stats.rows_skipped / relaxations : 0.0},
                  {"assembly_ms", m_stats.assembly_ms},
                  {"galerkin_ms", m_stats.galerkin_ms},
                  {"smoothing_ms", m_stats.smoothing_ms},
                  {"linear_ms", m_stats.linear_ms},
                  {"transfer_ms", m_stats.transfer_ms},
                  {"line_search_ms", m_stats.line_search_ms},
                  {"gradient_ms", m_stats.gradient_ms},
                  {"model_ms", m_stats.model_ms}};
  return rep;
}

}  // namespace mgcloth::solvers
