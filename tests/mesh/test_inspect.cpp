#include "mesh/mesh_checks.hpp"

#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/inspect.hpp>
#include <mgcloth/mesh/topology.hpp>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <limits>

namespace mgcloth::mesh {
namespace {

TEST(Inspect, ValidMeshMatchesTopology) {
  RectangleSpec spec;
  spec.unstructured = true;
  spec.target_vertices = 1500;
  spec.width = 1.2;
  spec.holes = {{{0.6, 0.5}, 0.2}};
  TriMesh m = make_rectangle(spec);
  m.x.row(2) = 0.3 * m.x.row(0);  // tilt: world area = material area * sqrt(1 + 0.3^2)
  const Topology topo = build_topology(m);
  const MeshReport r = inspect(m);
  EXPECT_EQ(r.vertices, m.num_vertices());
  EXPECT_EQ(r.triangles, m.num_triangles());
  EXPECT_EQ(r.edges, topo.num_edges());
  EXPECT_EQ(r.boundary_loops, 2);
  EXPECT_NEAR(r.material_area, m.total_material_area(), 1e-12);
  EXPECT_NEAR(r.world_area, m.total_material_area() * std::sqrt(1.09), 1e-12);
  EXPECT_GT(r.min_edge, 0.0);
  EXPECT_LT(r.min_edge, r.mean_edge);
  EXPECT_LT(r.mean_edge, r.max_edge);
  EXPECT_GT(r.min_angle_deg, 20.0);
  EXPECT_TRUE(r.degenerate_triangles.empty());
  EXPECT_TRUE(r.non_manifold_edges_first_tri.empty());
  EXPECT_TRUE(r.invalid_triangles.empty());
  EXPECT_EQ(r.unreferenced_vertices, 0);
  EXPECT_EQ(r.non_finite_vertices, 0);
  EXPECT_EQ(r.negative_area_triangles, 0);
  EXPECT_EQ(r.inconsistent_edges, 0);
  const std::string text = format_report(r, "cloth.obj");
  EXPECT_EQ(text.rfind("cloth.obj\n", 0), 0u);
  EXPECT_NE(text.find(fmt::format("vertices             {}", m.num_vertices())), std::string::npos);
  EXPECT_NE(text.find("boundary loops       2"), std::string::npos);
  EXPECT_NE(text.find("no problems found"), std::string::npos);
  EXPECT_EQ(text.find("problem:"), std::string::npos);
}

TEST(Inspect, UnitSquareNumbers) {
  const MeshReport r = inspect(test::unit_square());
  EXPECT_EQ(r.edges, 5);
  EXPECT_EQ(r.boundary_loops, 1);
  EXPECT_DOUBLE_EQ(r.material_area, 1.0);
  EXPECT_DOUBLE_EQ(r.min_edge, 1.0);
  EXPECT_DOUBLE_EQ(r.max_edge, std::sqrt(2.0));
  EXPECT_DOUBLE_EQ(r.mean_edge, (4.0 + std::sqrt(2.0)) / 5.0);
  EXPECT_NEAR(r.min_angle_deg, 45.0, 1e-12);
}

TEST(Inspect, ReportsTrianglesBelowTheSizeFloor) {
  const TriMesh m = test::flat_mesh({{0, 0}, {1e-9, 0}, {0, 1e-9}, {1e-9, 1e-9}}, {{0, 1, 2}, {1, 3, 2}});
  const MeshReport r = inspect(m);
  EXPECT_TRUE(r.degenerate_triangles.empty());
  EXPECT_EQ(r.tiny_triangles, (std::vector<Index>{0, 1}));
  const std::string text = format_report(r, "tiny.obj");
  EXPECT_NE(text.find("problem: 2 triangles smaller than 1e-07 m in material space (0, 1)"), std::string::npos) << text;
}

TEST(Inspect, BrokenMeshIsReportedNotThrown) {
  // 0: fine; 1: degenerate (collinear); 2 and 3 share edge (0, 1) with 0 (non-manifold); 4: index out of range.
  // Vertex 7 is unused and vertex 6 has a NaN.
  TriMesh m = test::flat_mesh({{0, 0}, {1, 0}, {0.5, 1}, {0.5, -1}, {0.6, 2}, {2, 0}, {3, 3}, {9, 9}},
                              {{0, 1, 2}, {1, 5, 0}, {1, 0, 3}, {0, 1, 4}, {0, 1, 42}, {2, 4, 6}});
  m.x(0, 6) = std::numeric_limits<double>::quiet_NaN();
  MeshReport r;
  ASSERT_NO_THROW(r = inspect(m));
  EXPECT_EQ(r.invalid_triangles, (std::vector<Index>{4}));
  EXPECT_EQ(r.degenerate_triangles, (std::vector<Index>{1}));
  EXPECT_EQ(r.non_manifold_edges_first_tri.size(), 1u);
  EXPECT_EQ(r.unreferenced_vertices, 1);
  EXPECT_EQ(r.non_finite_vertices, 1);
  const std::string text = format_report(r, "broken.obj");
  EXPECT_NE(text.find("1 triangles refer to missing vertices (triangles 4)"), std::string::npos) << text;
  EXPECT_NE(text.find("1 degenerate (zero material area) triangles (1)"), std::string::npos) << text;
  EXPECT_NE(text.find("1 non-manifold edges"), std::string::npos) << text;
  EXPECT_NE(text.find("1 vertices are not used"), std::string::npos) << text;
  EXPECT_NE(text.find("non-finite"), std::string::npos) << text;
  EXPECT_EQ(text.find("no problems found"), std::string::npos) << text;
}

TEST(Inspect, MirroredChartAndFold) {
  TriMesh m = test::square_annulus();
  m.u.row(0) *= -1.0;  // mirrored: legal, reported as a note
  MeshReport r = inspect(m);
  EXPECT_EQ(r.negative_area_triangles, m.num_triangles());
  EXPECT_EQ(r.boundary_loops, 2);
  EXPECT_EQ(r.inconsistent_edges, 0);
  EXPECT_NE(format_report(r, "m").find("no problems found"), std::string::npos);

  const TriMesh fold = test::flat_mesh({{0, 0}, {1, 0}, {0.5, 1}, {0.4, 0.5}}, {{0, 1, 2}, {1, 0, 3}});
  r = inspect(fold);
  EXPECT_EQ(r.inconsistent_edges, 1);
  EXPECT_NE(format_report(r, "fold").find("inconsistent orientation"), std::string::npos);
}

TEST(Inspect, EmptyAndMismatchedMeshes) {
  MeshReport r;
  ASSERT_NO_THROW(r = inspect(TriMesh{}));
  EXPECT_EQ(r.vertices, 0);
  EXPECT_NE(format_report(r, "empty").find("no triangles"), std::string::npos);

  TriMesh m = test::unit_square();
  m.u.conservativeResize(2, 2);
  ASSERT_NO_THROW(r = inspect(m));
  EXPECT_FALSE(r.sizes_match);
  EXPECT_EQ(r.invalid_triangles.size(), 2u);
}

}  // namespace
}  // namespace mgcloth::mesh
