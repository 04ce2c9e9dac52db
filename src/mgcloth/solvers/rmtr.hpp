#pragma once
#include <mgcloth/linalg/trust_region_qp.hpp>
#include <mgcloth/solvers/trust_region.hpp>

#include <memory>
#include <string>
#include <vector>

namespace mgcloth::solvers {

/// RMTR settings (Kopaničáková 2019, Alg. 4.2-4.3, Table 2, §7.3-7.4).
struct RmtrParams {
  /// η1, η2, γ1, γ2, Δ₀ (Table 2) and the stopping rules of (7.1), shared by every level; `qp` is ignored (the
  /// smoother and coarse QP solvers below are used).
  TrustRegionParams tr;
  int pre_smoothing = 1;   ///< μ1: Local_TR iterations before the coarse correction
  int post_smoothing = 1;  ///< μ2: after it
  /// Local_TR iterations on the coarsest level per cycle; 0: μ1 + μ2 (Alg. 4.2 run on l = 0 literally).
  int coarsest_iters = 0;
  double eps_delta = 1e-3;      ///< ε^Δ of Alg. 4.3
  int smoother_cg_iters = 10;   ///< ST-CG iterations per smoothing step on all levels but the coarsest (§7.3)
  TrQp smoother_qp = TrQp::SteihaugCg;
  TrQp coarsest_qp = TrQp::Dogleg;  ///< dogleg with a sparse direct solve on the coarsest level (§7.3)
  /// Levels used, finest first; 0: every level the problem provides.
  int levels = 0;
  /// Projection of iterates: "reverse_subdivision" (the discretization's own operator: Q of §5.3.2, or injection
  /// on nested triangle meshes) or "least_squares" (eq. 5.18).
  std::string projection = "reverse_subdivision";
  /// Coarse trust regions in the level-dependent norm of eq. 4.9, ‖s‖_l = ‖I s‖₂ with I the prolongation to the
  /// finest level, so that a prolongated correction never leaves the fine trust region (eq. 4.7). false: each
  /// level's ℓ2 norm (for comparison only; (4.7) is then not guaranteed).
  bool level_norms = true;
  /// Scaling of the finest level (beyond the paper): "none" (ℓ2, as in the paper) or "jacobi" (a diagonal scaling
  /// D from the Hessian at the start of each solve: Jacobi-preconditioned ST-CG smoothing and the trust region
  /// ‖s‖_D ≤ Δ; the coarse norms follow as Iᵀ D I).
  std::string scaling = "none";
  /// Coarse models: "first_order" (eq. 4.3, the paper) or "second_order" (beyond the paper: also the curvature
  /// term ½ (x − x₀)ᵀ (Sᵀ H S − ∇²f_l(x₀)) (x − x₀), so the coarse Hessian at x₀ is the Galerkin product of the fine
  /// one; costs one more Hessian assembly per level and visit).
  std::string coarse_model = "first_order";
  /// Gradient tolerance ε_g^l of the coarse levels (Alg. 4.2, line 13), absolute; 0: the finest level's target.
  double coarse_abs_grad = 0.0;
  /// Where the V-cycles start (beyond the paper): "fine" (the given iterate, as in the paper) or "nested" (nested
  /// iteration, the F-cycle start of full multigrid: the coarsest level's own problem is solved by Local_TR, its
  /// solution prolongated as a correction to the next level, whose problem is solved by RMTR V-cycles on the levels
  /// below it, and so on up to the finest). Large motions are then found where a step costs 4^-l of a fine one.
  std::string initial = "fine";
  /// Nested iteration: each coarse level above the coarsest is solved to ‖∇f_l‖ ≤ nested_rel_grad · ‖∇f_l(start)‖
  /// (the coarsest to the finest level's target) ...
  double nested_rel_grad = 1e-3;
  /// ... or for at most this many V-cycles (Local_TR iterations on the coarsest level: 100 times as many).
  int nested_max_cycles = 200;
  /// ... or once its last 10 V-cycles (1,000 Local_TR iterations on the coarsest level) lowered its energy by at
  /// most nested_energy_tol times the decrease since its start (beyond the paper; 0: off). The stiff boundary
  /// penalty of a deep hierarchy keeps ‖∇f_l‖ large long after the energy has settled, and a nested solution is
  /// only a start.
  double nested_energy_tol = 0.0;
  /// The coarse start x^{l-1}_0 (beyond the paper): "projection" (P x, eq. 4.6) or "best" (P x or the level's own
  /// iterate where its last visit ended, whichever has the lower coarse energy). In large motion P x of a
  /// wrinkled fine state can have a coarse energy of 1e20 J and more (the woven material's exponential stiffening
  /// of the strains the projection introduces), where round-off leaves the coarse model nothing to resolve.
  std::string coarse_start = "projection";
  /// A coarse correction s that (4.11) rejects is retried as x + αs, α = ½, ¼, … at most this many times, and
  /// accepted at the first α with Armijo decrease f(x) − f(x + αs) ≥ η1·α·(−∇fᵀs) (beyond the paper; 0: off, as
  /// in Alg. 4.2). First-order consistency makes s a descent direction of the fine level wherever the coarse model
  /// decreased from its start along it; the coarse model's curvature, not its slope, is what a rediscretized
  /// exponential material gets wrong. The radius still shrinks by the whole step's ρ.
  int correction_backtracking = 0;
};

/// Work on one level, accumulated over a solve.
struct RmtrLevelCounters {
  Index dofs = 0;
  int visits = 0;               ///< times the V-cycle entered the level
  int hessian_assemblies = 0;   ///< Q^l of eq. 7.3 (derivatives are assembled once per visit and accepted step)
  int gradient_assemblies = 0;
  int energy_evaluations = 0;
  int qp_calls = 0;
  long cg_iterations = 0;
  int accepted = 0, rejected = 0;  ///< Local_TR steps on the level
  int corrections_accepted = 0;    ///< coarse corrections from the level below accepted by eq. 4.11
  int corrections_rejected = 0;
  int radius_exhausted = 0;        ///< visits that ended because the fine radius was used up (Alg. 4.3)
  int starts_kept = 0;             ///< coarse_start "best": visits that started from the last visit's end state
  int cholmod_fallbacks = 0;       ///< dogleg steps whose Hessian needed a shift H + λI (it was indefinite)
  int projected_models = 0;        ///< "hessian": "hybrid": dogleg steps on the projected Hessian
  int extrapolations = 0;
  int corrections_backtracked = 0; ///< corrections_accepted that were rejected whole and accepted as x + αs, α < 1
  int factorizations = 0;          ///< numeric CHOLMOD factorizations of the dogleg, shifted retries included
};

/// One coarse correction's test (eq. 4.11), for tests and diagnostics.
struct RmtrCorrection {
  int level = 0;                 ///< the level that received the correction (finest = number of levels − 1)
  double coarse_reduction = 0.0; ///< h^{l-1}(P x) − h^{l-1}(x^{l-1})
  double fine_reduction = 0.0;   ///< h^l(x) − h^l(x + s)
  double rho = 0.0;
  double step_norm = 0.0;        ///< ‖s‖ in level l's norm (eq. 4.9)
  double radius = 0.0;           ///< Δ^l the correction had to respect (eq. 4.7)
  bool accepted = false;
  double fraction = 1.0;         ///< α of the accepted x + αs (< 1 after correction_backtracking)
};

/// The recursive multilevel trust-region method (Kopaničáková 2019, Alg. 4.2; Gross-Krause 2009) as V-cycles on a
/// hierarchy of rediscretized objectives: on each level the model h_l of eq. 4.3 (the level's own energy plus the
/// first-order coupling term), Local_TR as pre- and post-smoother (ST-CG with a fixed iteration budget) and on the
/// coarsest level (dogleg with CHOLMOD), corrections prolongated by S and accepted by the multilevel ratio
/// (eq. 4.11), radii that keep every coarse correction inside the fine trust region (Alg. 4.3, eqs. 4.7-4.9).
/// One Stop iteration is one V-cycle; the stopping rules are those of the single-level TR, (7.1), tested on the
/// finest level after each cycle.
///
/// Needs Problem::level_objectives, prolongations and projections (needs_level_objectives()). The levels'
/// Local_TR objects (with their CHOLMOD analyses) and the norm matrices are kept across minimize() calls while the
/// hierarchy stays the same.
class Rmtr final : public NonlinearSolver {
 public:
  explicit Rmtr(RmtrParams params = {}, std::string name = "rmtr");
  ~Rmtr() override;
  std::string name() const override { return m_name; }
  bool needs_hierarchy() const override { return true; }
  bool needs_level_objectives() const override { return true; }
  const RmtrParams& params() const { return m_params; }
  /// Report counters: accepted and rejected coarse corrections, per-level assemblies and QP calls (level0_… is
  /// the finest), and the work units of eq. 7.3 for assemblies (work_assembly) and QP calls (work_qp).
  SolveReport minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) override;

