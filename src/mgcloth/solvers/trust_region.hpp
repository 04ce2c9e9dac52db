#pragma once
#include <mgcloth/linalg/exact_trust_region.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>
#include <mgcloth/linalg/patch_smoother.hpp>
#include <mgcloth/linalg/trust_region_qp.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

#include <functional>
#include <string>
#include <vector>

namespace mgcloth::solvers {

/// Subproblem solver of each trust-region iteration (Kopaničáková 2019, §7.3).
/// GaussSeidel: a smoothing step (linalg::gauss_seidel_step), for RMTR's smoothers (beyond the paper).
/// Schwarz: the same with overlapping patches (linalg::patch_step; needs LocalTrustRegion::set_patches()).
enum class TrQp { Dogleg, SteihaugCg, GaussSeidel, Schwarz, Exact };

/// Trust-region constants (Kopaničáková 2019, Table 2) and stopping rules (§7.2, criterion 7.1).
struct TrustRegionParams {
  double eta1 = 0.1;     ///< a trial point is accepted when ρ > η1 (Alg. 4.1, line 4); Δ shrinks when ρ < η1
  double eta2 = 0.75;    ///< Δ grows when ρ > η2 (Alg. 4.3, line 2)
  double gamma1 = 0.5;   ///< shrink factor
  double gamma2 = 2.0;   ///< growth factor
  double delta0 = 1.0;   ///< initial radius of every minimize()
  double delta_max = 1e20;
  TrQp qp = TrQp::Dogleg;
  int stcg_max_iters = 0;     ///< CG iterations per subproblem; 0: 3·dofs (in effect unlimited)
  /// CG stops at ‖r‖ ≤ tol·‖g‖; 0: the forcing term min(0.5, √(‖g‖/‖g₀‖)) of the run's start g₀, which keeps
  /// Newton's superlinear convergence near the minimizer (Nocedal-Wright Thm. 7.2) without solving far from it.
  double stcg_rel_tol = 0.0;
  int gs_sweeps = 2;  ///< symmetric Gauss-Seidel or Schwarz sweeps per subproblem (TrQp::GaussSeidel, Schwarz)
  /// Criterion (7.1), second part: once Δ > stagnation_delta (the method has become Newton's), the solve stops as
  /// "stalled" when the last iteration changed the energy or the iterate by less than stagnation_tol (absolute),
  /// the limiting accuracy of the ill-conditioned problem. A rejected step changes neither, so it stops too.
  double stagnation_tol = 1e-12;
  double stagnation_delta = 1e15;
  /// When the predicted decrease is below roundoff_tol·|h(x)|, ρ compares round-off noise; the trial point is
  /// then judged by the gradient norm: accepted with Δ unchanged when ‖∇h‖ decreases, else the run stops as
  /// "stalled" (limiting accuracy). Relative to |h| alone, not max(1, |h|): cloth energies of 0.05 J would
  /// otherwise hit the guard while ρ is still accurate. Beyond the paper; 0 = off.
  double roundoff_tol = 1e-14;
  /// The model's Hessian: exact (false, the paper) or with every element Hessian projected to positive semidefinite
  /// (true, beyond the paper: the projected Newton of the cloth solvers, a convex model that needs no shift).
  bool psd_hessian = false;
  /// Dogleg, "hessian": "hybrid" (beyond the paper): the exact Hessian where it is positive definite, the projected
  /// one (psd_hessian) where it is not, instead of the exact one shifted by λI.
  bool hybrid_hessian = false;
  /// Dogleg: geometric bisections of the shift λ where H is indefinite (0: the first decade that factorizes).
  int shift_bisections = 0;
  /// Dogleg ("shift": "radius"): where H is indefinite, λ solves ‖(H + λI)⁻¹g‖ = Δ (to 10%, at most 6 more
  /// factorizations per radius), the shift of the exact trust-region step, so that the radius sets the step's
  /// length. false ("factorize"): the smallest shift found that factorizes, whatever Δ. Implies shrink_from_step.
  bool radius_shift = false;
  /// A rejected step shrinks the radius to γ1·min(Δ, ‖s‖) instead of γ1·Δ (beyond the paper's Alg. 4.3, line 2; the
  /// usual practice): after an interior (Newton) step far inside a radius that has grown to 1e15, halving Δ alone
  /// would need tens of rejected iterations before the radius constrains anything again.
  bool shrink_from_step = false;
  /// Beyond the paper: after an accepted step whose actual decrease exceeded the model's (ρ > 1, the model is too
  /// stiff along s, as the PSD-projected Hessian of "hybrid" is where the exact one has negative curvature), try
  /// doubling the total step up to this many times, keeping each doubling that lowers the energy (one energy
  /// evaluation each). 0 = off.
  int extrapolate = 0;
};

/// Alg. 4.3, line 2: γ1Δ for ρ < η1, Δ for ρ ∈ [η1, η2], γ2Δ (at most Δ_max) for ρ > η2.
double radius_update(const TrustRegionParams& p, double rho, double radius, double step_norm = kInf);

/// The objective of one level, h(x) = f(x) + ⟨δg, x − x₀⟩ (Kopaničáková 2019, eq. 4.3): the coupling term
/// makes the coarse gradient at x₀ equal the restricted fine gradient (eq. 4.5). Without δg, h = f. The Hessian
/// is always f's exact one (eq. 4.1: H = ∇²f, never PSD-projected). Keeps references: f must outlive it.
class LevelModel {
 public:
  explicit LevelModel(const physics::Objective& f) : m_f(&f) {}
  LevelModel(const physics::Objective& f, VecX delta_g, const VecX& x0);

