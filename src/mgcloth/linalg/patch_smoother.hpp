#pragma once
#include <mgcloth/linalg/block_matrix.hpp>

#include <vector>

namespace mgcloth::linalg {

/// Multiplicative overlapping Schwarz (patch) smoothing for A x = b: each patch (a small set of points, e.g. a
/// control point and its one-ring) is solved exactly in turn, x_p += A_pp⁻¹ (b − A x)_p. Unlike point Gauss-Seidel
/// it resolves the locally coupled modes of a patch together — for thin shells the nearly inextensional bending
/// modes, which are 10⁻⁴ as stiff as membrane modes of the same scale and which point smoothers leave untouched.
/// A patch matrix that is not positive definite is replaced by its eigen-decomposition with |λ| (floored), so a
/// sweep stays a descent-like correction on indefinite Hessians.
class PatchSmoother {
 public:
  PatchSmoother() = default;
  /// `patches`: sorted point lists; every point should lie in at least one patch.
  explicit PatchSmoother(std::vector<std::vector<Index>> patches);

  /// Factorizes every patch matrix of A (same pattern for all calls).
  void set_matrix(const BlockMatrix3& A);
  /// `sweeps` symmetric sweeps (patches forward, then backward) on x.
  void symmetric_sweeps(const VecX& b, VecX& x, int sweeps) const;
  Index num_patches() const { return static_cast<Index>(m_patches.size()); }

 private:
  void relax(size_t p, const VecX& b, VecX& x) const;

  std::vector<std::vector<Index>> m_patches;
  std::vector<MatX> m_inverse;  ///< A_pp⁻¹ (or its |λ| version), dense 3p × 3p
  const BlockMatrix3* m_A = nullptr;
};

}  // namespace mgcloth::linalg
