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

/// Checks what every solver relies on and throws InputError naming `source` and the element:
/// finite coordinates, indices in range, no repeated vertex in a triangle, no zero-area triangle (in material
/// space, relative tolerance), every edge shared by at most two triangles, consistent orientation.
/// Triangles with negative material area are flipped (a mirrored UV chart is legal), not rejected.
void validate(TriMesh& mesh, const std::string& source);

}  // namespace mgcloth::mesh
