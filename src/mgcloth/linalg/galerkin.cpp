#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/linalg/galerkin.hpp>

#include <algorithm>

namespace mgcloth::linalg {

GalerkinProduct::GalerkinProduct(const BlockMatrix3& A, Index nc, const std::vector<Index>& po,
                                 const std::vector<Index>& pi, const std::vector<double>& pw)
    : m_fine_blocks(A.num_blocks()) {
  if (static_cast<Index>(po.size()) != A.rows() + 1)
    throw Error(fmt::format("Galerkin: interpolation has {} rows, the matrix {}", po.size() - 1, A.rows()));
  // Row by row with a marker per coarse column, as in a sparse product's symbolic phase: no list of all the terms, no
  // sort of them and no search per term. Contact rebuilds this whenever its stencils change, inside a solve.
  // Pᵀ: per coarse vertex, the fine vertices interpolating from it, ascending (so each block sums in the order of
  // its fine rows, then fine blocks, then interpolation entries).
  std::vector<Index> t_off(static_cast<size_t>(nc) + 1, 0);
  for (Index i = 0; i < A.rows(); ++i)
    for (Index a = po[i]; a < po[i + 1]; ++a) {
      if (pi[a] < 0 || pi[a] >= nc)
        throw Error(fmt::format("Galerkin: fine vertex {} interpolates from coarse vertex {} of {}", i, pi[a], nc));
      if (pw[a] != 0.0) ++t_off[pi[a] + 1];
    }
  for (Index c = 0; c < nc; ++c) t_off[c + 1] += t_off[c];
  std::vector<Index> t_fine(static_cast<size_t>(t_off[nc])), cursor(t_off.begin(), t_off.end() - 1);
  std::vector<double> t_weight(t_fine.size());
  for (Index i = 0; i < A.rows(); ++i)
    for (Index a = po[i]; a < po[i + 1]; ++a)
      if (pw[a] != 0.0) {
        t_fine[cursor[pi[a]]] = i;
        t_weight[cursor[pi[a]]++] = pw[a];
      }
  const auto& off = A.row_offsets();
  const auto& cols = A.col_indices();
  // Calls f(J, fine block, weight) for every term of coarse row I.
  const auto for_each_term = [&](Index I, const auto& f) {
    for (Index t = t_off[I]; t < t_off[I + 1]; ++t) {
      const Index i = t_fine[t];
      const double wa = t_weight[t];
      for (Index k = off[i]; k < off[i + 1]; ++k) {
        const Index j = cols[k];
        for (Index b = po[j]; b < po[j + 1]; ++b)
          if (pw[b] != 0.0) f(pi[b], k, wa * pw[b]);
      }
    }
  };
  std::vector<Index> mark(static_cast<size_t>(nc), -1);
  std::vector<Index> c_off(static_cast<size_t>(nc) + 1, 0), c_cols;
  std::vector<Index> row;
  for (Index I = 0; I < nc; ++I) {
    row.assign(1, I);
    mark[I] = 0;
    for_each_term(I, [&](Index J, Index, double) {
      if (mark[J] < 0) {
        mark[J] = 0;
        row.push_back(J);
      }
    });
    std::sort(row.begin(), row.end());
    for (Index J : row) mark[J] = -1;
    c_cols.insert(c_cols.end(), row.begin(), row.end());
    c_off[I + 1] = static_cast<Index>(c_cols.size());
  }
  m_offsets.assign(c_cols.size() + 1, 0);
  const auto with_slots = [&](Index I, const auto& f) {
    for (Index s = c_off[I]; s < c_off[I + 1]; ++s) mark[c_cols[s]] = s;
    for_each_term(I, [&](Index J, Index k, double w) { f(mark[J], k, w); });
    for (Index s = c_off[I]; s < c_off[I + 1]; ++s) mark[c_cols[s]] = -1;
  };
  for (Index I = 0; I < nc; ++I) with_slots(I, [&](Index s, Index, double) { ++m_offsets[s + 1]; });
  for (size_t s = 0; s + 1 < m_offsets.size(); ++s) m_offsets[s + 1] += m_offsets[s];
  m_terms.resize(static_cast<size_t>(m_offsets.back()));
  std::vector<Index> fill(m_offsets.begin(), m_offsets.end() - 1);
  for (Index I = 0; I < nc; ++I) with_slots(I, [&](Index s, Index k, double w) { m_terms[fill[s]++] = {k, w}; });
  m_coarse = BlockMatrix3::from_rows(nc, std::move(c_off), std::move(c_cols));
}

void GalerkinProduct::compute(const BlockMatrix3& A, BlockMatrix3& coarse) const {
  if (A.num_blocks() != m_fine_blocks) throw Error("Galerkin: matrix pattern differs from the one analysed");
  if (!coarse.same_pattern(m_coarse)) coarse = m_coarse;
  if (has_constant_blocks()) {
    if (!m_constant_ready) throw Error("Galerkin: constant blocks set but their share not computed");
    parallel_for(m_coarse.num_blocks(), [&](Index c) {
      Mat3 s = m_constant[c];
      for (Index t = m_variable_offsets[c]; t < m_variable_offsets[c + 1]; ++t)
        s.noalias() += m_variable_terms[t].weight * A.block(m_variable_terms[t].fine_block);
      coarse.block(c) = s;
    });
    return;
  }
  parallel_for(m_coarse.num_blocks(), [&](Index c) {
    Mat3 s = Mat3::Zero();
    for (Index t = m_offsets[c]; t < m_offsets[c + 1]; ++t) s.noalias() += m_terms[t].weight * A.block(m_terms[t].fine_block);
    coarse.block(c) = s;
  });
}

void GalerkinProduct::set_constant_blocks(const std::vector<char>& constant) {
  if (static_cast<Index>(constant.size()) != m_fine_blocks)
    throw Error(fmt::format("Galerkin: {} constant-block flags for {} fine blocks", constant.size(), m_fine_blocks));
  const Index nc = m_coarse.num_blocks();
  m_constant_flags = constant;
  m_variable_offsets.assign(static_cast<size_t>(nc) + 1, 0);
  parallel_for(nc, [&](Index c) {
    Index n = 0;
    for (Index t = m_offsets[c]; t < m_offsets[c + 1]; ++t) n += !constant[m_terms[t].fine_block];
    m_variable_offsets[c + 1] = n;
  });
  for (Index c = 0; c < nc; ++c) m_variable_offsets[c + 1] += m_variable_offsets[c];
  m_variable_terms.resize(static_cast<size_t>(m_variable_offsets.back()));
  parallel_for(nc, [&](Index c) {
    Index out = m_variable_offsets[c];
    for (Index t = m_offsets[c]; t < m_offsets[c + 1]; ++t)
      if (!constant[m_terms[t].fine_block]) m_variable_terms[out++] = m_terms[t];
  });
  m_constant.assign(static_cast<size_t>(nc), Mat3::Zero());
  m_constant_ready = false;
}

void GalerkinProduct::compute_constant(const BlockMatrix3& A) {
  if (!has_constant_blocks()) throw Error("Galerkin: compute_constant without constant blocks");
  if (A.num_blocks() != m_fine_blocks) throw Error("Galerkin: matrix pattern differs from the one analysed");
  parallel_for(m_coarse.num_blocks(), [&](Index c) {
    Mat3 s = Mat3::Zero();
    for (Index t = m_offsets[c]; t < m_offsets[c + 1]; ++t)
      if (m_constant_flags[m_terms[t].fine_block]) s.noalias() += m_terms[t].weight * A.block(m_terms[t].fine_block);
    m_constant[c] = s;
  });
  m_constant_ready = true;
}

void GalerkinProduct::clear_constant_blocks() {
  m_variable_offsets.clear();
  m_variable_terms.clear();
  m_constant_flags.clear();
  m_constant.clear();
  m_constant_ready = false;
}

}  // namespace mgcloth::linalg
