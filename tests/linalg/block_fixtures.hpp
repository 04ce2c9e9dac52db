#pragma once
// Random symmetric block matrices shared by the linear-algebra tests.
#include <mgcloth/linalg/block_matrix.hpp>

#include <random>

namespace mgcloth::linalg {

/// A random symmetric block matrix on a ring-with-chords graph (neighbours i ± 1 and i ± chord): off-diagonal
/// blocks uniform in [-1, 1], diagonal blocks b bᵀ + diagonal·I, so a large `diagonal` makes it SPD and a small
/// or negative one indefinite.
inline BlockMatrix3 random_ring_matrix(Index n, std::uint64_t seed, Index chord, double diagonal) {
  std::vector<std::pair<Index, Index>> pairs;
  for (Index i = 0; i < n; ++i) {
    pairs.emplace_back(i, (i + 1) % n);
    pairs.emplace_back(i, (i + chord) % n);
  }
  BlockMatrix3 A(n, pairs);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  for (Index r = 0; r < n; ++r)
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k) {
      const Index c = A.col_indices()[k];
      if (c < r) continue;
      Mat3 b;
      for (int i = 0; i < 9; ++i) b.data()[i] = u(rng);
      if (c == r) b = b * b.transpose() + diagonal * Mat3::Identity();
      A.block(k) = b;
      A.block(A.find(c, r)) = b.transpose();
    }
  return A;
}

}  // namespace mgcloth::linalg
