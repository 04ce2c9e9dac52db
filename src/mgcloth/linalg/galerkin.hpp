#pragma once
#include <mgcloth/linalg/block_matrix.hpp>
#include <mgcloth/linalg/stencil_table.hpp>

namespace mgcloth::linalg {

/// Galerkin coarse operator A_c = (P ⊗ I₃)ᵀ A (P ⊗ I₃) for a 3x3-block matrix A and a scalar interpolation P given
/// as CSR rows (fine vertex → coarse vertices and weights) — Wang 2018 §3.1: A_{h+1} = (I_{h+1}^h)ᵀ A_h I_{h+1}^h.
/// The symbolic part (coarse pattern, and for every coarse block the list of fine blocks and weight products that
/// sum into it) depends only on the patterns, so it is built once; compute() is then one parallel gather per
/// coarse block, without atomics, and bitwise deterministic.
class GalerkinProduct {
 public:
  GalerkinProduct() = default;
  GalerkinProduct(const BlockMatrix3& fine_pattern, Index num_coarse, const std::vector<Index>& p_offsets,
                  const std::vector<Index>& p_indices, const std::vector<double>& p_weights);
  /// P a prolongation: rows the fine vertices, columns the coarse ones.
  GalerkinProduct(const BlockMatrix3& fine_pattern, const StencilTable& P)
      : GalerkinProduct(fine_pattern, P.num_cols, P.offsets, P.indices, P.weights) {}

  /// Fills coarse (which gets the coarse pattern on first use) from A, which must have the fine pattern.
  void compute(const BlockMatrix3& A, BlockMatrix3& coarse) const;
  const BlockMatrix3& coarse_pattern() const { return m_coarse; }
  /// Number of (fine block, weight) terms summed over all coarse blocks: the numeric pass's work.
  Index num_terms() const { return static_cast<Index>(m_terms.size()); }
  /// The symbolic map: coarse block k = Σ_{t ∈ [term_offsets()[k], term_offsets()[k+1])} weight_t · A[fine_block_t].
  struct Term {
    Index fine_block;
    double weight;
  };
  const std::vector<Index>& term_offsets() const { return m_offsets; }
  const std::vector<Term>& terms() const { return m_terms; }

 private:
  BlockMatrix3 m_coarse;
  std::vector<Index> m_offsets;  ///< per coarse block: its terms
  std::vector<Term> m_terms;
  Index m_fine_blocks = 0;
};

}  // namespace mgcloth::linalg
