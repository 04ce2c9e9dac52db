#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/quad_mesh.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

namespace mgcloth::mesh {
namespace {

double signed_area(const QuadMesh& m, const Quad& q) {
  double a = 0.0;
  for (int k = 0; k < 4; ++k) {
    const Vec2 p = m.u.col(q[k]), r = m.u.col(q[(k + 1) % 4]);
    a += p.x() * r.y() - p.y() * r.x();
  }
  return 0.5 * a;
}

/// Every quad counter-clockwise with the cell area, every interior edge shared by exactly two quads in opposite
/// directions (a consistently oriented manifold), ghost points exactly the points with no real face.
void expect_valid(const QuadMesh& m, double cell_area) {
  std::map<std::pair<Index, Index>, int> directed;
  for (const Quad& q : m.quads) {
    EXPECT_NEAR(signed_area(m, q), cell_area, 1e-12);
    for (int k = 0; k < 4; ++k) {
      const std::pair<Index, Index> edge{q[k], q[(k + 1) % 4]};
      EXPECT_EQ(directed[edge]++, 0) << "edge used twice in one direction";
    }
  }
  std::vector<char> on_real(m.num_vertices(), 0);
  for (Index f = 0; f < m.num_faces(); ++f)
    if (!m.is_ghost_face(f))
      for (Index v : m.quads[f]) on_real[v] = 1;
  for (Index v = 0; v < m.num_vertices(); ++v) EXPECT_EQ(m.is_ghost_vertex(v), !on_real[v]) << "vertex " << v;
  EXPECT_TRUE(m.x.row(2).isZero(0.0));
  EXPECT_TRUE(m.x.topRows(2).isApprox(m.u));
}

// The control-point counts of the paper's 1 m square (Kopaničáková 2019, Table 3: 147, 363, 1,083, 3,675, 13,467,
// 51,483 dofs for levels 1-6): 4·2^(l-1) quads per side plus the ghost layer.
TEST(QuadMesh, RectangleWithGhostLayerHasThePapersDofCounts) {
  const std::vector<Index> dofs{147, 363, 1083, 3675, 13467, 51483};
  for (int l = 1; l <= 6; ++l) {
    const int n = 4 << (l - 1);
    const QuadMesh m = make_quad_rectangle(1.0, 1.0, n, n);
    EXPECT_EQ(3 * m.num_vertices(), dofs[static_cast<size_t>(l - 1)]) << "level " << l;
    EXPECT_EQ(m.num_faces(), (n + 2) * (n + 2));
    EXPECT_EQ(m.num_real_vertices(), (n + 1) * (n + 1));
    if (l <= 3) expect_valid(m, 1.0 / (n * n));
  }
}

TEST(QuadMesh, GhostLayerSurroundsTheRealRegionByOneCell) {
  const QuadMesh m = make_quad_rectangle(2.0, 1.0, 4, 2);
  expect_valid(m, 0.25);
  EXPECT_EQ(m.num_faces(), 6 * 4);
  Index ghosts = 0;
  for (Index f = 0; f < m.num_faces(); ++f) ghosts += m.is_ghost_face(f);
  EXPECT_EQ(ghosts, 6 * 4 - 4 * 2);
  EXPECT_NEAR(m.u.row(0).minCoeff(), -0.5, 1e-15);
  EXPECT_NEAR(m.u.row(0).maxCoeff(), 2.5, 1e-15);
  EXPECT_NEAR(m.u.row(1).minCoeff(), -0.5, 1e-15);
  EXPECT_NEAR(m.u.row(1).maxCoeff(), 1.5, 1e-15);
  const QuadMesh bare = make_quad_rectangle(2.0, 1.0, 4, 2, false);
  EXPECT_EQ(bare.num_faces(), 8);
  EXPECT_EQ(bare.num_vertices(), 15);
  EXPECT_EQ(bare.num_real_vertices(), 15);
  expect_valid(bare, 0.25);
}

// The notch is ringed by ghost cells too, including the cell diagonal to the re-entrant corner, so that the limit
// surface of the real faces is complete up to the notch's edges.
TEST(QuadMesh, NotchedSquareHasGhostCellsInsideTheNotch) {
  const QuadMesh m = make_notched_square(1.0, 0.5, 4);
  expect_valid(m, 1.0 / 16.0);
  Index real = 0;
  std::set<std::pair<int, int>> ghost_cells;
  for (Index f = 0; f < m.num_faces(); ++f) {
    const Vec2 lo = m.u.col(m.quads[f][0]);
    if (!m.is_ghost_face(f)) {
      ++real;
      EXPECT_FALSE(lo.x() >= 0.5 - 1e-12 && lo.y() >= 0.5 - 1e-12) << "a real cell inside the notch";
    } else {
      ghost_cells.insert({static_cast<int>(std::lround(lo.x() * 4)), static_cast<int>(std::lround(lo.y() * 4))});
    }
  }
  EXPECT_EQ(real, 16 - 4);
  // Inside the notch [2,4) x [2,4): the ring along its two edges, (2,2) through (2,3) and (3,2), and the diagonal
  // cell (2,2) at the re-entrant corner; (3,3) touches no real cell.
  EXPECT_TRUE(ghost_cells.count({2, 2}));
  EXPECT_TRUE(ghost_cells.count({2, 3}));
  EXPECT_TRUE(ghost_cells.count({3, 2}));
  EXPECT_FALSE(ghost_cells.count({3, 3}));
}

TEST(QuadMesh, BadSpecsAreInputErrors) {
  EXPECT_THROW(make_quad_rectangle(0.0, 1.0, 4, 4), InputError);
  EXPECT_THROW(make_quad_rectangle(1.0, 1.0, 0, 4), InputError);
  EXPECT_THROW(make_notched_square(1.0, 0.3, 4), InputError);  // 1.2 cells: not a whole number
  EXPECT_THROW(make_notched_square(1.0, 1.0, 4), InputError);
  EXPECT_THROW(make_notched_square(1.0, -0.25, 4), InputError);
  QuadGridSpec s;
  s.notch_i0 = 0;
  s.notch_i1 = 4;
  s.notch_j0 = 0;
  s.notch_j1 = 4;
  EXPECT_THROW(make_quad_grid(s), InputError);  // removes everything
  s.notch_i1 = 5;
  EXPECT_THROW(make_quad_grid(s), InputError);  // outside the grid
  EXPECT_NO_THROW(make_notched_square(1.0, 0.3, 10));  // 3 of 10 cells
}

}  // namespace
}  // namespace mgcloth::mesh
