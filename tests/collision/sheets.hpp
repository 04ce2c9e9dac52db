// Test surfaces for the collision module, which links only core: grid sheets, flat, crumpled and folded.
#pragma once
#include <mgcloth/core/types.hpp>

#include <random>
#include <vector>

namespace mgcloth::collision::test {

/// Point (i, j) of an nx × ny grid.
inline Index grid_point(Index nx, Index i, Index j) { return j * nx + i; }

/// Two triangles per cell of an nx × ny grid of points.
inline std::vector<Tri> grid_triangles(Index nx, Index ny) {
  std::vector<Tri> t;
  for (Index j = 0; j + 1 < ny; ++j)
    for (Index i = 0; i + 1 < nx; ++i) {
      const Index a = grid_point(nx, i, j), b = grid_point(nx, i + 1, j), c = grid_point(nx, i + 1, j + 1),
                  d = grid_point(nx, i, j + 1);
      t.push_back({a, b, c});
      t.push_back({a, c, d});
    }
  return t;
}

/// The flat grid in the plane z = 0 with spacing h.
inline VecX flat_grid(Index nx, Index ny, double h) {
  VecX x(3 * nx * ny);
  for (Index j = 0; j < ny; ++j)
    for (Index i = 0; i < nx; ++i) vertex(x, grid_point(nx, i, j)) = Vec3(i * h, j * h, 0.0);
  return x;
}

/// The grid folded over at column k: columns past k lie back over the first ones, `gap` above them.
inline VecX folded_grid(Index nx, Index ny, Index k, double h, double gap) {
  VecX x(3 * nx * ny);
  for (Index j = 0; j < ny; ++j)
    for (Index i = 0; i < nx; ++i)
      vertex(x, grid_point(nx, i, j)) = i <= k ? Vec3(i * h, j * h, 0.0) : Vec3((2 * k - i) * h, j * h, gap);
  return x;
}

/// Every point moved uniformly at random by up to `amplitude` along each axis.
inline void displace(VecX& x, double amplitude, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  for (Index k = 0; k < x.size(); ++k) x[k] += u(rng);
}

}  // namespace mgcloth::collision::test
