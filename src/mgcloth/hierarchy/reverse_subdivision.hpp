#pragma once
#include <mgcloth/hierarchy/subdivision_hierarchy.hpp>

#include <array>
#include <cstddef>
#include <memory>
#include <vector>

namespace mgcloth::hierarchy {

/// Which rule reconstructed a coarse point in reverse_subdivision() (Kopaničáková 2019, §5.3.2 and App. A-C).
enum class ReverseRule : int {
  kOrdinary,       ///< interior, valence 4: eq. (5.19) with (5.21)
  kExtraordinary,  ///< interior, valence other than 3 and 4: eq. (5.19) with (5.21)
  kValence3,       ///< interior, valence 3: the edge-point rule (B.2) with a reconstructed neighbour (App. C)
  kBoundary,       ///< on a boundary with its fine neighbours kept: the cubic B-spline rule (A.2) reversed
  kCorner,         ///< the same on a boundary point of one face (valence 2)
  kGhost,          ///< without its fine one-ring (ghost layer dropped): the edge-point rule (B.2)
  kCornerGhost,    ///< the face-point rule (B.4) when no edge rule applies
  kCount
};
using ReverseRuleCounts = std::array<Index, static_cast<std::size_t>(ReverseRule::kCount)>;

/// Q of Kopaničáková 2019 §5.3.2: Q S = I on the hierarchy step `step` made from `coarse` by subdivide(), so that
/// projecting a prolongated iterate gives it back (eq. 5.16). Every row sums to one (Q is affine).
/// Interior points of valence != 3 whose fine one-ring was kept use eq. (5.19) with the coefficients (5.21); points
/// on the boundary of a mesh without ghost layer reverse the boundary rules (A.1), (A.2):
/// v = 2 v' - (e'_a + e'_b) / 2 with e'_a, e'_b the fine midpoints of its two boundary edges (corners included,
/// since subdivide() smooths them by (A.2) too). The other points are reconstructed in waves from points already
/// reconstructed: through an interior edge (v, w) by (B.2), v = 4 e' - w - f'_1 - f'_2 (App. C for valence 3, App. B
/// for ghost points), else through a face by (B.4), v = 4 f' - (its other three corners); each reconstructed
/// neighbour's row is substituted, so a row is a combination of fine points only. Among the candidates of a wave
/// the shortest row is taken. Throws Error naming the first coarse point that no rule reaches (e.g. on a closed mesh
/// of valence-3 points only, such as a cube: (5.20) is singular and no neighbour is ever reconstructed); callers
/// fall back to LeastSquaresProjection. `rule_counts`, when given, receives how many coarse points each
/// ReverseRule reconstructed.
linalg::StencilTable reverse_subdivision(const mesh::QuadMesh& coarse, const SubdivisionStep& step,
                                    ReverseRuleCounts* rule_counts = nullptr);

/// The least-squares projection of Kopaničáková 2019, eq. (5.18): P = (SᵀS)⁻¹Sᵀ, the Moore-Penrose pseudo-inverse
/// of the subdivision matrix, by a sparse Cholesky factorization (Eigen's SimplicialLLT, AMD ordering) of the
/// scalar SᵀS, done once. Throws Error when SᵀS is not positive definite (S not injective).
class LeastSquaresProjection {
 public:
  explicit LeastSquaresProjection(const linalg::StencilTable& S);
  ~LeastSquaresProjection();
  LeastSquaresProjection(LeastSquaresProjection&&) noexcept;
  LeastSquaresProjection& operator=(LeastSquaresProjection&&) noexcept;

  Index num_coarse() const { return m_num_coarse; }
  Index num_fine() const { return m_num_fine; }
  /// coarse3 = (P (x) I_3) fine3, xyz interleaved.
  void apply(const VecX& fine3, VecX& coarse3) const;
  /// Nonzeros of the Cholesky factor L (diagonal included).
  Index factor_nonzeros() const;
  /// The factor as stored: values and row indices of L, its column offsets and the fill-reducing permutation
  /// and its inverse. The copy of S kept for Sᵀ is not counted (it is the size of S itself).
  std::size_t memory_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
  Index m_num_coarse = 0, m_num_fine = 0;
};

}  // namespace mgcloth::hierarchy
