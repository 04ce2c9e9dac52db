#pragma once
#include <mgcloth/mesh/tri_mesh.hpp>

#include <cstdint>

namespace mgcloth::mesh {

/// The generators' largest vertex count (a rectangle needs at least 4, a tube 8): what the scene format and the
/// Python module accept, checked there under their own names and by make_rectangle and make_tube.
inline constexpr Index kMaxGeneratedVertices = 5'000'000;

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
///
/// Details of this implementation: the interior is a Poisson-disk sample of radius r grown from the boundary
/// points (Bridson's algorithm with candidates evenly spaced on the circle of radius r), deterministic for a seed
/// (std::mt19937_64, no std:: distributions). Boundary segments are at most r long. The triangulation is then
/// Delaunay-refined with a shape bound only, so every angle is >= 20.7 degrees; the sample alone gives 27 to 33
/// degrees, so refinement adds points only around holes less than ~8 spacings around. Interior valences range
/// from 4 to 9. Vertex counts: within 3% of the target from 100 vertices up and within 1% from 1000 up
/// (unstructured; the regular grid within 4.5% from 100 up and 2% from 1000 up); a small hole's graded ring adds
/// vertices beyond that. Vertices are numbered row by row; triangles are CCW in material space. Throws InputError
/// for a bad spec (non-positive size, target_vertices outside [4, kMaxGeneratedVertices], holes with a regular grid, holes not strictly inside the rectangle or overlapping each other) and OutOfMemory naming the
/// mesh when memory runs out.
TriMesh make_rectangle(const RectangleSpec& spec);

/// A two-panel garment: a tube (a skirt or sleeve) sewn from a front and a back panel along both side seams.
struct TubeSpec {
  double circumference = 1.0;     ///< m; each panel is circumference/2 wide
  double height = 0.5;            ///< m
  Index target_vertices = 10000;  ///< both panels together, stitched vertices counted once per panel
  bool unstructured = false;
  std::uint64_t seed = 1;
};

/// Front and back panels, each a rectangle [0, circumference/2] x [0, height] in material space (the two charts
/// overlap there, as separately laid-out sewing patterns may), placed on a vertical circular cylinder of that
/// circumference around the world z axis, v along z, so the initial state is unstretched. The front panel's right
/// side is stitched to the back panel's left side and vice versa: stitched vertices share a source_vertex
/// (Topology::stitch_groups), as they would reading the garment from an OBJ with UV seams. Vertices 0..n/2-1 are
/// the front panel. Throws InputError for a bad spec.
TriMesh make_tube(const TubeSpec& spec);

}  // namespace mgcloth::mesh
