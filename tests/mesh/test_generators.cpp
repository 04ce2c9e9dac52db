#include "mesh/mesh_checks.hpp"

#include <mgcloth/core/timer.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>

#include <gtest/gtest.h>

#include <cstdio>
#include <numbers>

namespace mgcloth::mesh {
namespace {

using test::throws_input_error;

double hole_area(const RectangleSpec& spec) {
  double a = 0.0;
  for (const CircleHole& h : spec.holes) a += std::numbers::pi * h.radius * h.radius;
  return a;
}

/// What every generated rectangle must satisfy.
void expect_well_formed(const TriMesh& m, const RectangleSpec& spec) {
  ASSERT_EQ(m.x.cols(), m.u.cols());
  EXPECT_TRUE(m.x.row(2).isZero(0.0));
  EXPECT_TRUE(m.x.topRows<2>() == m.u);
  EXPECT_GE(m.u.minCoeff(), 0.0);
  EXPECT_LE(m.u.row(0).maxCoeff(), spec.width);
  EXPECT_LE(m.u.row(1).maxCoeff(), spec.height);
  Index negative = 0;
  for (Index t = 0; t < m.num_triangles(); ++t) negative += m.material_area(t) <= 0.0;
  EXPECT_EQ(negative, 0);
  TriMesh copy = m;
  EXPECT_NO_THROW(validate(copy, "generated"));
  EXPECT_EQ(copy.tris, m.tris);  // nothing needed flipping
  const Topology topo = build_topology(m);
  EXPECT_EQ(topo.boundary_loops.size(), 1 + spec.holes.size());
  EXPECT_EQ(m.num_vertices() - topo.num_edges() + m.num_triangles(), 1 - static_cast<Index>(spec.holes.size()));
}

double relative_count_error(const TriMesh& m, const RectangleSpec& spec) {
  return std::abs(static_cast<double>(m.num_vertices()) / spec.target_vertices - 1.0);
}

TEST(Generators, RegularHitsTargetAndArea) {
  for (const auto& [w, h, n] : std::vector<std::tuple<double, double, Index>>{
           {1.0, 1.0, 100}, {1.0, 1.0, 10000}, {2.0, 1.0, 5000}, {0.3, 1.7, 2500}, {10.0, 1.0, 1000}}) {
    SCOPED_TRACE(testing::Message() << w << " x " << h << ", " << n << " vertices");
    RectangleSpec spec;
    spec.width = w;
    spec.height = h;
    spec.target_vertices = n;
    const TriMesh m = make_rectangle(spec);
    EXPECT_LE(relative_count_error(m, spec), 0.05) << m.num_vertices();
    EXPECT_NEAR(m.total_material_area(), w * h, 1e-12 * w * h);
    expect_well_formed(m, spec);
    // Near-square cells: edge lengths along x and y within 25 % of each other.
    const double ex = m.u(0, 1) - m.u(0, 0);
    const Index row = static_cast<Index>(std::lround(w / ex)) + 1;
    const double ey = m.u(1, row) - m.u(1, 0);
    EXPECT_NEAR(ex / ey, 1.0, 0.25);
  }
}

TEST(Generators, RegularDiagonalsAlternate) {
  RectangleSpec spec;
  spec.target_vertices = 16;  // 4 x 4 vertices, 3 x 3 cells
  const TriMesh m = make_rectangle(spec);
  ASSERT_EQ(m.num_vertices(), 16);
  // The diagonal of each cell is the side shared by its two triangles (2 * cell, 2 * cell + 1).
  auto diagonal_rises = [&](Index cell) {
    const Tri& a = m.tris[2 * cell];
    const Tri& b = m.tris[2 * cell + 1];
    std::vector<Index> shared;
    for (Index v : a)
      if (std::find(b.begin(), b.end(), v) != b.end()) shared.push_back(v);
    EXPECT_EQ(shared.size(), 2u);
    const Vec2 d = m.u.col(shared[1]) - m.u.col(shared[0]);
    return d.x() * d.y() > 0.0;
  };
  for (Index j = 0; j < 3; ++j)
    for (Index i = 0; i < 3; ++i) EXPECT_EQ(diagonal_rises(3 * j + i), (i + j) % 2 == 0) << i << ", " << j;
}

TEST(Generators, UnstructuredHitsTargetAreaAndQuality) {
  for (const auto& [w, h, n] : std::vector<std::tuple<double, double, Index>>{
           {1.0, 1.0, 50}, {1.0, 1.0, 1000}, {2.0, 1.0, 5000}, {0.5, 1.5, 20000}}) {
    SCOPED_TRACE(testing::Message() << w << " x " << h << ", " << n << " vertices");
    RectangleSpec spec;
    spec.unstructured = true;
    spec.width = w;
    spec.height = h;
    spec.target_vertices = n;
    const TriMesh m = make_rectangle(spec);
    EXPECT_LE(relative_count_error(m, spec), 0.05) << m.num_vertices();
    EXPECT_NEAR(m.total_material_area(), w * h, 1e-12 * w * h);
    expect_well_formed(m, spec);
    double worst = 180.0;
    for (Index t = 0; t < m.num_triangles(); ++t) worst = std::min(worst, test::min_angle_deg(m, t));
    // Refinement guarantees 20.7; the Poisson-disk sample alone gives 27.9 to 33 degrees here.
    EXPECT_GT(worst, 26.0);
    // Unstructured in connectivity, not only in geometry: interior valences other than 6 are common.
    const Topology topo = build_topology(m);
    Index irregular = 0, interior = 0;
    for (Index v = 0; v < m.num_vertices(); ++v) {
      if (topo.is_boundary_vertex[v]) continue;
      ++interior;
      irregular += topo.adjacency_offsets[v + 1] - topo.adjacency_offsets[v] != 6;
    }
    if (n >= 1000) {
      EXPECT_GT(irregular, interior / 4) << irregular << " of " << interior;
    }
  }
}

TEST(Generators, UnstructuredIsDeterministicPerSeed) {
  RectangleSpec spec;
  spec.unstructured = true;
  spec.target_vertices = 2000;
  const TriMesh a = make_rectangle(spec), b = make_rectangle(spec);
  EXPECT_TRUE(a.u == b.u);
  EXPECT_EQ(a.tris, b.tris);
  spec.seed = 2;
  const TriMesh c = make_rectangle(spec);
  EXPECT_FALSE(c.u.cols() == a.u.cols() && c.u == a.u);
}

TEST(Generators, UnstructuredWithHoles) {
  RectangleSpec spec;
  spec.unstructured = true;
  spec.width = 2.0;
  spec.height = 1.0;
  spec.target_vertices = 20000;
  spec.holes = {{{0.5, 0.5}, 0.2}, {{1.4, 0.45}, 0.3}, {{1.9, 0.9}, 0.05}};
  const TriMesh m = make_rectangle(spec);
  EXPECT_LE(relative_count_error(m, spec), 0.05) << m.num_vertices();
  // The holes are inscribed polygons, so the area is slightly above the exact one (by < 0.1 % at this size).
  const double exact = spec.width * spec.height - hole_area(spec);
  EXPECT_GT(m.total_material_area(), exact);
  EXPECT_NEAR(m.total_material_area(), exact, 1e-3 * exact);
  expect_well_formed(m, spec);
  // No vertex inside a hole: all lie outside the inscribed polygons (8 sides at least).
  for (Index i = 0; i < m.num_vertices(); ++i)
    for (const CircleHole& h : spec.holes)
      ASSERT_GE((m.u.col(i) - h.center).norm(), h.radius * std::cos(std::numbers::pi / 8) * (1 - 1e-12));
  double worst = 180.0;
  for (Index t = 0; t < m.num_triangles(); ++t) worst = std::min(worst, test::min_angle_deg(m, t));
  EXPECT_GT(worst, 26.0);  // measured 28.3; the 0.05 hole spans ~10 spacings, so refinement adds nothing
}

TEST(Generators, HoleSmallerThanSpacingIsGraded) {
  // The spacing is ~0.1 and the hole's circumference ~0.13: its 8-gon would make slivers against the sample,
  // and Delaunay refinement grades the mesh around it instead.
  RectangleSpec spec;
  spec.unstructured = true;
  spec.target_vertices = 120;
  spec.holes = {{{0.5, 0.5}, 0.02}};
  const TriMesh m = make_rectangle(spec);
  expect_well_formed(m, spec);
  double worst = 180.0;
  for (Index t = 0; t < m.num_triangles(); ++t) worst = std::min(worst, test::min_angle_deg(m, t));
  EXPECT_GT(worst, 20.7 - 1e-9);
  EXPECT_GT(m.num_vertices(), 120);  // the graded ring costs vertices: documented, not hidden
  EXPECT_LT(m.num_vertices(), 200);
}

TEST(Generators, LargeUnstructuredMeshIsFast) {
#ifdef NDEBUG
  const Index n = 250000;
#else
  const Index n = 40000;  // unoptimized CGAL is an order of magnitude slower
#endif
  RectangleSpec spec;
  spec.unstructured = true;
  spec.target_vertices = n;
  spec.holes = {{{0.3, 0.3}, 0.1}};
  Timer timer;
  const TriMesh m = make_rectangle(spec);
  const double t_generate = timer.seconds();
  timer.reset();
  const Topology topo = build_topology(m);
  const double t_topology = timer.seconds();
  std::printf("[ info     ] %d vertices, %d triangles: make_rectangle %.3f s, build_topology %.3f s\n",
              m.num_vertices(), m.num_triangles(), t_generate, t_topology);
  RecordProperty("make_rectangle_s", std::to_string(t_generate));
  RecordProperty("build_topology_s", std::to_string(t_topology));
  EXPECT_LE(relative_count_error(m, spec), 0.05);
  EXPECT_EQ(topo.boundary_loops.size(), 2u);
  EXPECT_EQ(m.num_vertices() - topo.num_edges() + m.num_triangles(), 0);
}

TEST(Generators, RejectsBadSpecs) {
  RectangleSpec spec;
  spec.width = 0.0;
  EXPECT_TRUE(throws_input_error([&] { make_rectangle(spec); }, {"rectangle", "width and height"}));
  spec = {};
  spec.height = -1.0;
  EXPECT_TRUE(throws_input_error([&] { make_rectangle(spec); }, {"width and height"}));
  spec = {};
  spec.target_vertices = 3;
  EXPECT_TRUE(throws_input_error([&] { make_rectangle(spec); }, {"target_vertices", "at least 4"}));
  spec.target_vertices = 1'000'000'000;  // the generator's own limit, whoever calls it (it used to allocate on)
  EXPECT_TRUE(throws_input_error([&] { make_rectangle(spec); }, {"target_vertices", "at most 5000000", "1000000000"}));
  TubeSpec tube;
  tube.target_vertices = 5'000'001;
  EXPECT_TRUE(throws_input_error([&] { make_tube(tube); }, {"tube", "at most 5000000"}));
  spec = {};
  spec.holes = {{{0.5, 0.5}, 0.1}};
  EXPECT_TRUE(throws_input_error([&] { make_rectangle(spec); }, {"holes need an unstructured mesh"}));
  spec.unstructured = true;
  spec.holes = {{{0.5, 0.5}, 0.5}};  // touches all four sides
  EXPECT_TRUE(throws_input_error([&] { make_rectangle(spec); }, {"hole 0", "not strictly inside"}));
  spec.holes = {{{0.3, 0.5}, 0.1}, {{1.2, 0.5}, 0.1}};
  EXPECT_TRUE(throws_input_error([&] { make_rectangle(spec); }, {"hole 1", "not strictly inside"}));
  spec.holes = {{{0.3, 0.5}, 0.2}, {{0.6, 0.5}, 0.15}};
  EXPECT_TRUE(throws_input_error([&] { make_rectangle(spec); }, {"holes 0 and 1 overlap"}));
  spec.holes = {{{0.3, 0.5}, 0.0}};
  EXPECT_TRUE(throws_input_error([&] { make_rectangle(spec); }, {"hole 0", "positive radius"}));
}

TEST(Generators, SmallestTargets) {
  for (bool unstructured : {false, true}) {
    RectangleSpec spec;
    spec.unstructured = unstructured;
    spec.target_vertices = 4;
    const TriMesh m = make_rectangle(spec);
    EXPECT_GE(m.num_vertices(), 4);
    EXPECT_LE(m.num_vertices(), 6);
    EXPECT_NEAR(m.total_material_area(), 1.0, 1e-12);
    expect_well_formed(m, spec);
  }
}

}  // namespace
}  // namespace mgcloth::mesh
