#pragma once
#include <mgcloth/linalg/stencil_table.hpp>
#include <mgcloth/mesh/quad_mesh.hpp>

#include <vector>

namespace mgcloth::hierarchy {

/// One Catmull-Clark step of a control mesh: the fine mesh and the subdivision matrix S with q_fine = S q_coarse
/// (Kopaničáková 2019, eq. 5.11), as a weight table whose rows are the fine control points.
struct SubdivisionStep {
  mesh::QuadMesh fine;
  linalg::StencilTable subdivision;
  /// For each fine point, how it was made: 0 vertex point (parent = coarse vertex), 1 edge point (parent = coarse
  /// edge, as the pair of its end points), 2 face point (parent = coarse face). Reverse subdivision reads these.
  std::vector<char> kind;
  std::vector<std::array<Index, 2>> parent;
};

/// Subdivides `coarse` once by the Catmull-Clark rules written out in the paper: face points (eq. 5.12), edge
/// points (eq. 5.13), vertex points (eq. 5.14) in the interior; edge midpoints (eq. A.1) and the cubic B-spline
/// curve rule (eq. A.2, on the coarse boundary neighbours) on the boundary. Fine faces keep their parent's ghost
/// flag. With a ghost layer, the outer layer of fine ghost faces is discarded (§5.2.1, Fig. 5): a fine face is
/// kept when it is real or shares a point with a real fine face, so every level again has exactly one ring of
/// ghost faces, and its unused points are dropped (rows of S removed). Without a ghost layer nothing is dropped.
/// Material coordinates and positions of the fine points are S applied to the coarse ones, so the limit surface
/// and the material map are the same on every level.
SubdivisionStep subdivide(const mesh::QuadMesh& coarse);

/// A nested hierarchy of control meshes by uniform subdivision: level 0 is the coarsest (the input), level k the
/// input subdivided k times (the paper's levels 1..L).
class SubdivisionHierarchy {
 public:
  SubdivisionHierarchy() = default;
  /// `levels` >= 1 meshes in all.
  SubdivisionHierarchy(const mesh::QuadMesh& coarsest, int levels);

  int num_levels() const { return static_cast<int>(m_meshes.size()); }
  const mesh::QuadMesh& mesh(int level) const { return m_meshes[static_cast<size_t>(level)]; }
  const mesh::QuadMesh& finest() const { return m_meshes.back(); }
  /// S_l^{l+1}: from level `level` to level `level + 1` (transpose built).
  const linalg::StencilTable& subdivision(int level) const { return m_steps[static_cast<size_t>(level)].subdivision; }
  const SubdivisionStep& step(int level) const { return m_steps[static_cast<size_t>(level)]; }

 private:
  std::vector<mesh::QuadMesh> m_meshes;
  std::vector<SubdivisionStep> m_steps;
};

}  // namespace mgcloth::hierarchy
