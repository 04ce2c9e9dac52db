#pragma once
#include <mgcloth/core/types.hpp>
#include <mgcloth/linalg/stencil_table.hpp>

#include <functional>
#include <vector>

namespace mgcloth::physics {
class Objective;
}

namespace mgcloth::hierarchy {

/// Maps an iterate of one level to the next coarser level (xyz interleaved).
using Projection = std::function<void(const VecX& fine, VecX& coarse)>;

/// What a multilevel solver sees of a discretization's hierarchy, whatever made it (a triangle mesh's material-space
/// coarsening, a subdivision surface's control meshes, the union of several bodies'). Levels are numbered finest
/// first: level 0 is the problem's own unknown. The pointers are owned by whoever built the hierarchy (a body) and
/// stay valid for the step.
struct Hierarchy {
  struct Level {
    Index num_points = 0;
    /// The step's objective rediscretized on this level, for solvers that need coarse objectives (FAS, RMTR); on
    /// level 0 the problem's objective. Null where the builder was not asked for them (Galerkin coarse operators
    /// need only the prolongations).
    const physics::Objective* objective = nullptr;
    /// From level l + 1 to this level: rows this level's points, columns the coarser level's. Null on the coarsest.
    const linalg::StencilTable* prolongation = nullptr;
    /// This level's iterate to level l + 1: the discretization's own projection (injection for nested vertex sets,
    /// reverse subdivision for subdivision surfaces, Kopaničáková 2019 §5.3.2) and the least-squares one of eq.
    /// (5.18). Empty on the coarsest level and where the builder provides none.
    Projection project, project_lsq;
    /// Smoothing patches (every point with its one-ring) for patch (Schwarz) smoothers; null where none.
    const std::vector<std::vector<Index>>* patches = nullptr;
  };
  std::vector<Level> levels;

  bool empty() const { return levels.empty(); }
  std::size_t num_levels() const { return levels.size(); }
  /// The prolongations, finest first: entry l maps level l + 1 to level l (what Galerkin multigrid needs).
  std::vector<const linalg::StencilTable*> prolongations() const;
  /// Whether every level has an objective (levels from 1 on: level 0's is the problem's).
  bool has_objectives() const;
  /// Whether every level above the coarsest has a projection of iterates (`least_squares`: project_lsq).
  bool has_projections(bool least_squares = false) const;
};

/// A hierarchy of prolongations only (levels finest first: prolongations[l] maps level l + 1 to level l), for
/// Galerkin multigrid on an objective assembled elsewhere.
Hierarchy from_prolongations(const std::vector<const linalg::StencilTable*>& prolongations);

}  // namespace mgcloth::hierarchy
