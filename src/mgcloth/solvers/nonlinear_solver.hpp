#pragma once
#include <mgcloth/core/types.hpp>
#include <mgcloth/hierarchy/hierarchy.hpp>
#include <mgcloth/physics/energy_form.hpp>
#include <mgcloth/physics/objective.hpp>

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace mgcloth::solvers {

/// What a solver minimizes: the objective, the discretization's hierarchy for multilevel solvers, and a hook that
/// makes iterates feasible (docs/ARCHITECTURE.md).
struct Problem {
  const physics::Objective* objective = nullptr;
  /// Levels finest first, level 0 the objective's unknown (hierarchy.levels[0].objective == objective when set).
  /// Empty when the solver needs none (NonlinearSolver::needs_hierarchy()); coarse objectives and projections of
  /// iterates are filled only for solvers that rediscretize (NonlinearSolver::needs_level_objectives()).
  hierarchy::Hierarchy hierarchy;
  /// Optional: makes an iterate feasible (obstacle projection, Wang 2018 §4.5); called after accepted updates
  /// by solvers that support it. Returns the number of vertices it moved (0: x unchanged).
  std::function<Index(VecX&)> project;
};

struct Stop {
  double rel_grad = 1e-6;  ///< stop when |∇E(x)| <= rel_grad · |∇E(x_0)|
  double abs_grad = 0.0;   ///< or when |∇E(x)| <= abs_grad
  /// Or when the estimated largest per-vertex distance of x to the minimizer is at most step_tol (0: never). The
  /// estimate is StepErrorEstimate's; the simulator sets step_tol = velocity_tol · h, so that a solve stops once no
  /// vertex's velocity is off by more than velocity_tol (m/s).
  double step_tol = 0.0;
  /// Or once the model's Newton decrement λ² = ∇Eᵀ A⁻¹ ∇E measured at an iterate (A the solver's Hessian model, A⁻¹
  /// the solver's own inverse of it: a factorization, PCG, or FMG's V-cycle) is at most decrement_tol (J; 0: never).
  /// The iteration that measured it still takes its step, so the result has no higher energy than that iterate.
  /// E(x) − E* ≈ λ²/2, and where A ≥ M/h² (an implicit step's model: inertia plus PSD-projected forces) the kinetic
  /// energy of the velocity error is at most that: the simulator sets decrement_tol = M·velocity_rms_tol² so that the
  /// mass-weighted RMS of the velocity error is at most velocity_rms_tol (m/s).
  double decrement_tol = 0.0;
  int max_iters = 100;
  double max_seconds = kInf;
  /// Stop with status "interrupted" once mgcloth::interrupted() (SIGINT or SIGTERM under the CLI's handler).
  bool interruptible = false;
  /// Called with the current iterate, its iteration count, energy and gradient norm at most every
  /// checkpoint_seconds (after an accepted step or a V-cycle; `tr-*` and `rmtr`), so that a run killed without
  /// warning can go on from there.
  std::function<void(const VecX& x, int iterations, double energy, double grad_norm)> checkpoint;
  double checkpoint_seconds = 600.0;
};

/// One row per iteration (iteration 0 is the start point).
struct TraceRow {
  int iteration = 0;
  double energy = 0.0;
  double grad_norm = 0.0;
  double wall_ms = 0.0;  ///< since the solve started
  double step = 0.0;     ///< line-search step length taken to reach this iterate
};
using Trace = std::vector<TraceRow>;

struct SolveReport {
  int iterations = 0;
  bool converged = false;
  double energy = 0.0;
  double grad_norm = 0.0;
  double initial_grad_norm = 0.0;
  double wall_ms = 0.0;
  std::string status;  ///< "converged", "max_iters", "time_limit", "stalled" (no decrease possible in floating point)
  /// StepErrorEstimate's last estimate of the largest per-vertex distance of x to the minimizer (m), made whatever
  /// the stop rule; infinite where no estimate was possible (fewer than three moving iterations, steps not
  /// contracting, the last step cut short by contact); NaN where the solver makes none.
  double step_error = std::numeric_limits<double>::quiet_NaN();
  /// The last Newton decrement λ² (Stop::decrement_tol) the solve measured, at its last iterate but one; NaN where the
  /// solver measures none (NonlinearSolver::estimates_decrement) or made no iteration.
  double decrement = std::numeric_limits<double>::quiet_NaN();
  /// Solver-specific counters of the solve (e.g. line-search evaluations, time per phase), for statistics.
  std::vector<std::pair<std::string, double>> counters;
};

class NonlinearSolver {
 public:
  virtual ~NonlinearSolver() = default;
  virtual std::string name() const = 0;
  /// Whether minimize() needs Problem::hierarchy (its prolongations).
  virtual bool needs_hierarchy() const { return false; }
  /// Whether minimize() needs the hierarchy's coarse objectives, projections of iterates and patches (implies
  /// needs_hierarchy()).
  virtual bool needs_level_objectives() const { return false; }
  /// The energy forms this solver can minimize, the one it was made for first. The scene chooses the form
  /// ("energy_form"); a scene whose form is not in this list is refused (check_energy_form). Most solvers minimize
  /// either (the PD form is a smooth energy whose "Hessian" is the constant PD matrix); the pd-* presets are the PD
  /// local/global iterations and need its constant matrix.
  virtual std::vector<physics::EnergyForm> energy_forms() const {
    return {physics::EnergyForm::Elastic, physics::EnergyForm::Projective};
  }
  bool can_minimize(physics::EnergyForm form) const;
  /// Whether every trial point of minimize() is limited by the objective's max_step (Term::max_step), as an
  /// objective with cloth contact needs to stay intersection-free (check_step_limits refuses the others).
  virtual bool supports_step_limits() const { return false; }
  /// Whether SolveReport::step_error, and so Stop::step_tol, can be trusted: a single-level smoother's steps do not
  /// show how slowly it removes smooth errors (gs-chebyshev stopped with an estimate of 1e-3 m/s and 3.3e-2 m/s
  /// left, tests/solvers/test_step_error.cpp), so the simulator refuses a velocity tolerance for it.
  virtual bool estimates_step_error() const { return true; }
  /// Whether SolveReport::decrement, and so Stop::decrement_tol, is measured: a solver whose iterations solve (or
  /// approximate by a V-cycle from the finest level) the Newton system of the true Hessian model. Projective Dynamics'
  /// constant matrix, single-level smoothers and trust-region models bounded by their radius do not.
  virtual bool estimates_decrement() const { return false; }
  /// Minimizes problem.objective from x (updated in place). Throws SolveError when the solve diverges
  /// (non-finite energy or gradient, no descent possible far from a minimum).
  virtual SolveReport minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) = 0;
  /// Iterates besides x that a solve stopped part-way needs to go on as it would have (RMTR: every coarse level's
  /// state, where its coarse corrections start from); empty for most solvers. Valid during (for checkpoints) and
  /// after minimize().
  virtual std::vector<VecX> level_states() const { return {}; }
  /// Hands level_states() of an earlier part of the same solve to the next minimize(), which then goes on from
  /// them instead of starting afresh (ignored where they do not fit the problem).
  virtual void resume_level_states(std::vector<VecX> /*states*/) {}
  /// A solver that keeps the solution on a device ends the time step there too, after minimize(): contact
  /// projection of x, the velocity v = (x − x_old)/h and the friction filter (what bodies::ClothBody::finish_step does
  /// on the CPU). Returns false where the caller must do it.
  virtual bool finish_step(const VecX& /*x_old*/, double /*h*/, VecX& /*x*/, VecX& /*v*/) { return false; }
  /// What a minimize() leaves behind that steers the next one (FMG: the Chebyshev spectral radii estimated on the
  /// run's first matrix, the line search's starting scales), as bytes for checkpoints
  /// (sim::Checkpoint::Body::solver_state); empty when the next solve depends only on its problem and start.
  virtual std::string carried_state() const { return {}; }
  /// Gives carried_state() back before the next minimize(), which then solves exactly as the solver that wrote it
  /// would have (a resumed run repeats the uninterrupted one bit for bit). Empty: a fresh solver. Throws InputError
  /// when the state is not one this solver wrote for this problem's size.
  virtual void restore_carried_state(std::string_view state);
};

