#pragma once
#include <mgcloth/linalg/stencil_table.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/linalg/galerkin.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>

#include <functional>

namespace mgcloth::solvers {

struct MultigridParams {
  int pre_smooth = 2;   ///< symmetric Gauss-Seidel sweeps before the coarse correction
  int post_smooth = 2;  ///< and after; equal counts keep the V-cycle symmetric (usable inside PCG)
  /// Chebyshev semi-iterative acceleration of the smoothing sweeps (Wang 2015). The spectral radius of each
  /// level's sweep is estimated on the first matrix and reused for later ones (same mesh, similar spectrum); a
  /// checkpoint keeps them (LinearMultigrid::smoother_rhos).
  bool chebyshev = false;
  /// Factor the coarsest level (CHOLMOD). Off for a smoother-only use of a single level (nonlinear Gauss-Seidel),
  /// which then gets a smoother on its coarsest level instead.
  bool factorize_coarsest = true;
  /// Adaptive smoothing inside the V-cycles (Wang 2018 §4.3): skip vertices whose residual is below this times the
  /// level's RMS residual. 0 = off. Makes the cycle depend on its data, so only for use as a search direction
  /// (with a line search), not as a PCG preconditioner.
  double adaptive_threshold = 0.0;
  /// The smoothers' copies of the level matrices in float (MultiColorGaussSeidel::Precision::Single): half the
  /// bytes per sweep; residuals, transfers and the coarsest solve stay double.
  bool single_precision_smoother = false;
};

/// Linear geometric multigrid for the 3x3-block systems of Newton's method (Wang 2018 §3.1, Fig. 2a): Galerkin
/// coarse operators A_{l+1} = P_lᵀ A_l P_l, multi-color symmetric Gauss-Seidel smoothing, CHOLMOD on the
/// coarsest level. Patterns, colorings, Galerkin maps and the coarse symbolic analysis are built once.
class LinearMultigrid {
 public:
  /// `prolongations[l]` maps level l+1 to level l; `fine_pattern` is the pattern of the level-0 matrices.
  LinearMultigrid(std::vector<const linalg::StencilTable*> prolongations, const linalg::BlockMatrix3& fine_pattern,
                  MultigridParams params = {});

  /// New level-0 values: recomputes the coarse operators, smoother diagonals and the coarsest factorization.
  /// `constant` (per block of A): blocks whose values are the same in every matrix given with the same
  /// `constant_version` (physics::Objective::constant_blocks); the first Galerkin product then sums their share
  /// once per version. The caller must keep the promise: results are wrong otherwise. (The level-0 smoother's copy
  /// reads them anyway: skipping them there was measured no faster, their bytes share cache lines with the rest.)
  void set_matrix(const linalg::BlockMatrix3& A, const std::vector<char>* constant = nullptr, long constant_version = 0);
  /// y = A_l x: from the level's smoother copy where it has one in double precision (fewer bytes), else A_l's.
  void multiply(Index l, const VecX& x, VecX& y) const;
  /// One V-cycle for A x = b, improving x in place.
  void vcycle(const VecX& b, VecX& x) const;
  /// z = M⁻¹ r: one V-cycle from zero (a symmetric positive definite operator when pre = post smoothing).
  void precondition(const VecX& r, VecX& z) const;
  /// Full multigrid (Wang 2018 Fig. 2b): b restricted to every level, solved exactly on the coarsest, then on each
  /// finer level the prolonged solution improved by one V-cycle. Overwrites x; as accurate as a few V-cycles for
  /// the price of about one and a third. Not symmetric, so not a PCG preconditioner.
  void fmg(const VecX& b, VecX& x) const;
  /// Measured asymptotic residual reduction per V-cycle for A x = b from x = 0 (geometric mean over cycles 4 to 10),
  /// the multigrid convergence factor that benchmarks and tests report.
  double contraction(const VecX& b) const;
  /// Level-wise pieces, for the nonlinear FMG (Wang 2018 §4.2), which uses each level's smoothed correction as a
  /// search direction on the finest level.
  /// `sweeps` smoothing iterations on level l (symmetric GS, or Chebyshev-accelerated when enabled); with a mask,
  /// rows whose entry is 0 are skipped (adaptive smoothing, §4.3).
  void smooth(Index l, const VecX& b, VecX& x, int sweeps, const std::vector<char>* mask = nullptr) const;
  /// One V-cycle with level l as the finest (levels l..coarsest); exact solve when l is the coarsest.
  void vcycle(Index l, const VecX& b, VecX& x) const;
  /// x = A_coarsest⁻¹ b.
  void coarse_solve(const VecX& b, VecX& x) const;
  /// Level l+1 → level l, and its transpose.
  void prolong(Index l, const VecX& coarse, VecX& fine) const { m_p[l]->apply(coarse, fine); }
  void restrict_to(Index l, const VecX& fine, VecX& coarse) const { m_p[l]->apply_transpose(fine, coarse); }
  /// Vertices (block rows) of level l.
  Index level_size(Index l) const { return m_sizes[l]; }
  const MultigridParams& params() const { return m_params; }
  /// Adaptive smoothing statistics since the last reset: block-row relaxations done / possible (a symmetric sweep
  /// counts two per row).
  double rows_active() const { return m_rows_active; }
  double rows_total() const { return m_rows_total; }
  void reset_adaptive_stats() const { m_rows_active = m_rows_total = 0.0; }

