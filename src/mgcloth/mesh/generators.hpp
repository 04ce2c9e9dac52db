#pragma once
#include <mgcloth/mesh/tri_mesh.hpp>

#include <cstdint>

namespace mgcloth::mesh {

struct CircleHole {
  Vec2 center{0.5, 0.5};
  double radius = 0.1;
};

/// A rectangular cloth [0,width] x [0,height] in material space, lying in the world plane z = 0 (x = (u, v, 0)).
struct RectangleSpec {
  double width = 1.0;
  double height = 1.0;
  Index target_vertices = 10000;  ///< approximate; the generator hits it within a few percent
  bool unstructured = false;      ///< false: regular grid with alternating diagonals; true: quasi-uniform CDT
  std::vector<CircleHole> holes;  ///< unstructured only; holes are polygonal with the local edge length
  std::uint64_t seed = 1;         ///< unstructured point sampling
};

/// Regular: an (nx+1) x (ny+1) vertex grid with cell aspect close to 1, diagonals alternating.
/// Unstructured: boundary sampled at spacing s, interior by jittered/Poisson-disk points at spacing s,
/// triangulated by CGAL's constrained Delaunay triangulation with the boundary (and hole loops) as constraints.
TriMesh make_rectangle(const RectangleSpec& spec);

}  // namespace mgcloth::mesh