/// Throws InputError, naming `where` (e.g. the scene file), when `solver` cannot minimize `form`, saying which form
/// it minimizes and how to choose it.
void check_energy_form(const NonlinearSolver& solver, physics::EnergyForm form, const std::string& where);

/// Throws InputError, naming `where`, when the objective limits steps (cloth contact) and `solver` does not keep
/// its trial points within them, naming the solvers that do.
void check_step_limits(const NonlinearSolver& solver, const physics::Objective& objective, const std::string& where);
/// The solver names whose solvers support step limits (for messages and docs).
std::vector<std::string> step_limiting_solvers();

/// carried_state() encoding: `tag` (the solver kind, so that a state is never read by another kind), a NUL, then
/// the values' bytes in the host's order.
std::string encode_carried_state(std::string_view tag, const std::vector<double>& values);
/// The values of a state encode_carried_state(tag, ...) wrote; InputError naming `tag` otherwise.
std::vector<double> decode_carried_state(std::string_view tag, std::string_view state);

/// Pieces every iterative solver shares.
/// Throws SolveError when the energy or the gradient norm is not finite (the solve diverged).
void check_finite(const std::string& solver, double energy, double grad_norm, int iteration);
/// The stopping tests at the top of an iteration: sets report.status and returns true when the solve stops.
bool should_stop(double grad_norm, double target, double seconds, const Stop& stop, SolveReport& report);
/// For an objective whose Hessian does not depend on x (the Projective Dynamics matrix): assembles it into A on
/// first use (`have` false); later calls reassemble into `scratch` and swap it in only when it differs (the contact
/// active set changed). Returns whether A changed, i.e. whether factorizations of it must be redone.
bool update_constant_matrix(const physics::Objective& objective, const VecX& x, bool have, bool project_psd,
                            linalg::BlockMatrix3& A, linalg::BlockMatrix3& scratch);
