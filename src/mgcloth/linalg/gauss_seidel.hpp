#pragma once
#include <mgcloth/linalg/block_matrix.hpp>

namespace mgcloth::linalg {

/// Multi-color block Gauss-Seidel for A x = b with 3x3 diagonal blocks inverted exactly. A symmetric sweep relaxes
/// the colors forward then backward, so K sweeps from x = 0 apply a symmetric positive definite operator to b
/// when A is SPD (Wang 2018, Theorem 4.1) — what makes smoothed corrections descent directions. Rows within a
/// color are independent and run in parallel. The coloring is computed once per pattern; set_matrix() per new
/// values.
///
/// set_matrix() copies the off-diagonal blocks into color order (the rows of each color contiguous, the diagonal
/// left out), so that a pass over a color streams its rows instead of jumping between them: the jumps cost a memory
/// latency per row, which made a pass several times slower than a product with A (bench/RESULTS.md, issue 30).
/// With Precision::Single the copy holds floats: the smoother is then the exact symmetric Gauss-Seidel of Ã, A's
/// blocks rounded to float (still symmetric), at half the bytes per pass; x, b and the sums stay in double.
class MultiColorGaussSeidel {
 public:
  enum class Precision { Double, Single };

  MultiColorGaussSeidel() = default;
  explicit MultiColorGaussSeidel(const BlockMatrix3& pattern, Precision precision = Precision::Double);

  /// Takes new values: copies the blocks into color order and inverts the diagonal blocks (and colors the rows
  /// again when the pattern is not the one colored before). Throws SolveError for a singular block.
  void set_matrix(const BlockMatrix3& A);
  /// y = A x for the A of the last set_matrix, from the color-ordered copy (which stores most blocks as one number,
  /// so it moves fewer bytes than BlockMatrix3::multiply). Double precision only: in single precision the copy is
  /// a rounded A. Sums run in another order than BlockMatrix3::multiply's, so the two agree to round-off.
  void multiply(const VecX& x, VecX& y) const;
  bool can_multiply() const { return m_ready && m_precision == Precision::Double; }
  /// `sweeps` symmetric sweeps on x. With a mask, rows whose mask entry is 0 are skipped (adaptive smoothing hook).
  void symmetric_sweeps(const VecX& b, VecX& x, int sweeps, const std::vector<char>* mask = nullptr) const;
  /// One forward-ordered pass over the colors (or backward).
  void sweep(const VecX& b, VecX& x, bool forward, const std::vector<char>* mask = nullptr) const;

  const std::vector<std::vector<Index>>& colors() const { return m_colors; }
  Precision precision() const { return m_precision; }
  /// The bytes one pass over all colors must move at least: the copy's values and columns, the per-row layout and
  /// inverted diagonal, b read, x read and written (neighbours' x counted once, as if cached).
  double pass_bytes() const;

 private:
  /// The color-ordered layout of the current pattern (m_rows, m_color_begin, m_offsets, m_cols).
  void build_layout();
  /// Relaxes the rows of color c.
  void relax_color(Index c, const VecX& b, VecX& x, const std::vector<char>* mask) const;
  template <class T>
  void relax_rows(const T* values, Index begin, Index end, const VecX& b, VecX& x, const std::vector<char>* mask) const;

  /// Which off-diagonal blocks of the current values are multiples of the identity (stored as one number), and the
  /// value layout that follows from it. Returns false where a block classified scalar is no longer one.
  void classify(const BlockMatrix3& A);
  bool copy_values(const BlockMatrix3& A);
  /// Σ over row i's off-diagonal blocks of A_ij x_j (rows 0-1 as a pair, row 2).
  template <class T>
  void offdiagonal_product(const T* values, Index i, const double* x, double out[3]) const;

  bool m_ready = false;
  Precision m_precision = Precision::Double;
  std::vector<std::vector<Index>> m_colors;
  std::vector<Index> m_pattern_offsets, m_pattern_cols;  ///< the pattern m_colors belong to
  // Color-ordered copy: packed row i is row m_rows[i]; color c holds packed rows [m_color_begin[c],
  // m_color_begin[c+1]); its off-diagonal blocks are [m_offsets[i], m_offsets[i+1]) of m_cols, the first m_full[i]
  // of them full 3x3 blocks (9 values each, column-major like Mat3), the rest multiples of the identity (one value
  // each: the quadratic bending model's couplings beyond the membrane's one-ring are k·I₃, three quarters of a
  // cloth Hessian's blocks). Row i's values start at m_value_offsets[i].
  std::vector<Index> m_rows, m_color_begin, m_offsets, m_cols, m_full;
  std::vector<Index> m_packed_row;  ///< inverse of m_rows
  std::vector<size_t> m_value_offsets;
  std::vector<char> m_scalar;  ///< per block of A's pattern: stored as a multiple of the identity
  bool m_classified = false;
  std::vector<double> m_values;
  std::vector<float> m_values_single;
  std::vector<Mat3> m_inv_diag;  ///< per packed row
  std::vector<Mat3> m_diag;      ///< per packed row, as in A (for multiply)
};

/// The adaptive-smoothing mask (Wang 2018 §4.3): mask[i] = 1 where the residual of block row i has norm >=
/// threshold, else 0 (the row is skipped by the sweeps). Returns the number of active rows.
Index adaptive_mask(const VecX& residual, double threshold, std::vector<char>& mask);

}  // namespace mgcloth::linalg
