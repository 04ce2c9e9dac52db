#pragma once
#include <mgcloth/core/types.hpp>

#include <string>

#include <array>
#include <filesystem>
#include <utility>
#include <vector>

namespace mgcloth::mesh {

using Quad = std::array<Index, 4>;

/// A quad control mesh for Catmull-Clark subdivision surfaces (Kopaničáková 2019 §5.2): control points, their
/// material coordinates, and quads counter-clockwise in material space. Ghost control points and faces form one
/// layer around open boundaries (§5.2.1, Fig. 4c): they shape the limit surface up to the boundary but carry no
/// unknowns of their own (their positions follow the real points they were extrapolated from).
struct QuadMesh {
  Mat3X x;
  Mat2X u;
  std::vector<Quad> quads;
  std::vector<char> ghost_vertex;  ///< per control point; empty: no ghost layer
  std::vector<char> ghost_face;    ///< per quad; empty: no ghost layer

  Index num_vertices() const { return static_cast<Index>(x.cols()); }
  Index num_faces() const { return static_cast<Index>(quads.size()); }
  bool is_ghost_vertex(Index v) const { return !ghost_vertex.empty() && ghost_vertex[static_cast<size_t>(v)]; }
  bool is_ghost_face(Index f) const { return !ghost_face.empty() && ghost_face[static_cast<size_t>(f)]; }
  Index num_real_vertices() const;
};

/// A grid-aligned region: an nx × ny array of unit cells, each in or out. The paper's control meshes (rectangle,
/// square with a square notch) are such regions; a ghost layer on a grid is exact and simple (every cell outside
/// the region that touches it, by edge or corner, is a ghost cell).
struct QuadGridSpec {
  double width = 1.0, height = 1.0;  ///< metres, along material u and v
  int nx = 4, ny = 4;                ///< cells along u and v
  /// Cells removed: [i0, i1) × [j0, j1) in cell indices (e.g. the square notch of the re-entrant corner scenario).
  /// Empty (i0 == i1): none.
  int notch_i0 = 0, notch_i1 = 0, notch_j0 = 0, notch_j1 = 0;
  bool ghost_layer = true;  ///< add one layer of ghost faces around every open boundary
  /// Optional: where the grid lines lie on the limit surface, nx + 1 (ny + 1) increasing values from 0 to width
  /// (height). The control points are then placed so that the limit surface of grid line i is exactly at
  /// lines_u[i] (needs the ghost layer): non-uniform cells, e.g. a 0.3 m notch in a 4 x 4 grid of a 1 m square.
  /// Empty: uniform.
  std::vector<double> lines_u, lines_v;
};

/// Control mesh of a grid-aligned region in the z = 0 plane, material coordinates equal to (x, y); ghost points on
/// the ghost layer are placed on the same grid (the linear extrapolation of the boundary rows). Cells are numbered
/// row by row; vertices likewise. InputError for non-positive sizes, fewer than 1 cell, or a notch outside the grid
/// or covering it.
QuadMesh make_quad_grid(const QuadGridSpec& spec);
/// The paper's rectangle: n × m quads.
QuadMesh make_quad_rectangle(double width, double height, int nx, int ny, bool ghost_layer = true);
/// A square of side `size` with n × n quads and the square of side `notch` at its top-right corner removed (the
/// re-entrant corner scenario, §7). When `notch` is a whole number of cells the grid is uniform; otherwise the
/// notch takes round(notch / size · n) cells (at least one) and the grid lines are spaced evenly on each side of
/// the notch line (QuadGridSpec::lines_u), so a 0.3 m notch fits the paper's 4 × 4 coarsest grid.
QuadMesh make_notched_square(double size, double notch, int n, bool ghost_layer = true);

/// Edges of real faces on the boundary of the real region (no real face on the other side) as (face, k): the
/// edge from quads[face][k] to quads[face][(k + 1) % 4].
std::vector<std::pair<Index, int>> real_boundary_edges(const QuadMesh& mesh);

/// Checks a control mesh and throws InputError naming `source` and the element: finite coordinates, indices in
/// range, no repeated point in a quad, every edge in at most two quads, consistent orientation, every point used,
/// at least one real face.
void validate(const QuadMesh& mesh, const std::string& source);

/// Adds one layer of ghost faces around the open boundary (Kopaničáková 2019 §5.2.1, Fig. 4c), ghost points
/// extrapolated linearly across the boundary (2 v − v', v' the neighbour inside). Supported boundary points: on a
/// straight run (two faces) and convex corners (one face); elsewhere (a concave corner, a boundary point of more
/// faces) InputError asks for the ghost faces to be modelled in the input.
void add_ghost_layer(QuadMesh& mesh);

/// Reads an all-quad control mesh from OBJ: `vt` as material coordinates (one per position; without vt the
/// material coordinates are (x, y)), scaled by material_scale. Faces in a group or object named "ghost" are ghost
/// faces; otherwise, with `ghost_layer`, a ghost layer is added (add_ghost_layer). InputError names the file.
QuadMesh read_quad_obj(const std::filesystem::path& path, double material_scale = 1.0, bool ghost_layer = true);

}  // namespace mgcloth::mesh
