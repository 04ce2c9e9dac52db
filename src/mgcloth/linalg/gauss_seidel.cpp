#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/linalg/coloring.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>

#include <Eigen/LU>

namespace mgcloth::linalg {

MultiColorGaussSeidel::MultiColorGaussSeidel(const BlockMatrix3& pattern)
    : m_colors(color_rows(pattern)), m_offsets(pattern.row_offsets()), m_cols(pattern.col_indices()) {}

void MultiColorGaussSeidel::set_matrix(const BlockMatrix3& A) {
  m_A = &A;
  if (A.row_offsets() != m_offsets || A.col_indices() != m_cols) {
    m_colors = A.rows() > 0 ? color_rows(A) : std::vector<std::vector<Index>>{};
    m_offsets = A.row_offsets();
    m_cols = A.col_indices();
  }
  m_inv_diag.resize(A.rows());
  bool singular = false;
  parallel_for(A.rows(), [&](Index r) {
    bool ok = false;
    A.block(A.diagonal(r)).computeInverseWithCheck(m_inv_diag[r], ok);
    if (!ok) singular = true;
  });
  if (singular) throw SolveError("Gauss-Seidel: a 3x3 diagonal block is singular");
}

void MultiColorGaussSeidel::relax_row(Index r, const VecX& b, VecX& x) const {
  const auto& off = m_A->row_offsets();
  const auto& cols = m_A->col_indices();
  Vec3 s = b.segment<3>(3 * r);
  for (Index k = off[r]; k < off[r + 1]; ++k) {
    const Index c = cols[k];
    if (c != r) s.noalias() -= m_A->block(k) * x.segment<3>(3 * c);
  }
  x.segment<3>(3 * r) = m_inv_diag[r] * s;
}

void MultiColorGaussSeidel::sweep(const VecX& b, VecX& x, bool forward, const std::vector<char>* mask) const {
  const Index nc = static_cast<Index>(m_colors.size());
  for (Index i = 0; i < nc; ++i) {
    const auto& rows = m_colors[forward ? i : nc - 1 - i];
    parallel_for(static_cast<Index>(rows.size()), [&](Index k) {
      const Index r = rows[k];
      if (!mask || (*mask)[r]) relax_row(r, b, x);
    });
  }
}

void MultiColorGaussSeidel::symmetric_sweeps(const VecX& b, VecX& x, int sweeps, const std::vector<char>* mask) const {
  if (!m_A) throw Error("Gauss-Seidel used before set_matrix()");
  for (int s = 0; s < sweeps; ++s) {
    sweep(b, x, true, mask);
    sweep(b, x, false, mask);
  }
}

Index adaptive_mask(const VecX& residual, double threshold, std::vector<char>& mask) {
  const Index n = static_cast<Index>(residual.size() / 3);
  mask.resize(n);
  const double t2 = threshold * threshold;
  Index active = 0;
  for (Index i = 0; i < n; ++i) {
    mask[i] = residual.segment<3>(3 * i).squaredNorm() >= t2;
    active += mask[i];
  }
  return active;
}

}  // namespace mgcloth::linalg
