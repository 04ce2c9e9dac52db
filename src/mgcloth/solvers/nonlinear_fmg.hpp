#pragma once
#include <mgcloth/solvers/fmg_cycle.hpp>
#include <mgcloth/solvers/linear_multigrid.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

#include <cstdint>
#include <memory>
#include <optional>

namespace mgcloth::solvers {

struct FmgParams {
  /// Symmetric Gauss-Seidel sweeps per smoothing (pre_smooth on the way down, post_smooth on the way up), Chebyshev
  /// acceleration of the sweeps, used both for the nonlinear levels and inside the linear sub-V-cycles.
  MultigridParams multigrid{3, 3, true, true};
  MatrixUpdate matrix_update = MatrixUpdate::Cycle;
  /// With `cycle` (or `direction`) updates: a direction whose accepted step is below this fraction of the
  /// quadratic model's step triggers a matrix update before the next direction. 0 = only at cycle starts (§4.2.1).
  double refresh_below = 0.25;
  /// Levels, counted from the finest, on which every smoothed correction is its own search direction and the
  /// nonlinear residual is recomputed on the finest level after it (Wang 2018 §4.2.2, Fig. 7); below them the
  /// rest of each V-cycle runs as linear multigrid and gives one direction (Theorem 4.2). 0: every V-cycle is one
  /// linear direction; >= the number of levels: every level is nonlinear.
  int residual_levels = 0;
  /// Interleave small and large V-cycles (§4.2.1): each FMG cycle runs one V-cycle from every level, coarsest
  /// first. false (default, beyond the paper): one V-cycle from the finest level per cycle, as in Fig. 2a. On the
  /// CPU every direction costs a fine-level line search, gradient and model product whatever level it came from,
  /// and the small V-cycles do not earn theirs: 2x slower to 1e-3 at 10K and 40K (bench/RESULTS.md, Fig. 4).
  bool interleave = false;
  /// Only the single finest level's smoother (no coarse levels): nonlinear multi-color Gauss-Seidel, the
  /// "Gauss-Seidel with Chebyshev acceleration" baseline of Fig. 4 and of Projective Dynamics (Wang 2015,
  /// Fratarcangeli 2016). Then one iteration is one smoothing of pre_smooth sweeps.
  bool single_level = false;
  /// Backtracking line search on the true objective for every direction (§4.2.3); off for Projective Dynamics
  /// (§4.4), where the local step keeps the iteration stable.
  bool line_search = true;
  LineSearchParams line_search_params{.interpolate = true, .refine = 3};
  /// Adaptive smoother (§4.3): a smoothing skips the vertices whose restricted residual is below
  /// adaptive_threshold × the RMS residual of that level. 0 disables (exactly the plain smoother).
  double adaptive_threshold = 0.0;
  /// Chebyshev weights on the successive corrections, x⁺ = ω (x + c − x⁻) + x⁻ (Wang 2015; §4.4 for the FMG);
  /// the spectral-radius estimate ρ of the plain iteration, 0 disables. With a line search, a weighted update that
  /// does not decrease the energy restarts the weights and falls back to the line-searched direction.
  double chebyshev_rho = 0.0;
  int chebyshev_delay = 1;  ///< corrections taken unweighted before the weights start
  /// Minimize the quadratic model over the new direction and the previous step together (a 2D subspace, as a
  /// flexible preconditioned CG would), then line-search that combination. Beyond the paper; off = §4.2.3 exactly.
  bool momentum = true;
  bool project_psd = true;  ///< per-element PSD projection of the Hessian
  bool projective = false;  ///< a PD preset: minimizes the Projective Dynamics form only