  /// Also second-order consistent (beyond the paper): h(x) = f(x) + ⟨δg, x − x₀⟩ + ½ (x − x₀)ᵀ δH (x − x₀), so that
  /// ∇²h(x₀) = ∇²f(x₀) + δH is a given matrix (the Galerkin Sᵀ H S of the fine Hessian). δH must have the pattern
  /// of f's Hessian and outlive the model.
  LevelModel(const physics::Objective& f, VecX delta_g, const VecX& x0, const linalg::BlockMatrix3* delta_h);

  const physics::Objective& objective() const { return *m_f; }
  bool has_linear_term() const { return m_delta_g.size() > 0; }
  double value(const VecX& x) const;
  void gradient(const VecX& x, VecX& g) const;
  void hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd = false) const;

 private:
  const physics::Objective* m_f;
  VecX m_delta_g;
  double m_offset = 0.0;  ///< −⟨δg, x₀⟩
  const linalg::BlockMatrix3* m_delta_h = nullptr;
  VecX m_x0;
};

/// Work done by Local_TR; derivatives are assembled only at accepted points (Table 6's count).
struct TrCounters {
  int accepted = 0;
  int rejected = 0;
  int hessian_assemblies = 0;
  int gradient_assemblies = 0;
  int energy_evaluations = 0;
  int qp_calls = 0;
  long cg_iterations = 0;
  int factorizations = 0;     ///< numeric CHOLMOD factorizations (dogleg), shifted retries included
  int cholmod_fallbacks = 0;  ///< dogleg preparations whose H was not positive definite
  int projected_models = 0;   ///< "hybrid": points where the exact H was indefinite and the projected one was used
  int extrapolations = 0;     ///< doublings of accepted steps kept (TrustRegionParams::extrapolate)
};

/// One Local_TR iteration, accepted or rejected.
struct TrIteration {
  bool accepted = false;
  double radius = 0.0;       ///< Δ_i the subproblem was solved with
  double next_radius = 0.0;  ///< Δ_{i+1}
  double rho = 0.0;          ///< eq. (4.2); ±∞ when the trial energy was not finite
  double predicted = 0.0;    ///< m(0) − m(s)
  double actual = 0.0;       ///< h(x) − h(x + s)
  double step_norm = 0.0;    ///< ‖s‖
  linalg::QpStop qp = linalg::QpStop::Converged;
  int cg_iterations = 0;
  /// Accepted, and the full step of the unshifted exact model (dogleg or exact subproblem, interior, H itself
  /// positive definite): the trust region acted as Newton's method, as (7.1)'s Δ > 1e15 stands for.
  bool newton = false;
};

