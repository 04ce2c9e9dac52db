#pragma once
#include <mgcloth/hierarchy/transfer.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/linalg/galerkin.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>

#include <functional>

namespace mgcloth::solvers {

struct MultigridParams {
  int pre_smooth = 2;   ///< symmetric Gauss-Seidel sweeps before the coarse correction
  int post_smooth = 2;  ///< and after; equal counts keep the V-cycle symmetric (usable inside PCG)
};

/// Linear geometric multigrid for the 3x3-block systems of Newton's method (Wang 2018 §3.1, Fig. 2a): Galerkin
/// coarse operators A_{l+1} = P_lᵀ A_l P_l, multi-color symmetric Gauss-Seidel smoothing, CHOLMOD on the
/// coarsest level. Patterns, colorings, Galerkin maps and the coarse symbolic analysis are built once.
class LinearMultigrid {
 public:
  /// `prolongations[l]` maps level l+1 to level l; `fine_pattern` is the pattern of the level-0 matrices.
  LinearMultigrid(std::vector<const hierarchy::TransferTable*> prolongations, const linalg::BlockMatrix3& fine_pattern,
                  MultigridParams params = {});

  /// New level-0 values: recomputes the coarse operators, smoother diagonals and the coarsest factorization.
  void set_matrix(const linalg::BlockMatrix3& A);
  /// One V-cycle for A x = b, improving x in place.
  void vcycle(const VecX& b, VecX& x) const;
  /// z = M⁻¹ r: one V-cycle from zero (a symmetric positive definite operator when pre = post smoothing).
  void precondition(const VecX& r, VecX& z) const;
  Index num_levels() const { return static_cast<Index>(m_levels.size()); }
  const linalg::BlockMatrix3& matrix(Index l) const;

 private:
  void cycle(Index l, const VecX& b, VecX& x) const;

  struct Level {
    linalg::BlockMatrix3 A;  ///< levels >= 1 (level 0 points at the caller's matrix)
    linalg::MultiColorGaussSeidel smoother;
    linalg::GalerkinProduct rap;  ///< from this level to the next coarser one
  };
  std::vector<const hierarchy::TransferTable*> m_p;
  std::vector<Level> m_levels;
  const linalg::BlockMatrix3* m_fine = nullptr;
  linalg::CholmodSolver m_coarse_solver;
  MultigridParams m_params;
};

/// Preconditioned conjugate gradients for SPD A; returns the iterations used. Stops at |r| <= rel_tol |b|.
int pcg(const linalg::BlockMatrix3& A, const VecX& b, VecX& x, const std::function<void(const VecX&, VecX&)>& precondition,
        double rel_tol, int max_iters);

}  // namespace mgcloth::solvers