  /// The part of these settings that the cycle itself takes (the rest configures the CPU multigrid).
  FmgCycleParams cycle() const {
    return {matrix_update, refresh_below, line_search, line_search_params, chebyshev_rho, chebyshev_delay, momentum};
  }
};

/// Whether an FMG with these settings measures the Newton decrement (NonlinearSolver::estimates_decrement): the
/// Hessian model with a line search (not Projective Dynamics' matrix), and a linear V-cycle from the finest level
/// among its directions (not single-level, not residual levels).
inline bool fmg_estimates_decrement(const FmgParams& p) {
  return !p.single_level && !p.projective && p.line_search && p.residual_levels == 0;
}

/// The nonlinear full multigrid of Wang et al. 2018 (§4.2, Fig. 5). Every smoothed correction on level h,
/// c_h = Ã_h⁻¹ I_0^h r_0, prolonged to the finest level, is a search direction for the finest-level objective:
/// it is scaled by a backtracking line search on E, x is updated, the contact projection applied (§4.5), and the
/// residual r_0 = −∇E recomputed before the next level's smoothing. A_h = I_0^hᵀ A_0 I_0^h are Galerkin operators of
/// one finest-level matrix, updated per matrix_update. Small and large V-cycles are interleaved: each FMG cycle runs
/// one V-cycle starting from every level, coarsest first (§4.2.1). Symmetric (Chebyshev-)Gauss-Seidel keeps every
/// direction a descent direction (Theorems 4.1, 4.2). One iteration = one FMG cycle. The cycle is FmgCycle, shared
/// with the device pipeline ("fmg-cuda"); this class is its CPU backend: LinearMultigrid on BlockMatrix3.
class NonlinearFMG final : public NonlinearSolver {
 public:
  explicit NonlinearFMG(FmgParams params = {}, std::string name = "fmg");
  std::string name() const override { return m_name; }
  /// The Projective Dynamics presets keep one constant matrix per step, which cannot hold a contact barrier whose
  /// stiffness grows without bound: they are refused with cloth contact.
  bool supports_step_limits() const override { return !m_params.projective; }
  bool needs_hierarchy() const override { return !m_params.single_level; }
  bool estimates_step_error() const override { return !m_params.single_level; }
  /// The V-cycle from the finest level is each cycle's direction d = B r, so c·r = rᵀBr is the Newton decrement of
  /// the model with B for A⁻¹ (within a factor 1 − ρ of it for a V-cycle contracting by ρ).
  bool estimates_decrement() const override { return fmg_estimates_decrement(m_params); }
  std::vector<physics::EnergyForm> energy_forms() const override {
    if (m_params.projective) return {physics::EnergyForm::Projective};
    return NonlinearSolver::energy_forms();
  }
  SolveReport minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) override;
  const FmgParams& params() const { return m_params; }
  /// The Chebyshev radii of every level (estimated once, on the run's first matrix), the line search's starting
  /// scales and, with a constant matrix, a hash of it (a later solve refactors only when its matrix differs).
  std::string carried_state() const override;
  void restore_carried_state(std::string_view state) override;

  /// What the last minimize() did (the cycle's counts) and where the multigrid's time went.
  struct Stats : FmgCycle::Counts {
    double rows_relaxed = 0.0;   ///< block-row relaxations done by the smoothers of nonlinear levels
    double rows_skipped = 0.0;   ///< and skipped by the adaptive mask
    double assembly_ms = 0.0, galerkin_ms = 0.0, smoothing_ms = 0.0, linear_ms = 0.0, transfer_ms = 0.0;
  };
  const Stats& stats() const { return m_stats; }

 private:
  class Backend;
  std::vector<FmgStage> schedule(Index levels) const;
  /// Sets up the multigrid for the problem's hierarchy (kept while it is the same) and applies a restored state.
  void prepare(const Problem& problem);

  FmgParams m_params;
  std::string m_name;
  std::unique_ptr<LinearMultigrid> m_mg;
  std::vector<const linalg::StencilTable*> m_mg_for;
  linalg::BlockMatrix3 m_A, m_scratch;
  physics::Objective::ConstantHessian m_constant;  ///< m_A's constant blocks (Objective::hessian_reusing_constant)
  bool m_have_matrix = false;
  std::vector<double> m_beta;  ///< per level: accepted step / model step, to start the next line search (§4.2.3)
  /// restore_carried_state() for the next minimize(), applied once its multigrid exists.
  std::vector<double> m_restore;
  /// After a restore with a constant matrix: the hash of the matrix the writing solver held, which tells whether
  /// the first matrix assembled after the restore is a new one.
  std::optional<std::uint64_t> m_restored_matrix;
  Stats m_stats;
};

}  // namespace mgcloth::solvers