  /// Per level of the last minimize(), finest first.
  const std::vector<RmtrLevelCounters>& level_counters() const { return m_counters; }
  /// Every coarse correction of the last minimize(), in order.
  const std::vector<RmtrCorrection>& corrections() const { return m_corrections; }
  /// Finest-level energy after every change of the finest iterate (smoothing steps and accepted corrections).
  const std::vector<double>& finest_energies() const { return m_finest_energies; }
  /// coarse_start "best": each coarse level's kept state, coarsest first (empty otherwise).
  std::vector<VecX> level_states() const override;
  void resume_level_states(std::vector<VecX> states) override { m_resume_states = std::move(states); }
  /// Every level's dogleg shift (LocalTrustRegion::dogleg_shift), coarsest first.
  std::string carried_state() const override;
  void restore_carried_state(std::string_view state) override;
  /// Work units of eq. 7.3 for the last minimize(): Σ_l 2^{-2(L-l)} Q^l, with Q^l Hessian assemblies (assembly) or
  /// QP calls (qp) on level l.
  double work_units_assembly() const;
  double work_units_qp() const;

 private:
  struct Level;
  struct CycleResult {
    double h_start = 0.0, h_end = 0.0;
    bool converged = false;
  };
  void setup(const Problem& problem);
  /// Recomputes the coarse norm matrices from the finest one (and the finest metric when scaled).
  void update_norms(bool finest_scaled);
  void scale_finest(const VecX& x);
  /// One visit of level l (Alg. 4.2, lines 1-22) from x (updated). l < finest: `restricted` is R ∇h_{l+1} at the
  /// parent's iterate and `parent_radius` its Δ^{l+1}_{μ1}.
  /// `galerkin`: Sᵀ ∇²h_{l+1} S for a second-order coarse model (null: first order, eq. 4.3).
  CycleResult visit(int l, VecX& x, const VecX* restricted, const linalg::BlockMatrix3* galerkin, double parent_radius,
                    const LocalTrControl& base);
  // The steps of a visit, in the order of Alg. 4.2.
  struct Visit;
  /// Line 1: the model h_l (eq. 4.3; the top level's own objective) and its Local_TR control with the radius cap of
  /// Alg. 4.3, lines 3-7.
  void build_model(Visit& v, const VecX* restricted, const linalg::BlockMatrix3* galerkin, double parent_radius,
                   const LocalTrControl& base);
  /// Line 2: μ1 Local_TR iterations (the coarsest level: coarsest_iters).
  LocalTrResult pre_smooth(Visit& v, VecX& x);
  /// Lines 4-12: the coarse correction (visiting level l − 1) tested by eq. 4.11 and the radius update; whether x
  /// moved.
  bool coarse_correction(Visit& v, VecX& x, const LocalTrControl& base);
  /// x^{l-1}_0: P x (eq. 4.6), or with coarse_start "best" the level's last end point where its energy is lower.
  VecX coarse_start(int l, const VecX& x);
  /// A second-order coarse model's Sᵀ ∇²h_l S for level l − 1 (null for first-order models).
  const linalg::BlockMatrix3* coarse_galerkin(Visit& v, const VecX& x);
  /// The prolongated correction S(xc − xc0) tested by the multilevel ratio (eq. 4.11); accepted, it moves x.
  bool test_correction(Visit& v, VecX& x, const VecX& xc0, const VecX& xc, const CycleResult& rc);
  /// correction_backtracking: a rejected correction retried as x + αs with Armijo decrease.
  void backtrack_correction(Visit& v, const VecX& x, const VecX& s, RmtrCorrection& corr, VecX& trial, double& ft);
  /// Lines 13-17: μ2 Local_TR iterations, whose first test is the termination of line 13.
  CycleResult post_smooth(Visit& v, VecX& x, bool moved);
  /// The top level's bookkeeping after a Local_TR run (energy, stalls, Newton steps) and the finest energies.
  void note_finest(const Visit& v, const LocalTrResult& r);
  void record(const Visit& v, double energy);
  CycleResult finish(Visit& v, bool converged);
  void accumulate();
  /// Nested iteration (params.initial == "nested"): improves the finest iterate x by solving every coarser level's
  /// problem in turn, coarsest first.
  void nested_start(VecX& x, const LocalTrControl& base);

