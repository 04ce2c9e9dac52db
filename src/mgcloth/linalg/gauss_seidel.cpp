#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/linalg/coloring.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>

#include <Eigen/LU>

#include <cstring>

namespace mgcloth::linalg {

namespace {
/// Two doubles in one SSE register (GCC and Clang vector extension; a plain pair on other targets).
using Pair = double __attribute__((vector_size(16)));

inline Pair load_pair(const double* v) {
  Pair p;
  std::memcpy(&p, v, sizeof p);
  return p;
}
inline Pair load_pair(const float* v) { return Pair{static_cast<double>(v[0]), static_cast<double>(v[1])}; }

bool is_scalar_block(const Mat3& b) {
  return b(1, 0) == 0.0 && b(2, 0) == 0.0 && b(0, 1) == 0.0 && b(2, 1) == 0.0 && b(0, 2) == 0.0 && b(1, 2) == 0.0 &&
         b(0, 0) == b(1, 1) && b(1, 1) == b(2, 2);
}
}  // namespace

MultiColorGaussSeidel::MultiColorGaussSeidel(const BlockMatrix3& pattern, Precision precision)
    : m_precision(precision),
      m_colors(color_rows(pattern)),
      m_pattern_offsets(pattern.row_offsets()),
      m_pattern_cols(pattern.col_indices()) {
  build_layout();
}

void MultiColorGaussSeidel::build_layout() {
  const Index n = static_cast<Index>(m_pattern_offsets.size()) - 1;
  m_rows.clear();
  m_rows.reserve(static_cast<size_t>(std::max<Index>(0, n)));
  m_color_begin.assign(1, 0);
  for (const auto& color : m_colors) {
    m_rows.insert(m_rows.end(), color.begin(), color.end());
    m_color_begin.push_back(static_cast<Index>(m_rows.size()));
  }
  m_packed_row.assign(m_rows.size(), 0);
  for (size_t i = 0; i < m_rows.size(); ++i) m_packed_row[m_rows[i]] = static_cast<Index>(i);
  m_offsets.assign(m_rows.size() + 1, 0);
  for (size_t i = 0; i < m_rows.size(); ++i) {
    const Index r = m_rows[i];
    m_offsets[i + 1] = m_offsets[i] + (m_pattern_offsets[r + 1] - m_pattern_offsets[r] - 1);
  }
  m_cols.resize(static_cast<size_t>(m_offsets.back()));
  m_full.assign(m_rows.size(), 0);
  m_value_offsets.assign(m_rows.size() + 1, 0);
  m_scalar.assign(m_pattern_cols.size(), 0);
  m_classified = false;
  m_values.clear();
  m_values_single.clear();
  m_inv_diag.resize(m_rows.size());
  m_diag.resize(m_rows.size());
}

void MultiColorGaussSeidel::classify(const BlockMatrix3& A) {
  const auto& off = A.row_offsets();
  const auto& cols = A.col_indices();
  parallel_for(A.rows(), [&](Index r) {
    Index full = 0;
    for (Index k = off[r]; k < off[r + 1]; ++k) {
      if (cols[k] == r) continue;
      m_scalar[k] = is_scalar_block(A.block(k));
      full += !m_scalar[k];
    }
    m_full[m_packed_row[r]] = full;
  });
  for (size_t i = 0; i < m_rows.size(); ++i) {
    const Index blocks = m_offsets[i + 1] - m_offsets[i];
    m_value_offsets[i + 1] = m_value_offsets[i] + 9 * static_cast<size_t>(m_full[i]) + static_cast<size_t>(blocks - m_full[i]);
  }
  // Full blocks' columns first, then the scalars'.
  parallel_for(A.rows(), [&](Index r) {
    const Index i = m_packed_row[r];
    Index f = m_offsets[i], s = m_offsets[i] + m_full[i];
    for (Index k = off[r]; k < off[r + 1]; ++k)
      if (cols[k] != r) m_cols[m_scalar[k] ? s++ : f++] = cols[k];
  });
  const size_t values = m_value_offsets.back();
  if (m_precision == Precision::Single) m_values_single.resize(values);
  else m_values.resize(values);
  m_classified = true;
}

bool MultiColorGaussSeidel::copy_values(const BlockMatrix3& A) {
  const bool single = m_precision == Precision::Single;
  const auto& off = A.row_offsets();
  const auto& cols = A.col_indices();
  bool singular = false, reclassify = false;
  // A is read in its own row order and the rows written to their color-ordered places: reading it in color order
  // would jump between rows, the latency the copy exists to avoid.
  parallel_for(A.rows(), [&](Index r) {
    const Index i = m_packed_row[r];
    size_t f = m_value_offsets[i], s = f + 9 * static_cast<size_t>(m_full[i]);
    for (Index k = off[r]; k < off[r + 1]; ++k) {
      if (cols[k] == r) continue;
      const Mat3& b = A.block(k);
      if (m_scalar[k]) {
        if (!is_scalar_block(b)) reclassify = true;
        if (single) m_values_single[s++] = static_cast<float>(b(0, 0));
        else m_values[s++] = b(0, 0);
      } else {
        const double* v = b.data();
        if (single)
          for (int e = 0; e < 9; ++e) m_values_single[f + e] = static_cast<float>(v[e]);
        else
          for (int e = 0; e < 9; ++e) m_values[f + e] = v[e];
        f += 9;
      }
    }
    // In single precision the diagonal is rounded too, so that the sweeps are exactly Gauss-Seidel on Ã. (Rounded
    // from the source: rounding a copy in place lost its first two entries' rounding under GCC 12 -O3.)
    Mat3 d;
    m_diag[i] = A.block(A.diagonal(r));
    const double* diag = m_diag[i].data();
    for (int e = 0; e < 9; ++e) d.data()[e] = single ? static_cast<double>(static_cast<float>(diag[e])) : diag[e];
    bool ok = false;
    d.computeInverseWithCheck(m_inv_diag[i], ok);
    if (!ok) singular = true;
  });
  if (singular) throw SolveError("Gauss-Seidel: a 3x3 diagonal block is singular");
  return !reclassify;
}

void MultiColorGaussSeidel::set_matrix(const BlockMatrix3& A) {
  if (A.row_offsets() != m_pattern_offsets || A.col_indices() != m_pattern_cols) {
    m_colors = A.rows() > 0 ? color_rows(A) : std::vector<std::vector<Index>>{};
    m_pattern_offsets = A.row_offsets();
    m_pattern_cols = A.col_indices();
    build_layout();
  }
  // The classification of the first values is kept while it holds (a scalar block that stopped being one redoes it;
  // a full block that became scalar just stays full), so that a new matrix usually costs one pass over A.
  if (!m_classified || !copy_values(A)) {
    classify(A);
    if (!copy_values(A)) throw Error("Gauss-Seidel: block classification changed during the copy");
  }
  m_ready = true;
}

double MultiColorGaussSeidel::pass_bytes() const {
  const double value_bytes = m_precision == Precision::Single ? sizeof(float) : sizeof(double);
  const double per_row = 3 * sizeof(Index) + sizeof(size_t) + sizeof(Mat3) + 3 * 3 * sizeof(double);
  return value_bytes * static_cast<double>(m_value_offsets.back()) + sizeof(Index) * static_cast<double>(m_cols.size()) +
         per_row * static_cast<double>(m_rows.size());
}

template <class T>
inline void MultiColorGaussSeidel::offdiagonal_product(const T* values, Index i, const double* xd, double out[3]) const {
  const T* v = values + m_value_offsets[i];
  const Index* c = m_cols.data() + m_offsets[i];
  const Index* full_end = c + m_full[i];
  const Index* row_end = m_cols.data() + m_offsets[i + 1];
  Pair s01 = {0.0, 0.0};
  double s2 = 0.0;
  for (; c != full_end; ++c, v += 9) {  // full blocks, column-major: rows 0-1 of each column as a pair
    const double* xc = xd + 3 * *c;
    const double x0 = xc[0], x1 = xc[1], x2 = xc[2];
    s01 += load_pair(v) * x0 + load_pair(v + 3) * x1 + load_pair(v + 6) * x2;
    s2 += double(v[2]) * x0 + double(v[5]) * x1 + double(v[8]) * x2;
  }
  Pair t01 = {0.0, 0.0};
  double t2 = 0.0;
  for (; c != row_end; ++c, ++v) {  // multiples of the identity
    const double* xc = xd + 3 * *c;
    const double a = double(*v);
    t01 += a * load_pair(xc);
    t2 += a * xc[2];
  }
  s01 += t01;
  s2 += t2;
  out[0] = s01[0];
  out[1] = s01[1];
  out[2] = s2;
}

template <class T>
void MultiColorGaussSeidel::relax_rows(const T* values, Index begin, Index end, const VecX& b, VecX& x,
                                       const std::vector<char>* mask) const {
  double* xd = x.data();
  const double* bd = b.data();
  parallel_for(end - begin, [&](Index j) {
    const Index i = begin + j;
    const Index r = m_rows[i];
    if (mask && !(*mask)[r]) return;
    double t[3];
    offdiagonal_product(values, i, xd, t);
    const double s0 = bd[3 * r] - t[0], s1 = bd[3 * r + 1] - t[1], s2 = bd[3 * r + 2] - t[2];
    const Mat3& D = m_inv_diag[i];
    xd[3 * r] = D(0, 0) * s0 + D(0, 1) * s1 + D(0, 2) * s2;
    xd[3 * r + 1] = D(1, 0) * s0 + D(1, 1) * s1 + D(1, 2) * s2;
    xd[3 * r + 2] = D(2, 0) * s0 + D(2, 1) * s1 + D(2, 2) * s2;
  });
}

void MultiColorGaussSeidel::multiply(const VecX& x, VecX& y) const {
  if (!can_multiply()) throw Error("Gauss-Seidel: multiply needs a double-precision copy of a matrix");
  y.resize(x.size());
  const double* xd = x.data();
  double* yd = y.data();
  parallel_for(static_cast<Index>(m_rows.size()), [&](Index i) {
    const Index r = m_rows[i];
    double t[3];
    offdiagonal_product(m_values.data(), i, xd, t);
    const Vec3 d = m_diag[i] * Vec3(xd[3 * r], xd[3 * r + 1], xd[3 * r + 2]);
    yd[3 * r] = d[0] + t[0];
    yd[3 * r + 1] = d[1] + t[1];
    yd[3 * r + 2] = d[2] + t[2];
  });
}

void MultiColorGaussSeidel::relax_color(Index c, const VecX& b, VecX& x, const std::vector<char>* mask) const {
  if (m_precision == Precision::Single)
    relax_rows(m_values_single.data(), m_color_begin[c], m_color_begin[c + 1], b, x, mask);
  else
    relax_rows(m_values.data(), m_color_begin[c], m_color_begin[c + 1], b, x, mask);
}

void MultiColorGaussSeidel::sweep(const VecX& b, VecX& x, bool forward, const std::vector<char>* mask) const {
  if (!m_ready) throw Error("Gauss-Seidel used before set_matrix()");
  const Index nc = static_cast<Index>(m_colors.size());
  for (Index i = 0; i < nc; ++i) relax_color(forward ? i : nc - 1 - i, b, x, mask);
}

void MultiColorGaussSeidel::symmetric_sweeps(const VecX& b, VecX& x, int sweeps, const std::vector<char>* mask) const {
  if (!m_ready) throw Error("Gauss-Seidel used before set_matrix()");
  // The colors forward, then backward, `sweeps` times. A color relaxed right after itself reproduces the same
  // values bit for bit (its rows read only other colors, unchanged since), so each turn relaxes it once.
  const Index nc = static_cast<Index>(m_colors.size());
  Index last = -1;
  for (int s = 0; s < sweeps; ++s)
    for (Index i = 0; i < 2 * nc; ++i) {
      const Index c = i < nc ? i : 2 * nc - 1 - i;
      if (c != last) relax_color(c, b, x, mask);
      last = c;
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
