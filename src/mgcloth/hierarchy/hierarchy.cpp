#include <mgcloth/hierarchy/hierarchy.hpp>

namespace mgcloth::hierarchy {

std::vector<const linalg::StencilTable*> Hierarchy::prolongations() const {
  std::vector<const linalg::StencilTable*> out;
  for (std::size_t l = 0; l + 1 < levels.size(); ++l) out.push_back(levels[l].prolongation);
  return out;
}

bool Hierarchy::has_objectives() const {
  for (std::size_t l = 1; l < levels.size(); ++l)
    if (!levels[l].objective) return false;
  return !levels.empty();
}

bool Hierarchy::has_projections(bool least_squares) const {
  for (std::size_t l = 0; l + 1 < levels.size(); ++l)
    if (!(least_squares ? levels[l].project_lsq : levels[l].project)) return false;
  return !levels.empty();
}

Hierarchy from_prolongations(const std::vector<const linalg::StencilTable*>& prolongations) {
  Hierarchy h;
  for (const linalg::StencilTable* P : prolongations) {
    Hierarchy::Level level;
    level.num_points = P->num_rows;
    level.prolongation = P;
    h.levels.push_back(std::move(level));
  }
  Hierarchy::Level coarsest;
  coarsest.num_points = prolongations.empty() ? 0 : prolongations.back()->num_cols;
  h.levels.push_back(std::move(coarsest));
  return h;
}

}  // namespace mgcloth::hierarchy
