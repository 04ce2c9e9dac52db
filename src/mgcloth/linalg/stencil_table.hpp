#pragma once
#include <mgcloth/core/types.hpp>

#include <cstddef>
#include <vector>

namespace mgcloth::linalg {

/// A sparse linear map between two point sets as a scalar CSR table, the same weights applied to x, y and z of a
/// point: the 3R x 3C operator T ⊗ I₃ (OpenSubdiv's stencil tables are the model). Every operator between the levels
/// of a hierarchy is one: prolongation (rows: the fine points, each a combination of coarse points; Wang 2018 eq. 1,
/// Kopaničáková 2019 eq. 5.11), restriction (its transpose) and projection of iterates to a coarser level (rows: the
/// coarse points; reverse subdivision, eq. 5.16). Vectors are xyz interleaved.
struct StencilTable {
  Index num_rows = 0;
  Index num_cols = 0;
  std::vector<Index> offsets;   ///< row i: entries offsets[i] .. offsets[i+1]; size num_rows + 1
  std::vector<Index> indices;   ///< the column (point) of each entry
  std::vector<double> weights;  ///< the weight of each entry
  /// The transposed table (rows = columns of this one), filled by build_transpose(), used by apply_transpose().
  std::vector<Index> t_offsets;
  std::vector<Index> t_indices;
  std::vector<double> t_weights;

  Index num_entries() const { return static_cast<Index>(indices.size()); }
  Index max_row_length() const;
  /// Fills t_offsets/t_indices/t_weights from the rows; call once after the rows are set.
  void build_transpose();
  bool has_transpose() const { return t_offsets.size() == static_cast<std::size_t>(num_cols) + 1; }
  /// out = (T ⊗ I₃) in: `in` has 3 num_cols entries, `out` gets 3 num_rows (a prolongation: coarse → fine).
  void apply(const VecX& in, VecX& out) const;
  /// out = (T ⊗ I₃)ᵀ in: `in` has 3 num_rows entries, `out` gets 3 num_cols (a restriction: fine → coarse). Needs
  /// build_transpose(), so that every output entry is a gather in a fixed order (no atomics, bitwise deterministic).
  void apply_transpose(const VecX& in, VecX& out) const;
  /// Bytes of the CSR arrays (and of the transpose once built).
  std::size_t memory_bytes() const;
};

}  // namespace mgcloth::linalg
