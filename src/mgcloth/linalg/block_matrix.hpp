#pragma once
#include <mgcloth/core/types.hpp>

#include <Eigen/SparseCore>
#include <utility>
#include <vector>

namespace mgcloth::linalg {

/// Symmetric matrix of 3x3 blocks in block-CSR form, both triangles stored. The pattern is built once per mesh
/// (from the stencils of the objective's terms) and refilled at every assembly; only the values change.
class BlockMatrix3 {
 public:
  BlockMatrix3() = default;
  /// Pattern over n block rows from (row, col) pairs; symmetric partners and the diagonal are added.
  BlockMatrix3(Index n, std::vector<std::pair<Index, Index>> pairs);
  /// Pattern from block-CSR rows that are already sorted, free of duplicates, hold their diagonal and are
  /// symmetric (the caller's promise; the first three are checked).
  static BlockMatrix3 from_rows(Index n, std::vector<Index> offsets, std::vector<Index> cols);

  Index rows() const { return m_n; }
  Index num_blocks() const { return static_cast<Index>(m_cols.size()); }
  const std::vector<Index>& row_offsets() const { return m_offsets; }
  const std::vector<Index>& col_indices() const { return m_cols; }
  std::vector<Mat3>& blocks() { return m_values; }
  const std::vector<Mat3>& blocks() const { return m_values; }
  Mat3& block(Index k) { return m_values[k]; }
  const Mat3& block(Index k) const { return m_values[k]; }

  /// Position of block (r, c) in blocks(), or -1 when it is not in the pattern.
  Index find(Index r, Index c) const;
  Index diagonal(Index r) const { return m_diag[r]; }

  void set_zero();
  /// y = A x, parallel over block rows.
  void multiply(const VecX& x, VecX& y) const;
  VecX operator*(const VecX& x) const;
  /// Scalar copy for tests and for generic sparse algorithms.
  Eigen::SparseMatrix<double, Eigen::RowMajor> to_sparse() const;
  /// Same pattern (so that maps built against one apply to the other).
  bool same_pattern(const BlockMatrix3& other) const;

 private:
  Index m_n = 0;
  std::vector<Index> m_offsets{0};
  std::vector<Index> m_cols;
  std::vector<Index> m_diag;
  std::vector<Mat3> m_values;
};

}  // namespace mgcloth::linalg
