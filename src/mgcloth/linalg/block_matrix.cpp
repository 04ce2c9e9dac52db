#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/linalg/block_matrix.hpp>

#include <algorithm>

namespace mgcloth::linalg {

BlockMatrix3::BlockMatrix3(Index n, std::vector<std::pair<Index, Index>> pairs) : m_n(n) {
  // Rows bucketed by counting, then each short row sorted, instead of one sort of all the pairs: the row sorts are
  // short, and contact rebuilds patterns during a solve (a profile of a contact run showed the global sort at 8%).
  m_offsets.assign(n + 2, 0);
  for (const auto& [r, c] : pairs) {
    if (r < 0 || c < 0 || r >= n || c >= n) throw_error("BlockMatrix3: block ({}, {}) outside {} rows", r, c, n);
    ++m_offsets[r + 2];
    if (r != c) ++m_offsets[c + 2];
  }
  for (Index i = 0; i < n; ++i) ++m_offsets[i + 2];  // the diagonal
  for (Index i = 0; i < n; ++i) m_offsets[i + 2] += m_offsets[i + 1];
  std::vector<Index> cols(static_cast<size_t>(m_offsets[n + 1]));
  const auto put = [&](Index r, Index c) { cols[static_cast<size_t>(m_offsets[r + 1]++)] = c; };
  for (const auto& [r, c] : pairs) {
    put(r, c);
    if (r != c) put(c, r);
  }
  for (Index i = 0; i < n; ++i) put(i, i);
  // m_offsets[i + 1] is now the end of row i (and m_offsets[i] its start).
  std::vector<std::pair<Index, Index>>().swap(pairs);
  m_cols.clear();
  m_cols.reserve(cols.size());
  std::vector<Index> offsets(static_cast<size_t>(n) + 1, 0);
  for (Index i = 0; i < n; ++i) {
    const auto begin = cols.begin() + m_offsets[i], end = cols.begin() + m_offsets[i + 1];
    std::sort(begin, end);
    m_cols.insert(m_cols.end(), begin, std::unique(begin, end));
    offsets[static_cast<size_t>(i) + 1] = static_cast<Index>(m_cols.size());
  }
  m_offsets = std::move(offsets);
  m_diag.resize(n);
  for (Index i = 0; i < n; ++i) m_diag[i] = find(i, i);
  m_values.assign(m_cols.size(), Mat3::Zero());
}

BlockMatrix3 BlockMatrix3::from_rows(Index n, std::vector<Index> offsets, std::vector<Index> cols) {
  if (n < 0 || static_cast<Index>(offsets.size()) != n + 1 || offsets[0] != 0 ||
      offsets[n] != static_cast<Index>(cols.size()))
    throw_error("BlockMatrix3: {} row offsets for {} rows and {} blocks", offsets.size(), n, cols.size());
  BlockMatrix3 out;
  out.m_n = n;
  out.m_offsets = std::move(offsets);
  out.m_cols = std::move(cols);
  out.m_diag.resize(n);
  for (Index i = 0; i < n; ++i) {
    const Index b = out.m_offsets[i], e = out.m_offsets[i + 1];
    if (e < b) throw_error("BlockMatrix3: row {} has negative length", i);
    for (Index k = b; k < e; ++k)
      if (out.m_cols[k] < 0 || out.m_cols[k] >= n || (k > b && out.m_cols[k] <= out.m_cols[k - 1]))
        throw_error("BlockMatrix3: row {} is not sorted, unique and within {} columns", i, n);
    out.m_diag[i] = out.find(i, i);
    if (out.m_diag[i] < 0) throw_error("BlockMatrix3: row {} lacks its diagonal block", i);
  }
  out.m_values.assign(out.m_cols.size(), Mat3::Zero());
  return out;
}

Index BlockMatrix3::find(Index r, Index c) const {
  const auto begin = m_cols.begin() + m_offsets[r];
  const auto end = m_cols.begin() + m_offsets[r + 1];
  const auto it = std::lower_bound(begin, end, c);
  return (it != end && *it == c) ? static_cast<Index>(it - m_cols.begin()) : -1;
}

void BlockMatrix3::set_zero() {
  parallel_for(num_blocks(), [&](Index k) { m_values[k].setZero(); }, 4096);
}

void BlockMatrix3::multiply(const VecX& x, VecX& y) const {
  y.resize(3 * m_n);
  parallel_for(m_n, [&](Index r) {
    Vec3 s = Vec3::Zero();
    for (Index k = m_offsets[r]; k < m_offsets[r + 1]; ++k) s.noalias() += m_values[k] * x.segment<3>(3 * m_cols[k]);
    y.segment<3>(3 * r) = s;
  });
}

VecX BlockMatrix3::operator*(const VecX& x) const {
  VecX y;
  multiply(x, y);
  return y;
}

Eigen::SparseMatrix<double, Eigen::RowMajor> BlockMatrix3::to_sparse() const {
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(9 * m_cols.size());
  for (Index r = 0; r < m_n; ++r)
    for (Index k = m_offsets[r]; k < m_offsets[r + 1]; ++k)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) t.emplace_back(3 * r + a, 3 * m_cols[k] + b, m_values[k](a, b));
  Eigen::SparseMatrix<double, Eigen::RowMajor> s(3 * m_n, 3 * m_n);
  s.setFromTriplets(t.begin(), t.end());
  return s;
}

bool BlockMatrix3::same_pattern(const BlockMatrix3& o) const {
  return m_n == o.m_n && m_offsets == o.m_offsets && m_cols == o.m_cols;
}

}  // namespace mgcloth::linalg
