#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/hierarchy/transfer.hpp>

namespace mgcloth::hierarchy {

void TransferTable::build_transpose() {
  t_offsets.assign(static_cast<std::size_t>(num_coarse) + 1, 0);
  for (Index j : indices) ++t_offsets[j + 1];
  for (Index j = 0; j < num_coarse; ++j) t_offsets[j + 1] += t_offsets[j];
  t_indices.resize(indices.size());
  t_weights.resize(weights.size());
  std::vector<Index> fill(t_offsets.begin(), t_offsets.end() - 1);
  // Rows in increasing order, so each transposed row lists its fine vertices sorted: a deterministic sum order.
  for (Index i = 0; i < num_fine; ++i)
    for (Index k = offsets[i]; k < offsets[i + 1]; ++k) {
      const Index slot = fill[indices[k]]++;
      t_indices[slot] = i;
      t_weights[slot] = weights[k];
    }
}

void TransferTable::apply(const VecX& coarse3, VecX& fine3) const {
  if (coarse3.size() != 3 * static_cast<Eigen::Index>(num_coarse))
    throw_error("TransferTable::apply: coarse vector has {} entries, expected {}", coarse3.size(), 3 * num_coarse);
  fine3.resize(3 * static_cast<Eigen::Index>(num_fine));
  parallel_for(num_fine, [&](Index i) {
    Vec3 s = Vec3::Zero();
    for (Index k = offsets[i]; k < offsets[i + 1]; ++k) s += weights[k] * vertex(coarse3, indices[k]);
    vertex(fine3, i) = s;
  }, 2048);
}

void TransferTable::apply_transpose(const VecX& fine3, VecX& coarse3) const {
  if (fine3.size() != 3 * static_cast<Eigen::Index>(num_fine))
    throw_error("TransferTable::apply_transpose: fine vector has {} entries, expected {}", fine3.size(),
                3 * num_fine);
  if (t_offsets.size() != static_cast<std::size_t>(num_coarse) + 1)
    throw_error("TransferTable::apply_transpose: build_transpose() was not called");
  coarse3.resize(3 * static_cast<Eigen::Index>(num_coarse));
  parallel_for(num_coarse, [&](Index j) {
    Vec3 s = Vec3::Zero();
    for (Index k = t_offsets[j]; k < t_offsets[j + 1]; ++k) s += t_weights[k] * vertex(fine3, t_indices[k]);
    vertex(coarse3, j) = s;
  }, 2048);
}

}  // namespace mgcloth::hierarchy
