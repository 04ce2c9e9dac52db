#pragma once
#include <mgcloth/linalg/trust_region_qp.hpp>

namespace mgcloth::linalg {

/// The trust-region subproblem min_s gᵀs + ½ sᵀHs subject to ‖s‖_M ≤ Δ, solved exactly for small problems (the
/// coarsest level of a multilevel hierarchy) through one dense generalized eigen-decomposition H V = M V Λ, VᵀMV = I,
/// per Hessian. The solution is the Moré-Sorensen characterization (Nocedal-Wright Thm. 4.1): (H + σM) s = −g with
/// H + σM ⪰ 0 and σ(Δ − ‖s‖_M) = 0, including the hard case. Unlike the dogleg, whose Newton point of an indefinite
/// H is that of the shifted H + λI (short steps in saddle regions), it moves a full radius along negative curvature,
/// which is what a cloth whose Hessian is indefinite at most iterates (buckling, folds) needs.
class ExactTrustRegion {
 public:
  /// Decomposes H (dense, O(n³)); M from the metric (ℓ2 when null). Throws mgcloth::Error beyond max_dofs.
  void prepare(const BlockMatrix3& H, const VecX& g, const NormMetric* metric = nullptr);
  /// The exact step for radius Δ in O(n²) (no new decomposition): `reason` is Converged for the interior Newton step
  /// of a positive definite H, Boundary otherwise.
  QpResult step(double delta) const;
  static constexpr Index max_dofs = 6000;

 private:
  MatX m_V;       ///< M-orthonormal eigenvectors
  VecX m_lambda;  ///< ascending eigenvalues
  VecX m_a;       ///< Vᵀ g: the gradient in the eigenbasis
};

}  // namespace mgcloth::linalg