  /// Spectral radius of each level's symmetric sweep used by Chebyshev smoothing (0 until estimated).
  double smoother_rho(Index l) const { return m_levels[l].rho; }
  /// All of them, finest first, and their restoration (a resumed run smooths with the radii the uninterrupted run
  /// estimated on its first matrix, not with radii of the matrix it resumes at). Throws InputError for another
  /// level count or a value outside [0, 1).
  std::vector<double> smoother_rhos() const;
  void set_smoother_rhos(const std::vector<double>& rhos);
  Index num_levels() const { return static_cast<Index>(m_levels.size()); }
  /// How many times the pattern-dependent part (colorings, Galerkin maps, coarse patterns) was built: once, plus
  /// once for every set_matrix() whose pattern differed from the last one.
  int symbolic_builds() const { return m_symbolic_builds; }
  const linalg::BlockMatrix3& matrix(Index l) const;

 private:
  void cycle(Index l, const VecX& b, VecX& x) const;
  linalg::MultiColorGaussSeidel::Precision smoother_precision() const {
    return m_params.single_precision_smoother ? linalg::MultiColorGaussSeidel::Precision::Single
                                              : linalg::MultiColorGaussSeidel::Precision::Double;
  }
  /// The pattern-dependent part, for this fine pattern.
  void build_symbolic(const linalg::BlockMatrix3& fine_pattern);

  struct Level {
    linalg::BlockMatrix3 A;  ///< levels >= 1 (level 0 points at the caller's matrix)
    linalg::MultiColorGaussSeidel smoother;
    linalg::GalerkinProduct rap;  ///< from this level to the next coarser one
    double rho = 0.0;             ///< Chebyshev: estimated spectral radius of one symmetric sweep
  };
  std::vector<const linalg::StencilTable*> m_p;
  std::vector<Level> m_levels;
  std::vector<Index> m_sizes;
  mutable double m_rows_active = 0.0, m_rows_total = 0.0;
  const linalg::BlockMatrix3* m_fine = nullptr;
  std::vector<Index> m_fine_offsets, m_fine_cols;  ///< the fine pattern the symbolic part was built for
  int m_symbolic_builds = 0;
  long m_constant_version = -1;  ///< the version whose constant blocks level 0's Galerkin product has summed
  linalg::CholmodSolver m_coarse_solver;
  MultigridParams m_params;
};

}  // namespace mgcloth::solvers
