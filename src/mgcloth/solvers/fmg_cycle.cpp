#include <mgcloth/core/error.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/solvers/fmg_cycle.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

namespace mgcloth::solvers {

std::vector<std::string> matrix_update_names() { return {"direction", "cycle", "step", "constant"}; }

std::string to_string(MatrixUpdate u) { return matrix_update_names()[static_cast<size_t>(u)]; }

MatrixUpdate matrix_update_from_string(const std::string& s) {
  const auto names = matrix_update_names();
  for (size_t i = 0; i < names.size(); ++i)
    if (names[i] == s) return static_cast<MatrixUpdate>(i);
  throw InputError(fmt::format("unknown matrix update \"{}\" (available: {})", s, fmt::join(names, ", ")));
}

bool steepest_descent(FmgBackend& b, bool use_model, double& e, long* energy_evals) {
  using V = FmgBackend;
  b.scale(V::R, -1.0, V::G);
  const double gg = b.dot(V::G, V::G);
  if (!(gg > 0.0)) return false;
  double alpha = 0.0;
  if (use_model) {
    b.multiply(V::R, V::Ad);
    const double dAd = b.dot(V::R, V::Ad);
    if (dAd > 0.0) alpha = gg / dAd;
  }
  if (!(alpha > 0.0)) {
    // Secant curvature along −g from a probe a millionth of the gradient's length scale.
    const double probe = b.limits_steps() ? b.max_step(V::X, V::R, 1e-6 / std::sqrt(gg)) : 1e-6 / std::sqrt(gg);
    if (!(probe > 0.0)) return false;
    b.combine(V::Trial, 1.0, V::X, probe, V::R);
    b.gradient(V::Trial, V::GTrial);
    const double curvature = (b.dot(V::GTrial, V::R) - b.dot(V::G, V::R)) / probe;
    alpha = curvature > 0.0 ? gg / curvature : probe;
  }
  // Trial points stay where the energy is finite and the motion admissible (cloth contact).
  if (b.limits_steps()) alpha = b.max_step(V::X, V::R, alpha);
  if (!(alpha > 0.0)) return false;
  LineSearchParams ls;
  ls.max_steps = 60;
  const LineSearchResult r = backtrack(
      [&](double a) {
        b.combine(V::Trial, 1.0, V::X, a, V::R);
        if (energy_evals) ++*energy_evals;
        return b.energy(V::Trial);
      },
      e, -gg, alpha, ls);
  if (!r.success || !(r.energy < e)) return false;
  b.take(V::X, V::Trial);
  e = r.energy;
  return true;
}

namespace {

using V = FmgBackend;

/// The state of one solve: the cycle of Fig. 5 written as its named steps.
class Solve {
 public:
  Solve(FmgBackend& b, const std::string& name, const FmgCycleParams& params, std::vector<double>& beta,
        const Stop& stop, Trace* trace, FmgCycle::Counts& counts, const Timer& clock)
      : b(b), name(name), prm(params), beta(beta), stop(stop), trace(trace), n(counts), timer(clock) {}

  SolveReport run(const std::vector<FmgStage>& stages);

