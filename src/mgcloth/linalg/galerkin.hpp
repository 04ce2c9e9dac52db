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
  /// Fine blocks whose values stay fixed from one matrix to the next (`constant`, per fine block; the quadratic
  /// bending model's couplings beyond the one-ring). Their share of each coarse block is summed once, by
  /// compute_constant(), and compute() then reads only the other fine blocks: a quarter of a cloth matrix's. A
  /// pattern's coarse blocks sum their terms in another order this way, so results differ from compute()'s without
  /// constant blocks by round-off.
  void set_constant_blocks(const std::vector<char>& constant);
  /// Sums the constant blocks' share from A (call after set_constant_blocks and whenever those values change).
  void compute_constant(const BlockMatrix3& A);
  void clear_constant_blocks();
  bool has_constant_blocks() const { return !m_variable_offsets.empty(); }
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
  // With constant blocks: the terms that read variable fine blocks, in an array of their own (compute() streams the
  // term list, so skipping constant terms inside the full list would still drag their bytes through the caches),
  // and per coarse block the sum of the constant terms.
  std::vector<Index> m_variable_offsets;
  std::vector<Term> m_variable_terms;
  std::vector<char> m_constant_flags;
  std::vector<Mat3> m_constant;
  bool m_constant_ready = false;
};

}  // namespace mgcloth::linalg
