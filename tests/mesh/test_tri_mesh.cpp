#include "mesh/mesh_checks.hpp"

#include <mgcloth/mesh/tri_mesh.hpp>

#include <gtest/gtest.h>

#include <limits>

namespace mgcloth::mesh {
namespace {

using test::flat_mesh;
using test::throws_input_error;

TEST(TriMesh, Areas) {
  TriMesh m = test::unit_square();
  EXPECT_DOUBLE_EQ(m.material_area(0), 0.5);
  EXPECT_DOUBLE_EQ(m.total_material_area(), 1.0);
  // Lift vertex 2 to z = 1: triangle 0 becomes (0,0,0), (1,0,0), (1,1,1) with area |(1,0,0) x (1,1,1)| / 2.
  m.x(2, 2) = 1.0;
  EXPECT_DOUBLE_EQ(m.world_area(0), 0.5 * std::sqrt(2.0));
  EXPECT_DOUBLE_EQ(m.material_area(0), 0.5);  // the rest shape does not move with x
  std::swap(m.tris[0][1], m.tris[0][2]);
  EXPECT_DOUBLE_EQ(m.material_area(0), -0.5);
}

TEST(TriMesh, ValidateAcceptsGoodMesh) {
  TriMesh m = test::square_annulus();
  const auto tris = m.tris;
  EXPECT_NO_THROW(validate(m, "annulus"));
  EXPECT_EQ(m.tris, tris);
}

TEST(TriMesh, ValidateFlipsMirroredChart) {
  // A UV chart mirrored as a whole (u -> -u) is legal: every triangle is flipped to be CCW again.
  TriMesh m = test::square_annulus();
  m.u.row(0) *= -1.0;
  for (Index t = 0; t < m.num_triangles(); ++t) ASSERT_LT(m.material_area(t), 0.0);
  ASSERT_NO_THROW(validate(m, "mirrored"));
  for (Index t = 0; t < m.num_triangles(); ++t) EXPECT_GT(m.material_area(t), 0.0);
}

TEST(TriMesh, ValidateRejectsDegenerateTriangle) {
  // Triangle 1 has collinear material coordinates: vertex 3 lies on edge (0, 1).
  TriMesh m = flat_mesh({{0, 0}, {1, 0}, {0, 1}, {0.5, 0}}, {{0, 1, 2}, {0, 3, 1}});
  EXPECT_TRUE(throws_input_error([&] { validate(m, "cloth.obj"); },
                                 {"cloth.obj", "triangle 1 (vertices 0, 3, 1)", "zero area in material space"}));
  // Nearly collinear: height 1e-13 of the length.
  m.u(1, 3) = -1e-13;
  EXPECT_TRUE(throws_input_error([&] { validate(m, "cloth.obj"); }, {"triangle 1", "zero area"}));
  // A thin but usable triangle (height 1e-6 of its length) passes.
  m.u(1, 3) = -1e-6;
  EXPECT_NO_THROW(validate(m, "cloth.obj"));
}

TEST(TriMesh, ValidateRejectsCollapsedTriangle) {
  // All three vertices of triangle 1 within 1e-9 of each other, in a mesh with edges of length ~1.
  TriMesh m = flat_mesh({{0, 0}, {1, 0}, {0, 1}, {2, 2}, {2 + 1e-9, 2}, {2, 2 + 1e-9}}, {{0, 1, 2}, {3, 4, 5}});
  EXPECT_TRUE(throws_input_error([&] { validate(m, "m"); }, {"m: triangle 1", "zero area"}));
}

TEST(TriMesh, ValidateRejectsBadIndices) {
  TriMesh m = flat_mesh({{0, 0}, {1, 0}, {0, 1}}, {{0, 1, 3}});
  EXPECT_TRUE(throws_input_error([&] { validate(m, "m"); }, {"m: triangle 0", "outside [0, 3)"}));
  m.tris = {{0, 1, 1}};
  EXPECT_TRUE(throws_input_error([&] { validate(m, "m"); }, {"triangle 0 (vertices 0, 1, 1) repeats a vertex"}));
  m.tris = {{-1, 1, 2}};
  EXPECT_TRUE(throws_input_error([&] { validate(m, "m"); }, {"triangle 0"}));
}

TEST(TriMesh, ValidateRejectsNonFinite) {
  TriMesh m = test::unit_square();
  m.x(1, 2) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(throws_input_error([&] { validate(m, "m"); }, {"vertex 2", "non-finite world position"}));
  m = test::unit_square();
  m.u(0, 3) = kInf;
  EXPECT_TRUE(throws_input_error([&] { validate(m, "m"); }, {"vertex 3", "non-finite material coordinate"}));
}

TEST(TriMesh, ValidateRejectsSizeMismatchAndUnusedVertex) {
  TriMesh m = test::unit_square();
  m.u.conservativeResize(2, 3);
  EXPECT_TRUE(throws_input_error([&] { validate(m, "m"); }, {"4 world positions but 3 material coordinates"}));
  m = flat_mesh({{0, 0}, {1, 0}, {0, 1}, {5, 5}}, {{0, 1, 2}});
  EXPECT_TRUE(throws_input_error([&] { validate(m, "m"); }, {"vertex 3 is not used"}));
}

TEST(TriMesh, ValidateRejectsNonManifoldEdge) {
  TriMesh m = flat_mesh({{0, 0}, {1, 0}, {0.5, 1}, {0.5, -1}, {0.6, 2}}, {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}});
  EXPECT_TRUE(throws_input_error([&] { validate(m, "skirt.obj"); },
                                 {"skirt.obj", "edge (0, 1)", "3 triangles (0, 1, 2)"}));
}

TEST(TriMesh, ValidateRejectsFold) {
  // Triangles 0 and 1 share edge (0, 1) and both lie above it in material space: after the flip that makes each
  // CCW they traverse the edge in the same direction.
  TriMesh m = flat_mesh({{0, 0}, {1, 0}, {0.5, 1}, {0.4, 0.5}}, {{0, 1, 2}, {1, 0, 3}});
  EXPECT_TRUE(throws_input_error([&] { validate(m, "fold"); },
                                 {"fold: triangles 0 and 1 share edge (0, 1)", "inconsistent orientation"}));
}

TEST(TriMesh, DegeneracyTestSharedWithInspect) {
  const TriMesh m = flat_mesh({{0, 0}, {1, 0}, {0, 1}, {0.5, 0}}, {{0, 1, 2}, {0, 3, 1}});
  const double mean = mean_material_edge_length(m);
  EXPECT_NEAR(mean, (1 + std::sqrt(2.0) + 1 + 0.5 + 0.5 + 1) / 6.0, 1e-15);
  EXPECT_FALSE(is_degenerate(m, 0, mean));
  EXPECT_TRUE(is_degenerate(m, 1, mean));
}

// A 1e-30 m triangle passed every relative test and failed only in the solver's coarsest Galerkin matrix; a sliver of
// area 1e-8 l^2 made the default solver fail to find a descent direction.
TEST(TriMesh, ValidateRejectsTinyTrianglesAndSlivers) {
  TriMesh tiny = flat_mesh({{0, 0}, {1e-30, 0}, {0, 1e-30}}, {{0, 1, 2}});
  EXPECT_TRUE(throws_input_error([&] { validate(tiny, "tiny.obj"); },
                                 {"tiny.obj: triangle 0 (vertices 0, 1, 2) is 1.41e-30 m across in material space",
                                  "at least 1e-07 m", "units or material_scale"}));
  // At the floor's scale, a well-shaped mesh is fine.
  TriMesh micro = flat_mesh({{0, 0}, {2e-7, 0}, {0, 2e-7}}, {{0, 1, 2}});
  EXPECT_NO_THROW(validate(micro, "micro"));

  // The unit square with vertex 1 moved towards the diagonal 0-2 (triangle 0's height over it: h).
  const auto sliver = [](double h) {
    return flat_mesh({{0, 0}, {0.5 + h / std::sqrt(2.0), 0.5 - h / std::sqrt(2.0)}, {1, 1}, {0, 1}},
                     {{0, 1, 2}, {0, 2, 3}});
  };
  TriMesh thin = sliver(2e-8);  // area 1.4e-8 = 0.7e-8 l^2 with l = sqrt(2)
  EXPECT_TRUE(throws_input_error([&] { validate(thin, "thin"); },
                                 {"thin: triangle 0 (vertices 0, 1, 2) has near-zero area in material space",
                                  "longest edge 1.41 m"}));
  TriMesh fine = sliver(1e-5);  // a smallest angle of 8e-4 degrees: bad, but not degenerate
  EXPECT_NO_THROW(validate(fine, "fine"));
}

}  // namespace
}  // namespace mgcloth::mesh