 private:
  template <class F>
  auto timed(double& slot, F&& f) {
    Timer t;
    if constexpr (std::is_void_v<decltype(f())>) {
      f();
      b.synchronize();
      slot += t.ms();
    } else {
      auto v = f();
      b.synchronize();
      slot += t.ms();
      return v;
    }
  }
  double energy(V::Vec y) {
    ++n.energy_evals;
    return timed(n.line_search_ms, [&] { return b.energy(y); });
  }
  /// The gradient at x, and with `with_energy` its energy too, from one pass over the elements.
  void gradient_at_x(bool with_energy = false) {
    timed(n.gradient_ms, [&] {
      if (with_energy) e = b.energy_and_gradient(V::X, V::G);
      else b.gradient(V::X, V::G);
      b.scale(V::R, -1.0, V::G);
      gnorm = b.norm(V::G);
    });
  }
  /// After x changed: projection, then the new residual (and the energy when it is not known).
  void refresh(bool energy_known, double e_new) {
    const Index moved = b.has_projection() ? b.project(V::X) : 0;
    const bool known = energy_known && moved == 0;
    if (known) e = e_new;
    const bool evaluate = !known && (prm.line_search || moved);
    if (evaluate) ++n.energy_evals;
    gradient_at_x(evaluate);
  }
  void update_matrix() {
    if (!b.update_matrix(V::X)) return;  // e.g. the same contact set: keep the hierarchy and its factors
    as_stale = true;
    std::fill(beta.begin(), beta.end(), 1.0);  // a fresh model is trusted again
    ++n.matrix_updates;
  }
  /// Chebyshev weights across corrections (Wang 2015): ω_1 = 1, ω_2 = 2/(2 − ρ²), ω_{k+1} = 4/(4 − ρ² ω_k).
  double next_omega() {
    const double rho = prm.chebyshev_rho;
    ++cheb_k;
    const long k = cheb_k - prm.chebyshev_delay;
    omega = k <= 0 ? 1.0 : k == 1 ? 2.0 / (2.0 - rho * rho) : 4.0 / (4.0 - rho * rho * omega);
    return omega;
  }
  bool weighted() const { return prm.chebyshev_rho > 0.0; }
  /// Pulls Trial back along the segment from X so that the motion X → Trial is admissible (Term::max_step: cloth
  /// contact stays intersection-free); false when no part of it is. GTrial is the scratch for the step.
  bool limit_trial() {
    if (!b.limits_steps()) return true;
    b.combine(V::GTrial, 1.0, V::Trial, -1.0, V::X);
    const double t = timed(n.step_limit_ms, [&] { return b.max_step(V::X, V::GTrial, 1.0); });
    if (t < 1.0) {
      b.combine(V::Trial, 1.0, V::X, t, V::GTrial);
      cycle_cut = true;
    }
    return t > 0.0;
  }
  /// x ← trial, the step kept as s (momentum) unless `forget`.
  void accept(double alpha, double scale_s, bool energy_known, double e_new) {
    if (weighted()) b.copy(V::XPrev, V::X);
    b.scale(V::S, scale_s, V::P);
    b.scale(V::As, scale_s, V::Ap);
    have_s = true;
    b.take(V::X, V::Trial);
    last_alpha = alpha;
    refresh(energy_known, e_new);
  }

  bool direction(const FmgStage& st);
  bool projective_step();
  bool weighted_step(double model_alpha);
  double search_direction(double cr, double dAd, double model_alpha);
  bool accept_by_gradient();
  bool line_search(Index level, double p_slope);
  enum class Outcome { Continue, Stop };
  Outcome no_direction_moved(bool fresh_matrix, int k, SolveReport& rep);
  bool newton_step(int k, SolveReport& rep, bool& stagnated);

