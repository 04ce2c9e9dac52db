#pragma once
#include <mgcloth/core/types.hpp>

#include <vector>

namespace mgcloth::hierarchy {

/// Interpolation between two nested levels as a scalar CSR table (OpenSubdiv-style stencils): row i (a fine
/// vertex) lists the coarse vertices it interpolates from and their weights. The same scalar weights apply to
/// each of x, y and z of a vertex, so the 3N x 3M operator is P (x) I_3.
/// Wang 2018, eq. (1): x_fine_i = sum_j w_ij x_coarse_j, with w the barycentric weights of the coarse triangle
/// containing fine vertex i in material space (weight 1 where the fine vertex is itself a coarse vertex).
struct TransferTable {
  Index num_fine = 0;
  Index num_coarse = 0;
  std::vector<Index> offsets;    ///< row i: entries offsets[i] .. offsets[i+1]; size num_fine + 1
  std::vector<Index> indices;    ///< coarse vertex of each entry
  std::vector<double> weights;   ///< weight of each entry
  /// The transposed table (rows = coarse vertices), filled by build_transpose(); used by apply_transpose().
  std::vector<Index> t_offsets;
  std::vector<Index> t_indices;
  std::vector<double> t_weights;

  Index num_entries() const { return static_cast<Index>(indices.size()); }
  /// Fills t_offsets/t_indices/t_weights from the rows; call once after the rows are set.
  void build_transpose();
  /// Prolongation: fine3 = (P (x) I_3) coarse3; coarse3 has 3 * num_coarse entries (xyz interleaved).
  void apply(const VecX& coarse3, VecX& fine3) const;
  /// Restriction: coarse3 = (P (x) I_3)^T fine3; fine3 has 3 * num_fine entries. Needs build_transpose().
  void apply_transpose(const VecX& fine3, VecX& coarse3) const;
};

}  // namespace mgcloth::hierarchy
