#pragma once
#include <mgcloth/core/types.hpp>

#include <array>
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
};

/// Control mesh of a grid-aligned region in the z = 0 plane, material coordinates equal to (x, y); ghost points on
/// the ghost layer are placed on the same grid (the linear extrapolation of the boundary rows). Cells are numbered
/// row by row; vertices likewise. InputError for non-positive sizes, fewer than 1 cell, or a notch outside the grid
/// or covering it.
QuadMesh make_quad_grid(const QuadGridSpec& spec);
/// The paper's rectangle: n × m quads.
QuadMesh make_quad_rectangle(double width, double height, int nx, int ny, bool ghost_layer = true);
/// A square of side `size` with n × n quads and the square of side `notch` at its top-right corner removed (the
/// re-entrant corner scenario, §7); `notch` must be a whole number of cells.
QuadMesh make_notched_square(double size, double notch, int n, bool ghost_layer = true);

}  // namespace mgcloth::mesh
