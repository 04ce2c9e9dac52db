#pragma once
#include <mgcloth/core/types.hpp>

#include <string>
#include <vector>

namespace mgcloth::mesh {

/// A triangle mesh with a 2D material (rest) parameterization. Units: metres.
/// x: world positions (3 x N); u: material coordinates (2 x N), the flat rest state the membrane measures strain
/// against; tris: counter-clockwise in material space (positive material area).
struct TriMesh {
  Mat3X x;
  Mat2X u;
  std::vector<Tri> tris;
  /// For meshes read from OBJ: the OBJ position index each vertex came from (vertices split at UV seams share it).
  std::vector<Index> source_vertex;

  Index num_vertices() const { return static_cast<Index>(x.cols()); }
  Index num_triangles() const { return static_cast<Index>(tris.size()); }
  /// Signed area of triangle t in material space.
  double material_area(Index t) const;
  double world_area(Index t) const;
  double total_material_area() const;
};

/// Relative tolerance of the zero-area test shared by validate() and inspect(): triangle t is degenerate when
/// |A_t| <= kDegenerateAreaRatio * L^2, L the larger of t's longest material edge and the mesh's mean material
/// edge. Measuring against the triangle's own longest edge catches slivers (height/length <= 2e-12, far below any
/// element a membrane can use), measuring against the mean edge catches collapsed triangles (all vertices nearly
/// coincident). Round-off in the area of an exactly collinear triangle,
/// ~1e-16 * |u| * edge, stays below it while material coordinates are within ~1e4 edge lengths of the origin.
inline constexpr double kDegenerateAreaRatio = 1e-12;

/// Mean material length over triangle sides (an interior edge counts twice); triangles with an index out of range
/// are skipped. 0 for an empty mesh.
double mean_material_edge_length(const TriMesh& mesh);
/// The degeneracy test above; `mean_edge` from mean_material_edge_length(). Indices must be in range.
bool is_degenerate(const TriMesh& mesh, Index t, double mean_edge);

/// Checks what every solver relies on and throws InputError naming `source` and the element:
/// finite coordinates, indices in range, no repeated vertex in a triangle, no zero-area triangle (in material
/// space, relative tolerance), every edge shared by at most two triangles, consistent orientation.
/// Triangles with negative material area are flipped (a mirrored UV chart is legal), not rejected.
/// Also rejected: x and u of different sizes, and vertices no triangle uses (they would have no mass).
/// Consistent orientation means that, after the flips, the two triangles of every interior edge traverse it in
/// opposite directions; otherwise they overlap (fold) in material space.
void validate(TriMesh& mesh, const std::string& source);

}  // namespace mgcloth::mesh
