#pragma once
#include <mgcloth/linalg/block_matrix.hpp>

namespace mgcloth::linalg {

/// Multi-color block Gauss-Seidel for A x = b with 3x3 diagonal blocks inverted exactly. A symmetric sweep relaxes
/// the colors forward then backward, so K sweeps from x = 0 apply a symmetric positive definite operator to b
/// when A is SPD (Wang 2018, Theorem 4.1) — what makes smoothed corrections descent directions. Rows within a
/// color are independent and run in parallel. The coloring is computed once per pattern; set_matrix() per new
/// values.
class MultiColorGaussSeidel {
 public:
  MultiColorGaussSeidel() = default;
  explicit MultiColorGaussSeidel(const BlockMatrix3& pattern);

  /// Takes new values: inverts the diagonal blocks (and colors the rows again when the pattern is not the one
  /// colored before). Throws SolveError for a singular block.
  void set_matrix(const BlockMatrix3& A);
  /// `sweeps` symmetric sweeps on x. With a mask, rows whose mask entry is 0 are skipped (adaptive smoothing hook).
  void symmetric_sweeps(const VecX& b, VecX& x, int sweeps, const std::vector<char>* mask = nullptr) const;
  /// One forward-ordered pass over the colors (or backward).
  void sweep(const VecX& b, VecX& x, bool forward, const std::vector<char>* mask = nullptr) const;

  const std::vector<std::vector<Index>>& colors() const { return m_colors; }

 private:
  void relax_row(Index r, const VecX& b, VecX& x) const;

  const BlockMatrix3* m_A = nullptr;
  std::vector<std::vector<Index>> m_colors;
  std::vector<Index> m_offsets, m_cols;  ///< the pattern m_colors belong to
  std::vector<Mat3> m_inv_diag;
};

/// The adaptive-smoothing mask (Wang 2018 §4.3): mask[i] = 1 where the residual of block row i has norm >=
/// threshold, else 0 (the row is skipped by the sweeps). Returns the number of active rows.
Index adaptive_mask(const VecX& residual, double threshold, std::vector<char>& mask);

}  // namespace mgcloth::linalg
