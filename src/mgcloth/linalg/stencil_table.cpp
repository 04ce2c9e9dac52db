#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/linalg/stencil_table.hpp>

#include <algorithm>

namespace mgcloth::linalg {

Index StencilTable::max_row_length() const {
  Index m = 0;
  for (Index i = 0; i < num_rows; ++i) m = std::max(m, offsets[i + 1] - offsets[i]);
  return m;
}

void StencilTable::build_transpose() {
  t_offsets.assign(static_cast<std::size_t>(num_cols) + 1, 0);
  for (Index j : indices) ++t_offsets[j + 1];
  for (Index j = 0; j < num_cols; ++j) t_offsets[j + 1] += t_offsets[j];
  t_indices.resize(indices.size());
  t_weights.resize(weights.size());
  std::vector<Index> fill(t_offsets.begin(), t_offsets.end() - 1);
  // Rows in increasing order, so each transposed row lists its entries sorted: a deterministic sum order.
  for (Index i = 0; i < num_rows; ++i)
    for (Index k = offsets[i]; k < offsets[i + 1]; ++k) {
      const Index slot = fill[indices[k]]++;
      t_indices[slot] = i;
      t_weights[slot] = weights[k];
    }
}

void StencilTable::apply(const VecX& in, VecX& out) const {
  if (in.size() != 3 * static_cast<Eigen::Index>(num_cols))
    throw_error("StencilTable::apply: the input has {} entries, expected {} ({} points)", in.size(), 3 * num_cols,
                num_cols);
  out.resize(3 * static_cast<Eigen::Index>(num_rows));
  parallel_for(num_rows, [&](Index i) {
    Vec3 s = Vec3::Zero();
    for (Index k = offsets[i]; k < offsets[i + 1]; ++k) s += weights[k] * vertex(in, indices[k]);
    vertex(out, i) = s;
  }, 2048);
}

void StencilTable::apply_transpose(const VecX& in, VecX& out) const {
  if (in.size() != 3 * static_cast<Eigen::Index>(num_rows))
    throw_error("StencilTable::apply_transpose: the input has {} entries, expected {} ({} points)", in.size(),
                3 * num_rows, num_rows);
  if (!has_transpose()) throw_error("StencilTable::apply_transpose: build_transpose() was not called");
  out.resize(3 * static_cast<Eigen::Index>(num_cols));
  parallel_for(num_cols, [&](Index j) {
    Vec3 s = Vec3::Zero();
    for (Index k = t_offsets[j]; k < t_offsets[j + 1]; ++k) s += t_weights[k] * vertex(in, t_indices[k]);
    vertex(out, j) = s;
  }, 2048);
}

std::size_t StencilTable::memory_bytes() const {
  return (offsets.size() + indices.size() + t_offsets.size() + t_indices.size()) * sizeof(Index) +
         (weights.size() + t_weights.size()) * sizeof(double);
}

}  // namespace mgcloth::linalg
