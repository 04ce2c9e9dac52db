#pragma once
#include <mgcloth/mesh/tri_mesh.hpp>

#include <string>

namespace mgcloth::mesh {

/// What `mgcloth info` prints about a mesh.
struct MeshReport {
  Index vertices = 0;
  Index triangles = 0;
  Index edges = 0;
  Index boundary_loops = 0;
  double material_area = 0.0;
  double world_area = 0.0;
  double min_edge = 0.0, max_edge = 0.0, mean_edge = 0.0;  ///< material-space edge lengths
  std::vector<Index> degenerate_triangles;                 ///< zero material area (relative tolerance)
  std::vector<Index> tiny_triangles;  ///< not degenerate, but smaller than kMinMaterialEdge in material space
  std::vector<Index> non_manifold_edges_first_tri;         ///< a triangle of each non-manifold edge
  Index unreferenced_vertices = 0;
  std::vector<Index> invalid_triangles;  ///< an index out of range; left out of every other statistic
  Index non_finite_vertices = 0;         ///< a NaN or infinite coordinate in x or u
  Index negative_area_triangles = 0;     ///< clockwise in material space (validate() flips them)
  Index inconsistent_edges = 0;          ///< interior edges whose triangles fold over each other in material space
  double min_angle_deg = 0.0;            ///< smallest triangle angle in material space, non-degenerate triangles
  bool sizes_match = true;  ///< x and u have as many columns; if not, indices beyond the smaller count are invalid
};

/// Inspects without throwing (the mesh need not be valid).
MeshReport inspect(const TriMesh& mesh);
std::string format_report(const MeshReport& report, const std::string& name);

}  // namespace mgcloth::mesh
