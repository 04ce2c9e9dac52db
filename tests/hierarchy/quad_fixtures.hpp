#pragma once
// Small quad control meshes shared by the subdivision and reverse-subdivision tests.
#include <mgcloth/mesh/quad_mesh.hpp>

#include <cmath>

namespace mgcloth::hierarchy::fixtures {

/// n quads around a point of valence n (an extraordinary interior vertex for n ≠ 4), with boundary points of
/// valence 3 and corners of valence 2; optionally with a ring of ghost faces.
inline mesh::QuadMesh fan(int n, bool ghost_layer = false) {
  mesh::QuadMesh m;
  m.x.setZero(3, 1 + 2 * n);
  m.u.setZero(2, 1 + 2 * n);
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / n, b = a + M_PI / n;
    m.u.col(1 + i) = Vec2(std::cos(a), std::sin(a));
    m.u.col(1 + n + i) = 1.4 * Vec2(std::cos(b), std::sin(b));
  }
  m.x.topRows(2) = m.u;
  for (int i = 0; i < n; ++i) m.quads.push_back({0, 1 + i, 1 + n + i, 1 + (i + 1) % n});
  if (ghost_layer) mesh::add_ghost_layer(m);
  return m;
}

/// The surface of a cube: eight points of valence 3, each next to three others, closed (no boundary).
inline mesh::QuadMesh cube() {
  mesh::QuadMesh m;
  m.x.resize(3, 8);
  for (int i = 0; i < 8; ++i) m.x.col(i) = Vec3(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  m.u = m.x.topRows(2);
  m.quads = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  return m;
}

}  // namespace mgcloth::hierarchy::fixtures
