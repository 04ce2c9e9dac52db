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

/// Tolerances of the zero-area test shared by validate() and inspect(): triangle t is degenerate when
/// |A_t| <= max(kSliverAreaRatio * l^2, kDegenerateAreaRatio * L^2), l its longest material edge and L the mesh's
/// mean material edge.
/// - Against its own longest edge, a sliver: height/length <= 2e-7, a smallest angle below ~1e-5 degrees, which no
///   mesher makes on purpose. Its membrane stiffness is ~1/(height/length) times its neighbours'; in a 30 x 30 grid
///   the default FMG solver failed on a sliver of area 1.1e-8 l^2 and converged with 1.1e-7 l^2.
/// - Against the mean edge, a collapsed triangle (all three vertices nearly coincident), loose enough for meshes
///   graded a million to one. Round-off in the area of an exactly collinear triangle, ~1e-16 * |u| * edge, stays
///   below both while material coordinates are within ~1e4 edge lengths of the origin.
inline constexpr double kSliverAreaRatio = 1e-7;
inline constexpr double kDegenerateAreaRatio = 1e-12;
/// Smallest longest material edge of a triangle, in metres (0.1 µm, a hundredth of a textile fibre's diameter).
/// A mesh that is small as a whole passes the relative tests above, but a cloth element smaller than this has no
/// physical meaning and its bending stiffness (~1/l^2) swamps everything else: a 1e-30 m triangle failed only in
/// the solver's coarsest Galerkin matrix. Usually a unit mistake (an OBJ in micrometres, a wrong material_scale).
inline constexpr double kMinMaterialEdge = 1e-7;

/// Mean material length over triangle sides (an interior edge counts twice); triangles with an index out of range
/// are skipped. 0 for an empty mesh.
double mean_material_edge_length(const TriMesh& mesh);
/// The degeneracy test above; `mean_edge` from mean_material_edge_length(). Indices must be in range.
bool is_degenerate(const TriMesh& mesh, Index t, double mean_edge);
/// Triangle t's longest material edge (indices must be in range).
double longest_material_edge(const TriMesh& mesh, Index t);

/// Checks what every solver relies on and throws InputError naming `source` and the element:
/// finite coordinates, indices in range, no repeated vertex in a triangle, no zero-area triangle (in material
/// space, relative tolerances), no triangle smaller than kMinMaterialEdge, every edge shared by at most two
/// triangles, consistent orientation.
/// Triangles with negative material area are flipped (a mirrored UV chart is legal), not rejected.
/// Also rejected: x and u of different sizes, and vertices no triangle uses (they would have no mass).
/// Consistent orientation means that, after the flips, the two triangles of every interior edge traverse it in
/// opposite directions; otherwise they overlap (fold) in material space.
void validate(TriMesh& mesh, const std::string& source);

}  // namespace mgcloth::mesh
