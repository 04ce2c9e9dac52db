#include <mgcloth/core/error.hpp>
#include <mgcloth/hierarchy/subdivision_hierarchy.hpp>
#include <mgcloth/mesh/opensubdiv.hpp>
#include "quad_fixtures.hpp"

#include <opensubdiv/far/primvarRefiner.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace mgcloth::hierarchy {
namespace {

using mesh::QuadMesh;

/// A point for OpenSubdiv's PrimvarRefiner.
struct Point {
  double p[3];
  void Clear(void* = nullptr) { p[0] = p[1] = p[2] = 0.0; }
  void AddWithWeight(const Point& s, float w) = delete;
  void AddWithWeight(const Point& s, double w) {
    for (int k = 0; k < 3; ++k) p[k] += w * s.p[k];
  }
};

using fixtures::cube;
/// Five quads around a point of valence 5 (an extraordinary interior vertex).
QuadMesh pentagon_fan() { return fixtures::fan(5); }

/// S q against OpenSubdiv's own refinement of the same mesh, for random q: every kept fine point is found as the
/// child of its parent vertex, edge or face in OpenSubdiv's level 1.
void expect_matches_opensubdiv(const QuadMesh& coarse) {
  const SubdivisionStep step = subdivide(coarse);
  auto refiner = mesh::make_topology_refiner(coarse);
  refiner->RefineUniform(OpenSubdiv::Far::TopologyRefiner::UniformOptions(1));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::vector<Point> src(static_cast<size_t>(coarse.num_vertices()));
  VecX q(3 * coarse.num_vertices());
  for (Index i = 0; i < coarse.num_vertices(); ++i)
    for (int k = 0; k < 3; ++k) src[i].p[k] = q[3 * i + k] = uni(rng);
  std::vector<Point> dst(static_cast<size_t>(refiner->GetLevel(1).GetNumVertices()));
  Point* out = dst.data();
  OpenSubdiv::Far::PrimvarRefinerReal<double>(*refiner).Interpolate(1, src.data(), out);
  VecX fine;
  step.subdivision.apply(q, fine);
  const auto& level0 = refiner->GetLevel(0);
  ASSERT_EQ(step.kind.size(), static_cast<size_t>(step.fine.num_vertices()));
  for (Index i = 0; i < step.fine.num_vertices(); ++i) {
    const auto [a, b] = step.parent[i];
    Index child = -1;
    if (step.kind[i] == 0) child = level0.GetVertexChildVertex(a);
    if (step.kind[i] == 1) child = level0.GetEdgeChildVertex(level0.FindEdge(a, b));
    if (step.kind[i] == 2) child = level0.GetFaceChildVertex(a);
    ASSERT_GE(child, 0);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(fine[3 * i + k], dst[child].p[k], 1e-14) << "fine point " << i;
  }
  // Partition of unity: every row of S sums to one.
  for (Index i = 0; i < step.subdivision.num_rows; ++i) {
    double s = 0.0;
    for (Index k = step.subdivision.offsets[i]; k < step.subdivision.offsets[i + 1]; ++k) s += step.subdivision.weights[k];
    EXPECT_NEAR(s, 1.0, 1e-15);
  }
}

TEST(SubdivisionHierarchy, SubdivisionMatrixMatchesOpenSubdiv) {
  expect_matches_opensubdiv(mesh::make_quad_rectangle(1.0, 1.0, 4, 4));          // ghost layer, outer layer dropped
  expect_matches_opensubdiv(mesh::make_quad_rectangle(2.0, 1.0, 3, 2, false));   // boundary rules and corners
  expect_matches_opensubdiv(mesh::make_notched_square(1.0, 0.5, 4));             // re-entrant ghost corner
  expect_matches_opensubdiv(pentagon_fan());                                      // valence 5, boundary valence 3
  expect_matches_opensubdiv(cube());                                              // valence 3, closed
  expect_matches_opensubdiv(subdivide(pentagon_fan()).fine);                      // one extraordinary point per face
}

// Kopaničáková 2019, Table 3: 147, 363, 1,083, 3,675, 13,467, 51,483 dofs on levels 1-6 of the 1 m square, and
// each level is the generator's grid at that resolution (one ghost ring), points in the same places.
TEST(SubdivisionHierarchy, SquareHierarchyHasThePapersDofCountsAndGrids) {
  const SubdivisionHierarchy h(mesh::make_quad_rectangle(1.0, 1.0, 4, 4), 6);
  const std::vector<Index> dofs{147, 363, 1083, 3675, 13467, 51483};
  for (int l = 0; l < 6; ++l) {
    EXPECT_EQ(3 * h.mesh(l).num_vertices(), dofs[static_cast<size_t>(l)]) << "level " << l + 1;
    const QuadMesh grid = mesh::make_quad_rectangle(1.0, 1.0, 4 << l, 4 << l);
    ASSERT_EQ(h.mesh(l).num_faces(), grid.num_faces());
    EXPECT_EQ(h.mesh(l).num_real_vertices(), grid.num_real_vertices());
    // Linear reproduction: the subdivided rest positions are the uniform grid's (matched as sets).
    std::vector<std::array<long, 2>> a, b;
    for (Index i = 0; i < grid.num_vertices(); ++i) {
      const double s = (4 << l);
      a.push_back({std::lround(h.mesh(l).x(0, i) * s * 2), std::lround(h.mesh(l).x(1, i) * s * 2)});
      b.push_back({std::lround(grid.x(0, i) * s * 2), std::lround(grid.x(1, i) * s * 2)});
      EXPECT_NEAR(h.mesh(l).x(0, i) * s * 2, a.back()[0], 1e-9);
    }
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    EXPECT_EQ(a, b) << "level " << l + 1;
    Index ghost_faces = 0;
    for (Index f = 0; f < h.mesh(l).num_faces(); ++f) ghost_faces += h.mesh(l).is_ghost_face(f);
    EXPECT_EQ(ghost_faces, grid.num_faces() - (16 << (2 * l)));
  }
}

TEST(SubdivisionHierarchy, NotchedSquareKeepsOneGhostRing) {
  const SubdivisionHierarchy h(mesh::make_notched_square(1.0, 0.5, 4), 3);
  for (int l = 0; l < 3; ++l) {
    const QuadMesh grid = mesh::make_notched_square(1.0, 0.5, 4 << l);
    EXPECT_EQ(h.mesh(l).num_faces(), grid.num_faces()) << "level " << l;
    EXPECT_EQ(h.mesh(l).num_vertices(), grid.num_vertices()) << "level " << l;
    EXPECT_EQ(h.mesh(l).num_real_vertices(), grid.num_real_vertices()) << "level " << l;
  }
}

TEST(SubdivisionHierarchy, BadMeshesAreInputErrors) {
  QuadMesh m = mesh::make_quad_rectangle(1.0, 1.0, 2, 2, false);
  m.quads.push_back({0, 1, 4, 3});  // a third quad on edge (0, 1)
  EXPECT_THROW(subdivide(m), InputError);
  QuadMesh d = mesh::make_quad_rectangle(1.0, 1.0, 2, 2, false);
  d.quads[0][1] = d.quads[0][0];
  EXPECT_THROW(subdivide(d), InputError);
  QuadMesh o = mesh::make_quad_rectangle(1.0, 1.0, 2, 2, false);
  o.quads[0][2] = 99;
  EXPECT_THROW(subdivide(o), InputError);
  EXPECT_THROW(SubdivisionHierarchy(mesh::make_quad_rectangle(1.0, 1.0, 2, 2), 0), InputError);
}

}  // namespace
}  // namespace mgcloth::hierarchy