  RmtrParams m_params;
  std::string m_name;
  std::vector<std::unique_ptr<Level>> m_levels;  ///< coarsest first
  std::vector<const void*> m_key;                ///< the problem's operators the levels were built for
  double m_radius = 0.0;                         ///< Δ of the top level, carried across cycles
  int m_top = 0;  ///< the level the V-cycles solve: the finest, or a coarser one during nested iteration
  /// The finest iterate's energy and gradient where the next finest Local_TR run starts (null: unknown).
  double m_finest_energy = 0.0;
  const VecX* m_start_gradient = nullptr;
  VecX m_start;
  linalg::BlockMatrix3 m_scaling_hessian;
  bool m_finest_stalled = false;  ///< a finest Local_TR run of the current cycle stopped as "stalled"
  bool m_finest_newton = false;   ///< the current cycle's last finest smoothing step was a Newton step
  bool m_finest_stagnated = false;  ///< a finest smoothing run of the current cycle reached the limiting accuracy
  std::vector<RmtrLevelCounters> m_counters;
  std::vector<RmtrCorrection> m_corrections;
  std::vector<double> m_finest_energies;
  std::vector<int> m_nested_cycles;  ///< V-cycles (coarsest: Local_TR iterations) per level of nested iteration
  std::vector<VecX> m_resume_states;  ///< resume_level_states() for the next minimize()
  std::vector<double> m_restore_shifts;  ///< restore_carried_state() for the next minimize()
};

}  // namespace mgcloth::solvers