/// How long Local_TR runs and what it may call.
struct LocalTrControl {
  int max_iters = 1;  ///< i_max of Alg. 4.1: iterations, accepted or rejected
  /// Stop when ‖∇h‖ ≤ max(abs_grad, rel_grad·‖∇h(x₀)‖) (0, 0: never by the gradient).
  double rel_grad = 0.0;
  double abs_grad = 0.0;
  /// Stop::step_tol: or stop once StepErrorEstimate puts x within step_tol of the minimizer (0: never).
  double step_tol = 0.0;
  double max_seconds = kInf;
  bool interruptible = false;  ///< stop as "interrupted" once mgcloth::interrupted()
  /// Stop::checkpoint, called after accepted steps at most every checkpoint_seconds.
  std::function<void(const VecX&, int, double, double)> checkpoint;
  double checkpoint_seconds = 600.0;
  const Timer* timer = nullptr;  ///< clock of the time limit and of trace wall times (own clock when null)
  Trace* trace = nullptr;        ///< receives the start row and one row per iteration
  /// Applied to each new radius: Δ_{i+1} = radius_cap(x_{i+1}, Δ₊); for RMTR's coarse-level limit (Alg. 4.3,
  /// lines 3-7). A result ≤ 0 ends the run with status "radius_exhausted".
  std::function<double(const VecX& x, double radius)> radius_cap;
  /// Feasibility projection after accepted steps (Problem::project); h is re-evaluated when it moves x.
  std::function<Index(VecX&)> project;
  /// The trust-region norm: ‖s‖_M of RMTR's level-dependent norm (eq. 4.9) on a coarse level; ℓ2 when null.
  /// Must outlive the run.
  const linalg::NormMetric* metric = nullptr;
  /// When set, h(x) and ∇h(x) at the start are these (known to the caller, e.g. the restricted fine gradient of
  /// eq. 4.5 or the end of the previous run at the same x) instead of being evaluated.
  const double* start_energy = nullptr;
  const VecX* start_gradient = nullptr;
};

struct LocalTrResult {
  int iterations = 0;
  /// "max_iters" (i_max done), "converged", "time_limit", "stalled", "radius_exhausted".
  std::string status;
  double energy = 0.0;  ///< h at the final x
  double initial_energy = 0.0;  ///< h at the start
  double grad_norm = 0.0;
  double initial_grad_norm = 0.0;
  double grad_target = 0.0;
  double step_error = std::numeric_limits<double>::quiet_NaN();  ///< SolveReport::step_error
};

/// Local_TR (Kopaničáková 2019, Alg. 4.1) with the radius update of Alg. 4.3 line 2, as a reusable core: the
/// single-level TrustRegion solver runs it to convergence, RMTR runs it for μ iterations as a smoother on each
/// level's model h_l. Gradient and Hessian are assembled only at accepted points; a rejected step re-solves the
/// subproblem with the smaller radius (the dogleg without refactoring). The object keeps the dogleg's CHOLMOD
/// analysis across runs, so one instance per level (per Hessian pattern) should be reused.
class LocalTrustRegion {
 public:
  /// `name` prefixes the messages of the SolveErrors it throws.
  explicit LocalTrustRegion(TrustRegionParams params = {}, std::string name = "local-tr");
  const TrustRegionParams& params() const { return m_params; }

  /// Runs up to control.max_iters iterations on h from x (updated in place) with radius Δ (updated in place).
  /// Throws SolveError when h or ∇h is not finite at the start or at an accepted point.
  LocalTrResult run(const LevelModel& h, VecX& x, double& radius, const LocalTrControl& control);

  /// ∇h at the x run() returned (for RMTR's restriction of the fine gradient, eq. 4.4).
  const VecX& gradient() const { return m_g; }
  /// Accumulated over runs since the last reset().
  const TrCounters& counters() const { return m_counters; }
  const std::vector<TrIteration>& history() const { return m_history; }
  void reset();
  /// The dogleg's last shift, where the next indefinite Hessian's shift search starts (Dogleg::shift), and its
  /// restoration from a checkpoint.
  double dogleg_shift() const { return m_dogleg.shift(); }
  void set_dogleg_shift(double shift) { m_dogleg.set_start_shift(shift); }
  /// The patches of TrQp::Schwarz (e.g. every control point with its one-ring).
  void set_patches(std::vector<std::vector<Index>> patches);