  FmgBackend& b;
  const std::string& name;
  const FmgCycleParams& prm;
  std::vector<double>& beta;
  const Stop& stop;
  Trace* trace;
  FmgCycle::Counts& n;
  const Timer& timer;
  double e = 0.0, gnorm = 0.0, last_alpha = 0.0, omega = 1.0, initial = 0.0;
  long cheb_k = 0;
  bool have_s = false, as_stale = false, model_poor = false, force_update = false;
  // Stop::step_tol: the cycles' steps, and whether the motion's limit (contact) cut one of this cycle's moves short.
  StepErrorEstimate step_error{stop.step_tol};
  bool cycle_cut = false, marked = false;
  // Stop::decrement_tol: c·r of the last V-cycle from the finest level, and whether it met the tolerance.
  double decrement = std::numeric_limits<double>::quiet_NaN();
  bool decrement_met = false;
};

// Projective Dynamics (§4.4): the full correction, Chebyshev-weighted, no line search.
bool Solve::projective_step() {
  if (weighted()) {
    const double w = next_omega();
    b.combine(V::Trial, 1.0, V::X, 1.0, V::D);
    b.weight(V::Trial, w, V::Trial, V::XPrev);
    limit_trial();
    b.take(V::XPrev, V::X);
    b.take(V::X, V::Trial);
  } else if (b.limits_steps()) {
    b.combine(V::Trial, 1.0, V::X, 1.0, V::D);
    limit_trial();
    b.take(V::X, V::Trial);
  } else {
    b.combine(V::X, 1.0, V::X, 1.0, V::D);
  }
  last_alpha = 1.0;
  refresh(false, 0.0);
  return true;
}

// The model step weighted against the previous iterate; false (and the weights restart) when it does not decrease
// the energy, and the plain line-searched direction is taken instead.
bool Solve::weighted_step(double model_alpha) {
  const double w = next_omega();
  if (w == 1.0) return false;
  b.combine(V::Trial, 1.0, V::X, model_alpha, V::D);
  b.weight(V::Trial, w, V::Trial, V::XPrev);
  limit_trial();
  const double et = energy(V::Trial);
  if (std::isfinite(et) && et < e) {
    b.take(V::XPrev, V::X);
    b.take(V::X, V::Trial);
    have_s = false;
    last_alpha = model_alpha;
    refresh(true, et);
    return true;
  }
  cheb_k = 0;
  omega = 1.0;
  return false;
}

// The search direction p, scaled so that α = 1 minimizes the model; returns its slope ∇E·p. With momentum, p
// minimizes the model over span{d, s} for s the previous step (beyond the paper: conjugacy across directions, as in
// flexible PCG, which removes the slow tail of bending-dominated modes that the linear coarse correction resolves
// poorly).
double Solve::search_direction(double cr, double dAd, double model_alpha) {
  double p_slope = -model_alpha * cr;
  b.scale(V::P, model_alpha, V::D);
  b.scale(V::Ap, model_alpha, V::Ad);
  if (!(prm.momentum && have_s)) return p_slope;
  timed(n.model_ms, [&] {
    if (as_stale) {
      b.multiply(V::S, V::As);
      as_stale = false;
    }
    const double sAs = b.dot(V::S, V::As), dAs = b.dot(V::D, V::As), sr = b.dot(V::S, V::R);
    const double det = dAd * sAs - dAs * dAs;
    if (dAd > 0.0 && sAs > 0.0 && det > 1e-10 * dAd * sAs) {
      const double a = (cr * sAs - sr * dAs) / det, c = (dAd * sr - dAs * cr) / det;
      b.combine(V::P, a, V::D, c, V::S);
      b.combine(V::Ap, a, V::Ad, c, V::As);
      p_slope = -(a * cr + c * sr);  // < 0: the 2x2 model matrix is SPD
    }
  });
  return p_slope;
}

// Takes the model step when it reduces the gradient norm: where the predicted decrease is below the round-off of
// the energy sum, the Armijo test compares noise (as in Newton), and the gradient is the reliable measure.
bool Solve::accept_by_gradient() {
  b.combine(V::Trial, 1.0, V::X, 1.0, V::P);
  if (!limit_trial()) return false;
  const double gt = timed(n.gradient_ms, [&] {
    b.gradient(V::Trial, V::GTrial);
    return b.norm(V::GTrial);
  });
  if (!(gt < gnorm)) return false;
  accept(1.0, 1.0, false, 0.0);
  return true;
}

// Backtracking from the model step scaled by what this level needed last time (§4.2.3), with safeguarded quadratic
// interpolation between trials. Trial points are made feasible first (§4.5): a direction that would push a few
// vertices into an obstacle is not cut short for all the others by the penalty's steep wall.
bool Solve::line_search(Index level, double p_slope) {
  double& start = beta[static_cast<size_t>(level)];
  // Where the motion is limited (cloth contact), every trial stays below the admissible step; a step cut short by
  // contact says nothing about the level's scale, so it does not change the level's start.
  const double alpha0 =
      b.limits_steps() ? timed(n.step_limit_ms, [&] { return b.max_step(V::X, V::P, start); }) : start;
  if (alpha0 < start) {
    logger().debug("{}: level {} step limited to {:.3g} of {:.3g}", name, level, alpha0, start);
    cycle_cut = true;
  }
  if (!(alpha0 > 0.0)) {
    ++n.rejected;
    return false;
  }
  // Only a search that contact cut short is refined: there a wall of pairs entering their layer lies along the line.
  // Refining every backtracked search made the 10K layered drape take 1.33x the cycles (bench/RESULTS.md).
  LineSearchParams ls = prm.line_search_params;
  if (!(alpha0 < start)) ls.refine = 0;
  const auto place = [&](double alpha) {
    b.combine(V::Trial, 1.0, V::X, alpha, V::P);
    if (b.has_projection()) b.project(V::Trial);
  };
  const LineSearchResult r = backtrack(
      [&](double alpha) {
        place(alpha);
        return energy(V::Trial);
      },
      e, p_slope, alpha0, ls, place);
  if (!r.success) {
    start = std::max(1e-3, 0.5 * start);
    // Close to round-off the energy differences are noisy well above the model's own threshold.
    if (-p_slope < 1e-9 * std::max(1.0, std::abs(e)) && accept_by_gradient()) return true;
    ++n.rejected;
    return false;
  }
  if (r.alpha < prm.refresh_below) model_poor = true;
  // A first-trial acceptance lets the next start probe twice as far (never beyond the model step).
  if (alpha0 == start) start = std::min(1.0, r.trials == 1 ? 2.0 * r.alpha : r.alpha);
  accept(r.alpha, r.alpha, true, r.energy);
  return true;
}

// One search direction from a stage of the schedule; returns whether x moved.
bool Solve::direction(const FmgStage& st) {
  ++n.directions;
  const double cr = b.correction(st.level, st.linear, st.sweeps, V::R, V::D);
  if (st.level == 0 && st.linear) {
    decrement = std::max(0.0, cr);
    decrement_met = stop.decrement_tol > 0.0 && decrement <= stop.decrement_tol;
  }
  // Theorem 4.1/4.2: the smoothing operator is SPD, so c·r > 0 unless the (masked) residual vanishes.
  if (!(cr > 0.0)) {
    ++n.rejected;
    return false;
  }
  // The quadratic model E + ∇E·d + ½ dᵀA_0 d gives the step length: exactly 1 for the coarse solve, near 1 for
  // smoothed corrections under a fresh matrix, smaller for coarse corrections under a stale one (§4.2.3).
  const double dAd = timed(n.model_ms, [&] {
    b.multiply(V::D, V::Ad);
    return b.dot(V::D, V::Ad);
  });
  const double model_alpha = dAd > 0.0 ? cr / dAd : 1.0;
  if (!prm.line_search) return projective_step();
  if (weighted() && weighted_step(model_alpha)) return true;
  const double p_slope = search_direction(cr, dAd, model_alpha);
  if (-p_slope < 1e-13 * std::max(1.0, std::abs(e))) {
    if (accept_by_gradient()) return true;
    ++n.rejected;
    return false;
  }
  return line_search(st.level, p_slope);
}

// The Newton step of the model, solved by V-cycles to a residual of 1e-3. Where even its predicted decrease is below
// the round-off of the energy sum, the energy cannot tell better from worse (the limiting accuracy of a line
// search): the step is judged by the gradient norm, and if that fails too the solve has stagnated.
bool Solve::newton_step(int k, SolveReport& rep, bool& stagnated) {
  stagnated = false;
  b.newton_step(V::R, V::C, 1e-3 * gnorm);
  const double predicted = 0.5 * b.dot(V::C, V::R);
  const bool below_noise = !(predicted > 1e-13 * b.energy_magnitude(V::X));
  b.combine(V::Trial, 1.0, V::X, 1.0, V::C);
  if (b.has_projection()) b.project(V::Trial);
  if (!limit_trial()) return false;
  const double et = energy(V::Trial);
  const double gt = timed(n.gradient_ms, [&] {
    b.gradient(V::Trial, V::GTrial);
    return b.norm(V::GTrial);
  });
  if (std::isfinite(et) && (et < e || (below_noise && gt < gnorm))) {
    b.take(V::X, V::Trial);
    e = et;
    b.take(V::G, V::GTrial);
    gnorm = gt;
    b.scale(V::R, -1.0, V::G);
    have_s = false;
    ++n.fallbacks;
    force_update = true;
    check_finite(name, e, gnorm, k + 1);
    if (weighted()) b.copy(V::XPrev, V::X);
    return true;
  }
  if (below_noise) {
    rep.status = "stagnated";
    stagnated = true;
  }
  return false;
}

// No direction of a cycle decreased the energy: a matrix too stale to help (retry with a fresh one), the limiting
// accuracy (round-off), or a model that misleads every direction (steepest descent, then the model's Newton step,
// and go on).
Solve::Outcome Solve::no_direction_moved(bool fresh_matrix, int k, SolveReport& rep) {
  if (!fresh_matrix && prm.line_search) {
    force_update = true;
    return Outcome::Continue;
  }
  double floor = 0.0;
  if (b.at_roundoff_floor(V::X, gnorm, &floor)) {
    rep.status = "stagnated";
    return Outcome::Stop;
  }
  if (prm.line_search && steepest_descent(b, true, e, &n.energy_evals)) {
    refresh(true, e);
    have_s = false;
    std::fill(beta.begin(), beta.end(), 1.0);
    ++n.fallbacks;
    force_update = true;
    check_finite(name, e, gnorm, k + 1);
    if (weighted()) b.copy(V::XPrev, V::X);
    return Outcome::Continue;
  }
  bool stagnated = false;
  if (newton_step(k, rep, stagnated)) return Outcome::Continue;
  if (stagnated) return Outcome::Stop;
  if (gnorm <= 1e-3 * initial) {
    rep.status = "stalled";
    return Outcome::Stop;
  }
  throw SolveError(fmt::format("{}: no search direction decreased the energy in cycle {} (|g| = {:.3e}, relative "
                               "{:.3e}, {:.0f}x the gradient's round-off floor); tried: a fresh Hessian, every "
                               "level's correction, a steepest-descent step, the model's Newton step",
                               name, k + 1, gnorm, gnorm / initial, floor > 0 ? gnorm / floor : 0.0));
}

SolveReport Solve::run(const std::vector<FmgStage>& stages) {
  SolveReport rep;
  gradient_at_x(true);
  check_finite(name, e, gnorm, 0);
  initial = rep.initial_grad_norm = gnorm;
  if (trace) trace->push_back({0, e, gnorm, timer.ms(), 0.0});
  const double target = std::max(stop.abs_grad, stop.rel_grad * gnorm);
  if (weighted()) b.copy(V::XPrev, V::X);

  const bool per_solve = prm.matrix_update == MatrixUpdate::Step || prm.matrix_update == MatrixUpdate::Constant;
  const bool refreshable = prm.matrix_update == MatrixUpdate::Direction || prm.matrix_update == MatrixUpdate::Cycle;
  rep.status = "max_iters";
  int k = 0;
  bool done = false;
  for (; k < stop.max_iters && !done; ++k) {
    if (should_stop(gnorm, target, timer.seconds(), stop, rep)) break;
    if (marked) step_error.record(b.max_distance_from_mark(V::X), cycle_cut);
    marked = false;
    if (step_error.met()) {
      rep.status = "converged";
      break;
    }
    b.mark(V::X);
    marked = true;
    cycle_cut = false;
    const bool fresh_matrix = !per_solve || k == 0 || force_update;
    if (fresh_matrix) update_matrix();
    force_update = false;
    int moved = 0;
    bool stale = false;
    for (const FmgStage& st : stages) {
      // The matrix is also refreshed within a cycle when the line search found the model far off (a large move,
      // e.g. the coarse correction bringing the cloth into contact, whose stiffness the old matrix lacks).
      if (stale && refreshable && (prm.matrix_update == MatrixUpdate::Direction || model_poor)) {
        update_matrix();
        ++n.refreshes;
      }
      model_poor = false;
      stale = direction(st);
      if (stale) ++moved;
      check_finite(name, e, gnorm, k + 1);
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
    // The decrement was measured at this cycle's start point; its step was taken all the same.
    if (!done && decrement_met) {
      rep.status = "converged";
      done = true;
    }
    if (!prm.line_search) e = b.energy(V::X);
    ++n.cycles;
    if (trace) trace->push_back({k + 1, e, gnorm, timer.ms(), last_alpha});
    logger().debug("{} cycle {:3d}: E = {:.12e}  |g| = {:.3e}  directions {} rejected {}", name, k + 1, e, gnorm,
                   n.directions, n.rejected);
    if (moved == 0 && !done && no_direction_moved(fresh_matrix, k, rep) == Outcome::Stop) {
      ++k;
      break;
    }
  }
  if (marked) step_error.record(b.max_distance_from_mark(V::X), cycle_cut);
  finish_report(rep, k, e, gnorm, target, timer.ms());
  rep.step_error = step_error.error();
  rep.decrement = decrement;
  rep.counters = {{"directions", static_cast<double>(n.directions)},
                  {"rejected_directions", static_cast<double>(n.rejected)},
                  {"energy_evals", static_cast<double>(n.energy_evals)},
                  {"matrix_updates", static_cast<double>(n.matrix_updates)},
                  {"refreshes", static_cast<double>(n.refreshes)},
                  {"fallbacks", static_cast<double>(n.fallbacks)},
                  {"line_search_ms", n.line_search_ms},
                  {"gradient_ms", n.gradient_ms},
                  {"model_ms", n.model_ms},
                  {"step_limit_ms", n.step_limit_ms}};
  for (auto& c : b.counters()) rep.counters.push_back(std::move(c));
  return rep;
}

}  // namespace

SolveReport FmgCycle::run(FmgBackend& backend, const std::string& name, const FmgCycleParams& params,
                          const std::vector<FmgStage>& stages, std::vector<double>& beta, const Stop& stop,
                          Trace* trace, Counts& counts, const Timer& clock) {
  counts = Counts{};
  if (beta.empty()) throw_error("{}: no line-search scales (the hierarchy has no levels)", name);
  return Solve(backend, name, params, beta, stop, trace, counts, clock).run(stages);
}

}  // namespace mgcloth::solvers
