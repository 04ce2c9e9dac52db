#include "mesh/mesh_checks.hpp"

#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <set>

namespace mgcloth::mesh {
namespace {

using test::flat_mesh;
using test::signed_loop_area;

Index euler_characteristic(const TriMesh& m, const Topology& t) {
  return m.num_vertices() - t.num_edges() + m.num_triangles();
}

bool is_rotation_of(const std::array<Index, 3>& a, const Tri& t) {
  for (int k = 0; k < 3; ++k)
    if (a[0] == t[k] && a[1] == t[(k + 1) % 3] && a[2] == t[(k + 2) % 3]) return true;
  return false;
}

/// Every invariant the header promises, checked against the mesh.
void expect_consistent(const TriMesh& m, const Topology& topo) {
  const Index ne = topo.num_edges();
  ASSERT_EQ(topo.edge_tris.size(), topo.edges.size());
  ASSERT_EQ(topo.tri_edges.size(), m.tris.size());
  std::set<std::array<Index, 2>> unique(topo.edges.begin(), topo.edges.end());
  EXPECT_EQ(static_cast<Index>(unique.size()), ne);
  for (const auto& e : topo.edges) EXPECT_LT(e[0], e[1]);
  Index interior = 0;
  for (Index e = 0; e < ne; ++e) {
    const auto [t0, t1] = topo.edge_tris[e];
    ASSERT_GE(t0, 0);
    if (t1 >= 0) ++interior;
    for (Index t : {t0, t1}) {
      if (t < 0) continue;
      const auto& te = topo.tri_edges[t];
      EXPECT_TRUE(std::find(te.begin(), te.end(), e) != te.end()) << "edge " << e << " triangle " << t;
    }
  }
  EXPECT_EQ(static_cast<Index>(topo.hinges.size()), interior);
  for (Index t = 0; t < m.num_triangles(); ++t)
    for (int k = 0; k < 3; ++k) {
      const auto& e = topo.edges[topo.tri_edges[t][k]];
      const Index a = m.tris[t][k], b = m.tris[t][(k + 1) % 3];
      EXPECT_EQ(e[0], std::min(a, b));
      EXPECT_EQ(e[1], std::max(a, b));
    }
  // Hinge convention: (v0, v1, v2) oriented like tri[0], (v1, v0, v3) like tri[1].
  for (const Hinge& h : topo.hinges) {
    EXPECT_TRUE(is_rotation_of({h.v[0], h.v[1], h.v[2]}, m.tris[h.tri[0]]));
    EXPECT_TRUE(is_rotation_of({h.v[1], h.v[0], h.v[3]}, m.tris[h.tri[1]]));
    EXPECT_NE(h.v[2], h.v[3]);
  }
  // Adjacency: sorted, symmetric, exactly the edges.
  ASSERT_EQ(static_cast<Index>(topo.adjacency_offsets.size()), m.num_vertices() + 1);
  EXPECT_EQ(static_cast<Index>(topo.adjacency.size()), 2 * ne);
  for (Index v = 0; v < m.num_vertices(); ++v) {
    const auto b = topo.adjacency.begin() + topo.adjacency_offsets[v];
    const auto e = topo.adjacency.begin() + topo.adjacency_offsets[v + 1];
    EXPECT_TRUE(std::is_sorted(b, e));
    EXPECT_TRUE(std::adjacent_find(b, e) == e);
    for (auto it = b; it != e; ++it) {
      EXPECT_NE(*it, v);
      EXPECT_TRUE(unique.count({std::min(v, *it), std::max(v, *it)}));
    }
  }
  // Boundary flags are exactly the loop vertices; every loop step is a boundary edge.
  std::set<Index> on_loops;
  for (const auto& loop : topo.boundary_loops) {
    for (std::size_t i = 0; i < loop.size(); ++i) {
      on_loops.insert(loop[i]);
      const Index a = loop[i], b = loop[(i + 1) % loop.size()];
      const auto it = std::lower_bound(topo.edges.begin(), topo.edges.end(),
                                       std::array<Index, 2>{std::min(a, b), std::max(a, b)});
      ASSERT_TRUE(it != topo.edges.end() && *it == (std::array<Index, 2>{std::min(a, b), std::max(a, b)}));
      EXPECT_EQ(topo.edge_tris[it - topo.edges.begin()][1], -1);
    }
  }
  for (Index v = 0; v < m.num_vertices(); ++v) EXPECT_EQ(topo.is_boundary_vertex[v], on_loops.count(v) == 1) << v;
}

TEST(Topology, UnitSquare) {
  const TriMesh m = test::unit_square();
  const Topology topo = build_topology(m);
  expect_consistent(m, topo);
  EXPECT_EQ(topo.num_edges(), 5);
  ASSERT_EQ(topo.hinges.size(), 1u);
  EXPECT_EQ(euler_characteristic(m, topo), 1);
  // The diagonal 0-2: tri 0 = (0, 1, 2) runs it as 2 -> 0, so v0 = 2, v1 = 0, v2 = 1; tri 1 = (0, 2, 3) gives v3 = 3.
  const Hinge& h = topo.hinges[0];
  EXPECT_EQ(h.tri, (std::array<Index, 2>{0, 1}));
  EXPECT_EQ(h.v, (std::array<Index, 4>{2, 0, 1, 3}));
  ASSERT_EQ(topo.boundary_loops.size(), 1u);
  EXPECT_EQ(topo.boundary_loops[0], (std::vector<Index>{0, 1, 2, 3}));
  EXPECT_EQ(topo.adjacency_offsets, (std::vector<Index>{0, 3, 5, 8, 10}));
  EXPECT_EQ(topo.adjacency, (std::vector<Index>{1, 2, 3, 0, 2, 0, 1, 3, 0, 2}));
}

TEST(Topology, GridCountsAndEuler) {
  RectangleSpec spec;
  spec.target_vertices = 12;  // 4 x 3 vertices
  spec.width = 1.5;
  const TriMesh m = make_rectangle(spec);
  ASSERT_EQ(m.num_vertices(), 12);
  const Topology topo = build_topology(m);
  expect_consistent(m, topo);
  // nx = 3, ny = 2: 6 cells, 12 triangles, 3*3 + 4*2 + 6 diagonals = 23 edges, 23 - 10 boundary edges = 13 hinges.
  EXPECT_EQ(m.num_triangles(), 12);
  EXPECT_EQ(topo.num_edges(), 23);
  EXPECT_EQ(topo.hinges.size(), 13u);
  EXPECT_EQ(euler_characteristic(m, topo), 1);
  ASSERT_EQ(topo.boundary_loops.size(), 1u);
  EXPECT_EQ(topo.boundary_loops[0].size(), 10u);
  EXPECT_NEAR(signed_loop_area(m, topo.boundary_loops[0]), 1.5, 1e-12);  // outer loop counter-clockwise
}

TEST(Topology, AnnulusHasHoleLoop) {
  const TriMesh m = test::square_annulus();
  const Topology topo = build_topology(m);
  expect_consistent(m, topo);
  EXPECT_EQ(euler_characteristic(m, topo), 0);
  ASSERT_EQ(topo.boundary_loops.size(), 2u);
  std::vector<double> areas;
  for (const auto& loop : topo.boundary_loops) areas.push_back(signed_loop_area(m, loop));
  std::sort(areas.begin(), areas.end());
  EXPECT_NEAR(areas[0], -1.0, 1e-12);  // the hole, clockwise
  EXPECT_NEAR(areas[1], 9.0, 1e-12);   // the outer boundary, counter-clockwise
  EXPECT_EQ(std::count(topo.is_boundary_vertex.begin(), topo.is_boundary_vertex.end(), true), 16);
}

TEST(Topology, SeparatePanels) {
  TriMesh m = flat_mesh({{0, 0}, {1, 0}, {0, 1}, {3, 0}, {4, 0}, {4, 1}, {3, 1}},
                        {{0, 1, 2}, {3, 4, 5}, {3, 5, 6}});
  const Topology topo = build_topology(m);
  expect_consistent(m, topo);
  EXPECT_EQ(euler_characteristic(m, topo), 2);
  ASSERT_EQ(topo.boundary_loops.size(), 2u);
  EXPECT_EQ(topo.boundary_loops[0].size(), 3u);
  EXPECT_EQ(topo.boundary_loops[1].size(), 4u);
}

TEST(Topology, LoopsSeparateAtTouchingCorners) {
  // Squares A = [0,1]^2 and B = [-1,0]^2 touch at vertex 0 only; triangles interleaved so that a walk along B
  // reaches vertex 0 while A's outgoing side there has the lower number.
  const TriMesh m = flat_mesh({{0, 0}, {1, 0}, {1, 1}, {0, 1}, {-1, -1}, {0, -1}, {-1, 0}},
                              {{4, 5, 0}, {0, 1, 2}, {4, 0, 6}, {0, 2, 3}});
  const Topology topo = build_topology(m);
  expect_consistent(m, topo);
  ASSERT_EQ(topo.boundary_loops.size(), 2u);
  EXPECT_EQ(topo.boundary_loops[0], (std::vector<Index>{4, 5, 0, 6}));
  EXPECT_EQ(topo.boundary_loops[1], (std::vector<Index>{0, 1, 2, 3}));
}

TEST(Topology, NonManifoldEdgeThrows) {
  // Triangles 0, 1 and 2 all contain edge (0, 1).
  const TriMesh m = flat_mesh({{0, 0}, {1, 0}, {0.5, 1}, {0.5, -1}, {0.6, 2}}, {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}});
  EXPECT_TRUE(test::throws_input_error([&] { build_topology(m, "panel.obj"); },
                                       {"panel.obj", "edge (0, 1)", "3 triangles", "0, 1, 2"}));
}

TEST(Topology, UnstructuredWithHolesIsConsistent) {
  RectangleSpec spec;
  spec.unstructured = true;
  spec.target_vertices = 3000;
  spec.width = 2.0;
  spec.holes = {{{0.5, 0.5}, 0.2}, {{1.4, 0.5}, 0.25}};
  const TriMesh m = make_rectangle(spec);
  const Topology topo = build_topology(m);
  expect_consistent(m, topo);
  EXPECT_EQ(euler_characteristic(m, topo), 1 - 2);
  EXPECT_EQ(topo.boundary_loops.size(), 3u);
}

TEST(Topology, GroupsSkipInvalidTriangles) {
  // group_triangle_sides must not throw or read out of bounds on broken input (inspect relies on it).
  const std::vector<Tri> tris{{0, 1, 2}, {0, 1, 7}, {-1, 0, 1}, {2, 2, 3}};
  const EdgeGroups g = group_triangle_sides(tris, 4);
  // Triangle 0 gives three edges; triangle 3 (2, 2, 3) adds (2, 3) twice; 1 and 2 are skipped.
  EXPECT_EQ(g.num_edges(), 4);
  EXPECT_EQ(g.edges.back(), (std::array<Index, 2>{2, 3}));
  EXPECT_EQ(g.count(3), 2);
}

}  // namespace
}  // namespace mgcloth::mesh
