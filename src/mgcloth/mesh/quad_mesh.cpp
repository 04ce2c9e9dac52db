#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/quad_mesh.hpp>

#include <cmath>

namespace mgcloth::mesh {

Index QuadMesh::num_real_vertices() const {
  Index n = 0;
  for (Index v = 0; v < num_vertices(); ++v) n += is_ghost_vertex(v) ? 0 : 1;
  return n;
}

QuadMesh make_quad_grid(const QuadGridSpec& s) {
  if (!(s.width > 0.0) || !(s.height > 0.0) || !std::isfinite(s.width) || !std::isfinite(s.height))
    throw_input_error("quad grid: width and height must be positive and finite (got {} x {})", s.width, s.height);
  if (s.nx < 1 || s.ny < 1) throw_input_error("quad grid: needs at least 1 x 1 cells (got {} x {})", s.nx, s.ny);
  const bool notched = s.notch_i0 < s.notch_i1 && s.notch_j0 < s.notch_j1;
  if (notched && (s.notch_i0 < 0 || s.notch_j0 < 0 || s.notch_i1 > s.nx || s.notch_j1 > s.ny))
    throw_input_error("quad grid: notch [{}, {}) x [{}, {}) is outside the {} x {} cells", s.notch_i0, s.notch_i1,
                      s.notch_j0, s.notch_j1, s.nx, s.ny);
  const auto real = [&](int i, int j) {
    if (i < 0 || j < 0 || i >= s.nx || j >= s.ny) return false;
    return !(notched && i >= s.notch_i0 && i < s.notch_i1 && j >= s.notch_j0 && j < s.notch_j1);
  };
  // Cells on an extended grid [-g, n + g) with g = 1 for the ghost layer.
  const int g = s.ghost_layer ? 1 : 0;
  const int cx = s.nx + 2 * g, cy = s.ny + 2 * g;
  std::vector<char> cell(static_cast<size_t>(cx) * cy, 0);  // 0 out, 1 real, 2 ghost
  Index real_cells = 0;
  for (int j = -g; j < s.ny + g; ++j)
    for (int i = -g; i < s.nx + g; ++i) {
      char& c = cell[static_cast<size_t>(j + g) * cx + (i + g)];
      if (real(i, j)) {
        c = 1;
        ++real_cells;
        continue;
      }
      if (!g) continue;
      for (int dj = -1; dj <= 1 && !c; ++dj)
        for (int di = -1; di <= 1 && !c; ++di)
          if (real(i + di, j + dj)) c = 2;
    }
  if (real_cells == 0) throw_input_error("quad grid: the notch removes every cell");

  // Vertices: corners of kept cells, numbered row by row on the extended grid of (cx + 1) × (cy + 1) points.
  const int px = cx + 1, py = cy + 1;
  std::vector<Index> id(static_cast<size_t>(px) * py, -1);
  const double hx = s.width / s.nx, hy = s.height / s.ny;
  QuadMesh m;
  std::vector<Vec2> u;
  for (int q = 0; q < py; ++q)
    for (int p = 0; p < px; ++p) {
      bool used = false, on_real = false;
      for (int dj = -1; dj <= 0; ++dj)
        for (int di = -1; di <= 0; ++di) {
          const int ci = p + di, cj = q + dj;
          if (ci < 0 || cj < 0 || ci >= cx || cj >= cy) continue;
          const char c = cell[static_cast<size_t>(cj) * cx + ci];
          used = used || c != 0;
          on_real = on_real || c == 1;
        }
      if (!used) continue;
      id[static_cast<size_t>(q) * px + p] = static_cast<Index>(u.size());
      u.emplace_back((p - g) * hx, (q - g) * hy);
      m.ghost_vertex.push_back(on_real ? 0 : 1);
    }
  m.u.resize(2, static_cast<Index>(u.size()));
  m.x.setZero(3, static_cast<Index>(u.size()));
  for (size_t v = 0; v < u.size(); ++v) {
    m.u.col(static_cast<Index>(v)) = u[v];
    m.x.col(static_cast<Index>(v)).head<2>() = u[v];
  }
  for (int j = 0; j < cy; ++j)
    for (int i = 0; i < cx; ++i) {
      const char c = cell[static_cast<size_t>(j) * cx + i];
      if (!c) continue;
      const auto at = [&](int p, int q) { return id[static_cast<size_t>(q) * px + p]; };
      m.quads.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});  // counter-clockwise in (u, v)
      m.ghost_face.push_back(c == 2 ? 1 : 0);
    }
  if (!g) {
    m.ghost_vertex.clear();
    m.ghost_face.clear();
  }
  return m;
}

QuadMesh make_quad_rectangle(double width, double height, int nx, int ny, bool ghost_layer) {
  QuadGridSpec s;
  s.width = width;
  s.height = height;
  s.nx = nx;
  s.ny = ny;
  s.ghost_layer = ghost_layer;
  return make_quad_grid(s);
}

QuadMesh make_notched_square(double size, double notch, int n, bool ghost_layer) {
  if (!(notch > 0.0) || !(notch < size))
    throw_input_error("notched square: the notch ({} m) must be positive and smaller than the square ({} m)", notch, size);
  const double cells = notch / size * n;
  const int k = static_cast<int>(std::lround(cells));
  if (std::abs(cells - k) > 1e-9 || k < 1 || k >= n)
    throw_input_error("notched square: a {} m notch is {} of the {} cells across a {} m square; it must be a whole "
                      "number of cells, at least 1 and fewer than {}", notch, cells, n, size, n);
  QuadGridSpec s;
  s.width = s.height = size;
  s.nx = s.ny = n;
  s.notch_i0 = s.notch_j0 = n - k;
  s.notch_i1 = s.notch_j1 = n;
  s.ghost_layer = ghost_layer;
  return make_quad_grid(s);
}

}  // namespace mgcloth::mesh