/// Whether a stuck solve is at its limiting accuracy (physics::at_roundoff_floor).
using physics::at_roundoff_floor;
using physics::kRoundoffFloorFactor;
/// The fallback of a solve whose own directions all failed: a steepest-descent step with a backtracking line search
/// from the step that minimizes the quadratic model along −∇E (`A` when non-null, else a secant guess from the
/// gradient at a small probe). On success x, e, g and grad_norm describe the new point.
bool steepest_descent_fallback(const physics::Objective& objective, const linalg::BlockMatrix3* A, VecX& x, double& e,
                               VecX& g, double& grad_norm);
/// The largest distance between corresponding vertices (consecutive coordinate triples) of a and b.
double max_vertex_distance(const VecX& a, const VecX& b);

/// The a-posteriori error estimate of a linearly contracting iteration (Hairer & Wanner, Solving ODEs II, §IV.8,
/// eqs. 8.10-8.11, their stopping rule for the Newton iterations of implicit integrators): with Δ_k the step of
/// iteration k (largest per-vertex length) and Θ_k = max(Δ_k/Δ_{k−1}, Δ_{k−1}/Δ_{k−2}) its observed contraction,
/// an iteration that contracts by Θ_k from here on is within Θ_k/(1 − Θ_k)·Δ_k of its limit (the first estimate
/// comes after three steps). Steps cut short by a limit on the motion (contact) are recorded with `cut`: they say
/// nothing of the contraction, and no ratio is formed with them.
class StepErrorEstimate {
 public:
  /// tol: Stop::step_tol (0: the estimate is made, for the report, but never stops a solve).
  explicit StepErrorEstimate(double tol) : m_tol(tol) {}
  /// Records the step of one iteration that moved x (a step of 0, nothing moved, is not an iteration of the map
  /// and is ignored); returns the new estimate.
  double record(double step, bool cut = false);
  /// Whether the last estimate is within a tolerance > 0.
  bool met() const { return m_tol > 0.0 && m_error <= m_tol; }
  double error() const { return m_error; }

 private:
  double m_tol = 0.0, m_previous = kInf, m_error = kInf;
  double m_ratio = std::numeric_limits<double>::quiet_NaN();  ///< the last step's ratio to the one before
  bool m_previous_cut = true;
};

/// StepErrorEstimate of a solver whose iterate is a VecX: at the top of every iteration, converged(x) records x's
/// change since the last call and says whether Stop::step_tol is met; finish() records the last iteration's step
/// and fills SolveReport::step_error. One copy of x per iteration.
class StepTracker {
 public:
  explicit StepTracker(const Stop& stop) : m_estimate(stop.step_tol) {}
  explicit StepTracker(double step_tol) : m_estimate(step_tol) {}
  /// `cut`: the motion's limit (contact) cut the step since the last call short.
  bool converged(const VecX& x, bool cut = false);
  void finish(const VecX& x, SolveReport& report, bool cut = false);

 private:
  StepErrorEstimate m_estimate;
  VecX m_mark;
  bool m_marked = false;
};

/// The report's final fields (a solve that ran out of iterations exactly at the target counts as converged).
void finish_report(SolveReport& report, int iterations, double energy, double grad_norm, double target, double wall_ms);

}  // namespace mgcloth::solvers
