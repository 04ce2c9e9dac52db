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
  struct Entry {
    Index I, J, k;
    double w;
  };
  std::vector<Entry> entries;
  std::vector<std::pair<Index, Index>> pairs;
  const auto& off = A.row_offsets();
  const auto& cols = A.col_indices();
  for (Index i = 0; i < A.rows(); ++i)
    for (Index k = off[i]; k < off[i + 1]; ++k) {
      const Index j = cols[k];
      for (Index a = po[i]; a < po[i + 1]; ++a)
        for (Index b = po[j]; b < po[j + 1]; ++b) {
          if (pw[a] == 0.0 || pw[b] == 0.0) continue;
          entries.push_back({pi[a], pi[b], k, pw[a] * pw[b]});
          if (pi[a] <= pi[b]) pairs.emplace_back(pi[a], pi[b]);
        }
    }
  m_coarse = BlockMatrix3(nc, std::move(pairs));
  // Group the terms by coarse block; stable order keeps the summation order fixed.
  std::vector<Index> slot(entries.size());
  std::vector<Index> count(m_coarse.num_blocks() + 1, 0);
  for (size_t e = 0; e < entries.size(); ++e) {
    slot[e] = m_coarse.find(entries[e].I, entries[e].J);
    ++count[slot[e] + 1];
  }
  for (Index c = 0; c < m_coarse.num_blocks(); ++c) count[c + 1] += count[c];
  m_offsets = count;
  m_terms.resize(entries.size());
  for (size_t e = 0; e < entries.size(); ++e) m_terms[count[slot[e]]++] = {entries[e].k, entries[e].w};
}

void GalerkinProduct::compute(const BlockMatrix3& A, BlockMatrix3& coarse) const {
  if (A.num_blocks() != m_fine_blocks) throw Error("Galerkin: matrix pattern differs from the one analysed");
  if (!coarse.same_pattern(m_coarse)) coarse = m_coarse;
  parallel_for(m_coarse.num_blocks(), [&](Index c) {
    Mat3 s = Mat3::Zero();
    for (Index t = m_offsets[c]; t < m_offsets[c + 1]; ++t) s.noalias() += m_terms[t].weight * A.block(m_terms[t].fine_block);
    coarse.block(c) = s;
  });
}

}  // namespace mgcloth::linalg
