#pragma once
#include <mgcloth/linalg/block_matrix.hpp>

namespace mgcloth::linalg {

/// Greedy distance-1 coloring of the block graph of A (rows sharing a stored block get different colors), in
/// row order, so it is deterministic. Rows of one color can be relaxed in parallel by Gauss-Seidel (Wang 2018
/// §3.1, after Fratarcangeli et al. 2016). Computed once per pattern.
std::vector<std::vector<Index>> color_rows(const BlockMatrix3& A);

}  // namespace mgcloth::linalg
