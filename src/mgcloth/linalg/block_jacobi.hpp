#pragma once
#include <mgcloth/linalg/block_matrix.hpp>

namespace mgcloth::linalg {

/// Block-Jacobi preconditioner M = blockdiag(A_ii): each vertex's 3x3 diagonal block inverted exactly, so the
/// xyz coupling of a vertex (anisotropic membrane stiffness) is kept. The cheapest SPD preconditioner for PCG and
/// the baseline the multilevel ones are measured against.
class BlockJacobi {
 public:
  BlockJacobi() = default;
  explicit BlockJacobi(const BlockMatrix3& A) { set_matrix(A); }

  /// Inverts every diagonal block (parallel). Throws SolveError naming the first block row whose diagonal block is
  /// not symmetric positive definite (M would not be SPD and PCG would break down).
  void set_matrix(const BlockMatrix3& A);
  /// z = M⁻¹ r, parallel over block rows.
  void apply(const VecX& r, VecX& z) const;
  Index rows() const { return static_cast<Index>(m_inv.size()); }

 private:
  std::vector<Mat3> m_inv;
};

}  // namespace mgcloth::linalg