 private:
  /// Solves subproblem (4.1) at the current point with radius Δ in the norm of `metric` (ℓ2 when null).
  linalg::QpResult solve_qp(double radius, double initial_grad_norm, const linalg::NormMetric* metric);
  // The steps of run(), one Alg. 4.1 iteration after the other.
  struct Run;
  struct Verdict;
  /// The energy and gradient at the start (given or evaluated), the gradient target and the trace's first row.
  void start(Run& r, const VecX& x);
  /// The stopping tests before an iteration: the gradient target, time, interruption, (7.1)'s second clause, a
  /// radius below round-off. Sets the run's status; true when it stops.
  bool stops(Run& r, const VecX& x, double radius) const;
  /// The Hessian at x and the subproblem solver's preparation (factorization, smoother), once per accepted point.
  void prepare_model(Run& r, const VecX& x, int i);
  /// Evaluates x + s: ρ of eq. 4.2 and acceptance (Alg. 4.1, line 4), or the gradient test where the decrease is
  /// round-off; the next radius.
  Verdict judge_trial(Run& r, const VecX& x, const linalg::QpResult& qp, TrIteration& it, double radius);
  /// Moves x to the accepted trial point (extrapolated, projected) and updates energy, gradient and checkpoint.
  void accept(Run& r, VecX& x, const linalg::QpResult& qp, TrIteration& it, const Verdict& v, int i);
  /// p.extrapolate: doubles an accepted step while the energy keeps decreasing.
  void extrapolate(Run& r, VecX& x, const VecX& s, TrIteration& it);
  void reject(Run& r);

  TrustRegionParams m_params;
  std::string m_name;
  linalg::Dogleg m_dogleg;
  bool m_model_exact = true;  ///< the current model's Hessian is the exact one (not projected)
  linalg::ExactTrustRegion m_exact;
  std::unique_ptr<linalg::MultiColorGaussSeidel> m_gs;
  std::unique_ptr<linalg::PatchSmoother> m_patches;
  linalg::BlockMatrix3 m_hessian;
  VecX m_g, m_g_trial, m_trial;
  TrCounters m_counters;
  std::vector<TrIteration> m_history;
};

/// The single-level trust-region method (Kopaničáková 2019, Alg. 4.1, Table 2) on the exact Hessian, with the
/// dogleg ("tr-dogleg", the paper's TR, §7.3) or Steihaug-Toint CG ("tr-stcg") as subproblem solver.
/// One Stop iteration is one trust-region iteration, accepted or rejected. Trace rows: one per iteration; `step`
/// is ‖s‖ of an accepted step and 0 for a rejected one (the iterate did not move); history() has the radii and ρ.
/// Stops on Stop's gradient and time tests, and as "stalled" on the stagnation clause of (7.1) or when no model
/// decrease is left in floating point (predicted decrease ≤ 0, or Δ below round-off of x). "stalled" is not
/// converged: the gradient target was not met, whatever the paper's criterion would say.
class TrustRegion final : public NonlinearSolver {
 public:
  /// An empty name is "tr-dogleg" or "tr-stcg", after params.qp.
  explicit TrustRegion(TrustRegionParams params = {}, std::string name = "");
  std::string name() const override { return m_name; }
  /// Report counters: accepted, rejected, hessian_assemblies, gradient_assemblies, energy_evaluations, qp_calls,
  /// cg_iterations, factorizations, cholmod_fallbacks, final_radius.
  SolveReport minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) override;
  /// Iterations of the last minimize().
  const std::vector<TrIteration>& history() const { return m_core.history(); }
  /// The dogleg's last shift (LocalTrustRegion::dogleg_shift).
  std::string carried_state() const override;
  void restore_carried_state(std::string_view state) override;

 private:
  std::string m_name;
  LocalTrustRegion m_core;
};

}  // namespace mgcloth::solvers
