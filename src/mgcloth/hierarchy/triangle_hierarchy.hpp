#pragma once
#include <mgcloth/hierarchy/hierarchy.hpp>
#include <mgcloth/linalg/stencil_table.hpp>
#include <mgcloth/mesh/tri_mesh.hpp>

#include <cstdint>
#include <vector>

namespace mgcloth::hierarchy {

/// How a nested triangle-mesh hierarchy is coarsened (Wang 2018, §3.1 and Appendix B).
struct HierarchyParams {
  double ratio = 4.0;               ///< target vertex-count reduction from one level to the next
  Index min_coarse_vertices = 100;  ///< a level is never coarsened below about this many vertices
  Index max_coarse_vertices = 400;  ///< coarsening stops once a level has at most this many vertices
  std::vector<Index> keep;          ///< finest-level vertices present on every level (e.g. pinned vertices)
  std::uint64_t seed = 1;           ///< order of the interior Poisson-disk sampling
  double corner_angle_deg = 30.0;   ///< boundary vertices turning more than this (material space) are kept
};

/// One level: a triangle mesh whose vertices are a subset of the level below's (nested sets).
struct Level {
  mesh::TriMesh mesh;
  std::vector<Index> fine_index;  ///< for each vertex, its index in level l-1 (identity on level 0)
  std::vector<Index> to_finest;   ///< for each vertex, its index on level 0
};

/// Levels 0 (finest, the input) to H (coarsest), and the prolongations between consecutive levels.
class TriangleHierarchy {
 public:
  TriangleHierarchy() = default;
  TriangleHierarchy(std::vector<Level> levels, std::vector<linalg::StencilTable> prolongations)
      : m_levels(std::move(levels)), m_prolongations(std::move(prolongations)) {}

  const std::vector<Level>& levels() const { return m_levels; }
  Index num_levels() const { return static_cast<Index>(m_levels.size()); }
  const Level& level(Index l) const { return m_levels[l]; }
  /// I_{l+1}^l of Wang 2018 eq. (1): from level l+1 (coarse) to level l (fine); l in [0, num_levels() - 1).
  const linalg::StencilTable& prolongation(Index l) const { return m_prolongations[l]; }
  /// Its levels as a solver sees them: prolongations, and injection (the vertex sets are nested, so it is an exact
  /// projection of iterates) as each level's projection. No objectives, least-squares projections or patches.
  Hierarchy levels_for_solvers() const;

 private:
  std::vector<Level> m_levels;
  std::vector<linalg::StencilTable> m_prolongations;
};

/// Builds the hierarchy in material space (Wang 2018, Appendix B): per level, keep the corner vertices of each
/// boundary loop (turning angle > corner_angle_deg), sample each boundary loop evenly by arc length, sample the
/// interior by a greedy Poisson-disk pass (seeded random order) at a radius tuned so the vertex count drops by
/// about `ratio`, always keep `keep`, and triangulate the kept vertices by CGAL's constrained Delaunay
/// triangulation with the coarse boundary loops as constraints (triangles outside the outer loop or inside holes
/// dropped by nesting level). Stops once a level has at most max_coarse_vertices vertices; the target of a level
/// is never below min_coarse_vertices. Coarse vertices copy x and u from the fine level.
/// Prolongation weights (eq. 1): 1 for a fine vertex that is also coarse; linear along the coarse boundary edge
/// for fine boundary vertices (projection onto the edge between the neighbouring coarse boundary vertices, so
/// straight boundaries are reproduced exactly); barycentric in the containing coarse triangle for interior
/// vertices, or, if none contains it (a concave boundary cut by a coarse chord), clamped and renormalized
/// barycentric weights of the closest coarse triangle. Every row sums to 1 with non-negative weights.
/// Garments: each panel (connected component) is triangulated and interpolated on its own, so panels may overlap
/// in material space; stitched seams (vertices sharing a TriMesh::source_vertex) are coarsened together (App. B
/// step 2): seam ends are kept like corners, a seam is sampled on one panel and its partner vertices are taken on
/// the other, so every coarse level stays stitched at the same points. A kept vertex keeps its stitch partners.
/// Throws InputError for bad parameters or keep indices out of range; `finest` must be a valid mesh.
TriangleHierarchy build_triangle_hierarchy(const mesh::TriMesh& finest, const HierarchyParams& params);

}  // namespace mgcloth::hierarchy
