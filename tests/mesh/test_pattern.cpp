#include "mesh/mesh_checks.hpp"

#include <mgcloth/mesh/pattern.hpp>
#include <mgcloth/mesh/topology.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <set>

namespace mgcloth::mesh {
namespace {

using test::min_angle_deg;
using test::throws_input_error;

std::filesystem::path skirt_path() { return std::filesystem::path(MGCLOTH_SOURCE_DIR) / "scenes/patterns/skirt.json"; }

SewingPattern parse(const std::string& text, const std::string& label = "test.json") {
  return parse_pattern(parse_json(text, label), label);
}

PatternPanel rectangle(const std::string& name, double w, double h) {
  PatternPanel p;
  p.name = name;
  p.vertices = {{0, 0}, {w, 0}, {w, h}, {0, h}};
  return p;
}

/// Checks shared by every triangulation: CCW triangles, valid mesh, outline counts as sampled.
void check_mesh(const PatternMesh& pm) {
  const TriMesh& m = pm.mesh;
  ASSERT_EQ(m.u.cols(), m.x.cols());
  ASSERT_EQ(static_cast<Index>(m.source_vertex.size()), m.num_vertices());
  ASSERT_EQ(static_cast<Index>(pm.panel_of_triangle.size()), m.num_triangles());
  for (Index t = 0; t < m.num_triangles(); ++t) ASSERT_GT(m.material_area(t), 0.0) << "triangle " << t;
  TriMesh copy = m;
  EXPECT_NO_THROW(validate(copy, "pattern"));
  // Every panel's boundary is one loop made of exactly the sampled edge vertices.
  const Topology topo = build_topology(m);
  std::size_t sampled = 0;
  for (const auto& panel : pm.edge_vertices)
    for (const auto& edge : panel) sampled += edge.size() - 1;
  std::size_t boundary = 0;
  for (const auto& loop : topo.boundary_loops) boundary += loop.size();
  EXPECT_EQ(boundary, sampled);
  EXPECT_EQ(topo.boundary_loops.size(), pm.panel_names.size());
  for (const auto& panel : pm.edge_vertices)
    for (const auto& edge : panel)
      for (Index v : edge) EXPECT_TRUE(topo.is_boundary_vertex[v]);
}

TEST(Pattern, RectangleCountAreaAngles) {
  SewingPattern pattern;
  pattern.source = "rect";
  pattern.panels.push_back(rectangle("a", 1.0, 0.6));
  const double h = 0.05;
  const PatternMesh pm = triangulate_pattern(pattern, h);
  check_mesh(pm);
  const TriMesh& m = pm.mesh;
  const double ideal = 0.6 / (std::sqrt(3.0) / 4.0 * h * h);
  EXPECT_GT(m.num_triangles(), 0.6 * ideal);
  EXPECT_LT(m.num_triangles(), 1.6 * ideal);
  EXPECT_NEAR(m.total_material_area(), 0.6, 1e-12);
  double min_angle = 180.0;
  for (Index t = 0; t < m.num_triangles(); ++t) min_angle = std::min(min_angle, min_angle_deg(m, t));
  EXPECT_GE(min_angle, 20.0);
  // Outline: 20 + 12 + 20 + 12 samples; x = (u, 0).
  ASSERT_EQ(pm.edge_vertices.size(), 1u);
  EXPECT_EQ(pm.edge_vertices[0][0].size(), 21u);
  EXPECT_EQ(pm.edge_vertices[0][1].size(), 13u);
  for (Index i = 0; i < m.num_vertices(); ++i) {
    EXPECT_EQ(m.x.col(i), Vec3(m.u(0, i), m.u(1, i), 0.0));
    EXPECT_EQ(m.source_vertex[i], i);
  }
  std::printf("rectangle 1 x 0.6 at %.3f: %d vertices, %d triangles (ideal %.0f), min angle %.1f\n", h,
              m.num_vertices(), m.num_triangles(), ideal, min_angle);
}

TEST(Pattern, CurvedEdgesMatchAnalyticArea) {
  // Unit square whose top edge is a quadratic Bezier bulging up (area 1 + 2/3 * triangle), and a square whose
  // right edge is an outward half circle (area 1 + pi/8).
  const auto quad = parse(R"({"panels": {"q": {"vertices": [[0,0],[1,0],[1,1],[0,1]],
      "edges": [{}, {}, {"curve": {"type": "quadratic", "control": [0.5, 1.6]}}, {}]}}})");
  const PatternMesh pq = triangulate_pattern(quad, 0.02);
  check_mesh(pq);
  EXPECT_NEAR(pq.mesh.total_material_area() / (1.0 + 2.0 / 3.0 * 0.5 * 1.0 * 0.6), 1.0, 0.01);

  const auto arc = parse(R"({"panels": {"c": {"vertices": [[0,0],[1,0],[1,1],[0,1]],
      "edges": [{}, {"curve": {"type": "circle", "radius": 0.5, "right": true}}, {}, {}]}}})");
  const PatternMesh pc = triangulate_pattern(arc, 0.02);
  check_mesh(pc);
  EXPECT_NEAR(pc.mesh.total_material_area() / (1.0 + std::numbers::pi / 8.0), 1.0, 0.01);
  EXPECT_NEAR(pattern_edge_length(arc.panels[0], 1), std::numbers::pi / 2.0, 1e-12);
  // Every sample of the arc lies on the circle.
  for (Index v : pc.edge_vertices[0][1]) EXPECT_NEAR((pc.mesh.u.col(v) - Vec2(1.0, 0.5)).norm(), 0.5, 1e-12);

  // A concave (default: left) arc takes area away; a large arc adds more than a half circle.
  const auto concave = parse(R"({"panels": {"c": {"vertices": [[0,0],[1,0],[1,1],[0,1]],
      "edges": [{}, {"curve": {"type": "circle", "radius": 0.5}}, {}, {}]}}})");
  EXPECT_NEAR(triangulate_pattern(concave, 0.02).mesh.total_material_area() / (1.0 - std::numbers::pi / 8.0), 1.0,
              0.01);
  const auto large = parse(R"({"panels": {"c": {"vertices": [[0,0],[1,0],[1,1],[0,1]],
      "edges": [{}, {"curve": {"type": "circle", "radius": 0.6, "large": true, "right": true}}, {}, {}]}}})");
  const double r = 0.6, d = 0.5, hgt = std::sqrt(r * r - d * d);
  const double segment = r * r * (std::numbers::pi - std::asin(d / r)) + d * hgt;  // large segment beyond chord
  EXPECT_NEAR(triangulate_pattern(large, 0.02).mesh.total_material_area() / (1.0 + segment), 1.0, 0.01);

  // Cubic from (1,1) to (0,1), controls evenly spaced in x at height 1.3: x = 1 - t, y - 1 = 0.9 t (1 - t), so
  // the area above the chord is 0.9 / 6 = 0.15.
  const auto cubic = parse(R"({"panels": {"c": {"vertices": [[0,0],[1,0],[1,1],[0,1]],
      "edges": [{}, {}, {"curve": {"type": "cubic", "control": [[0.6666666666666666, 1.3], [0.3333333333333333, 1.3]]}}, {}]}}})");
  EXPECT_NEAR(triangulate_pattern(cubic, 0.02).mesh.total_material_area() / 1.15,
              1.0, 0.01);
}

TEST(Pattern, StitchedPanelsShareGroups) {
  // Two rectangles of different widths along the seam sampling (1.0 vs 1.05 long seam => counts differ), and a
  // rotated placement.
  const auto pattern = parse(R"({"panels": {
      "a": {"vertices": [[0,0],[0.5,0],[0.5,1.0],[0,1.0]]},
      "b": {"vertices": [[0,0],[0.4,0],[0.4,1.05],[0,1.05]],
            "placement": {"translation": [1, 0, 0], "rotation_deg": [0, 0, 30]}}},
    "stitches": [[{"panel": "a", "edge": 1}, {"panel": "b", "edge": 3}]]})");
  const double h = 0.1;
  const PatternMesh pm = triangulate_pattern(pattern, h);
  check_mesh(pm);
  ASSERT_EQ(pm.panel_names, (std::vector<std::string>{"a", "b"}));
  const auto& ea = pm.edge_vertices[0][1];
  const auto& eb = pm.edge_vertices[1][3];
  EXPECT_EQ(ea.size(), eb.size());
  EXPECT_EQ(ea.size(), 12u);  // round(1.05 / 0.1) = 11 pieces on both
  ASSERT_EQ(pm.stitch_pairs.size(), 1u);
  const auto& pairs = pm.stitch_pairs[0];
  ASSERT_EQ(pairs.size(), ea.size());
  // Default direction: a's start (0.5, 0) with b's end (0, 0); a's end (0.5, 1) with b's start (0, 1.05).
  EXPECT_EQ(pairs.front().first, ea.front());
  EXPECT_EQ(pairs.front().second, eb.back());
  EXPECT_EQ(pm.mesh.u.col(pairs.front().second), Vec2(0, 0));
  EXPECT_EQ(pm.mesh.u.col(pairs.back().second), Vec2(0, 1.05));
  for (std::size_t k = 0; k + 1 < pairs.size(); ++k)  // both run along the seam in step
    EXPECT_LT(pm.mesh.u(1, pairs[k].second), pm.mesh.u(1, pairs[k + 1].second));
  const auto groups = find_stitch_groups(pm.mesh);
  EXPECT_EQ(groups.size(), pairs.size());
  std::map<Index, std::size_t> group_of;
  for (std::size_t g = 0; g < groups.size(); ++g)
    for (Index v : groups[g]) group_of[v] = g;
  for (const auto& [va, vb] : pairs) {
    ASSERT_TRUE(group_of.count(va) && group_of.count(vb));
    EXPECT_EQ(group_of[va], group_of[vb]);
    EXPECT_EQ(pm.mesh.source_vertex[va], pm.mesh.source_vertex[vb]);
  }
  // Panel b is rotated 30 degrees about z and moved: its vertex (0.4, 0) lands at R (0.4, 0, 0) + (1, 0, 0).
  const Index corner = pm.edge_vertices[1][1].front();
  EXPECT_EQ(pm.mesh.u.col(corner), Vec2(0.4, 0));
  EXPECT_NEAR((pm.mesh.x.col(corner) - Vec3(1 + 0.4 * std::cos(std::numbers::pi / 6), 0.4 * 0.5, 0)).norm(), 0.0,
              1e-12);

  // same_direction pairs start with start.
  const auto same = parse(R"({"panels": {
      "a": {"vertices": [[0,0],[0.5,0],[0.5,1.0],[0,1.0]]},
      "b": {"vertices": [[0,0],[0.4,0],[0.4,1.0],[0,1.0]]}},
    "stitches": [{"edges": [{"panel": "a", "edge": 1}, {"panel": "b", "edge": 1}], "same_direction": true}]})");
  const PatternMesh ps = triangulate_pattern(same, h);
  EXPECT_EQ(ps.stitch_pairs[0].front().second, ps.edge_vertices[1][1].front());
  EXPECT_EQ(ps.stitch_pairs[0].back().second, ps.edge_vertices[1][1].back());
}

TEST(Pattern, CornerSharedByTwoSeamsIsOneGroup) {
  // A tube from one panel (edge 1 to edge 3) plus a second panel sewn to edge 2 (the top): the top corners end
  // two seams each and join all three vertices.
  const auto pattern = parse(R"({"panels": {
      "body": {"vertices": [[0,0],[1,0],[1,0.5],[0,0.5]]},
      "lid": {"vertices": [[0,0],[1,0],[1,0.3],[0,0.3]]}},
    "stitches": [[{"panel": "body", "edge": 1}, {"panel": "body", "edge": 3}],
                 [{"panel": "body", "edge": 2}, {"panel": "lid", "edge": 0}]]})");
  const PatternMesh pm = triangulate_pattern(pattern, 0.1);
  check_mesh(pm);
  const Index top_right = pm.edge_vertices[0][2].front(), top_left = pm.edge_vertices[0][2].back();
  EXPECT_EQ(pm.mesh.source_vertex[top_right], pm.mesh.source_vertex[top_left]);
  const auto groups = find_stitch_groups(pm.mesh);
  bool found = false;
  for (const auto& g : groups)
    if (std::find(g.begin(), g.end(), top_right) != g.end()) {
      EXPECT_EQ(g.size(), 4u);  // body's two top corners and lid's two bottom corners
      found = true;
    }
  EXPECT_TRUE(found);
}

TEST(Pattern, SkirtReadsAndTriangulates) {
  const SewingPattern skirt = read_pattern(skirt_path());
  ASSERT_EQ(skirt.panels.size(), 2u);
  ASSERT_EQ(skirt.stitches.size(), 2u);
  for (const PatternStitch& s : skirt.stitches) {
    auto panel = [&](const std::string& n) -> const PatternPanel& {
      return n == skirt.panels[0].name ? skirt.panels[0] : skirt.panels[1];
    };
    EXPECT_NEAR(pattern_edge_length(panel(s.a.panel), s.a.edge), pattern_edge_length(panel(s.b.panel), s.b.edge),
                1e-9);
  }
  const PatternMesh pm = triangulate_pattern(skirt, 0.02);
  check_mesh(pm);
  const TriMesh& m = pm.mesh;
  double min_angle = 180.0;
  for (Index t = 0; t < m.num_triangles(); ++t) min_angle = std::min(min_angle, min_angle_deg(m, t));
  EXPECT_GE(min_angle, 15.0);
  // Sewn pairs: same count on both sides of each seam, one stitch group per pair.
  const auto groups = find_stitch_groups(m);
  std::size_t pairs = 0;
  for (const auto& s : pm.stitch_pairs) pairs += s.size();
  EXPECT_EQ(groups.size(), pairs);
  // Waist (front edge 2) about 0.43 m, the garment between knee and waist, outside the hips (r >= 0.2).
  const Index front = pm.panel_names[0] == "front" ? 0 : 1;
  double waist = 0.0;
  const auto& w = pm.edge_vertices[front][2];
  for (std::size_t k = 0; k + 1 < w.size(); ++k) waist += (m.u.col(w[k + 1]) - m.u.col(w[k])).norm();
  EXPECT_NEAR(waist, 0.43, 0.01);
  for (Index i = 0; i < m.num_vertices(); ++i) {
    EXPECT_NEAR(m.x.col(i).head<2>().norm(), 0.25, 1e-9);
    EXPECT_GT(m.x(2, i), 0.45);
    EXPECT_LT(m.x(2, i), 1.03);
  }
  // Front faces +x: its centre line is at x = 0.25.
  EXPECT_GT(m.x(0, pm.edge_vertices[front][0][pm.edge_vertices[front][0].size() / 2]), 0.24);
  std::printf("skirt at 0.02: %d vertices, %d triangles, min angle %.1f\n", m.num_vertices(), m.num_triangles(),
              min_angle);
}

TEST(Pattern, WrapKeepsLengthsAndRadius) {
  const auto pattern = parse(R"({"panels": {"p": {"vertices": [[-0.3,0],[0.3,0],[0.3,0.4],[-0.3,0.4]],
      "wrap": {"radius": 0.2},
      "placement": {"translation": [0.2, 0, 1], "rotation_deg": [90, 0, 90]}}}})");
  const double h = 0.02;
  const PatternMesh pm = triangulate_pattern(pattern, h);
  check_mesh(pm);
  const TriMesh& m = pm.mesh;
  // The axis is the world z axis: every vertex at distance 0.2 from it, height = 1 + v.
  for (Index i = 0; i < m.num_vertices(); ++i) {
    EXPECT_NEAR(m.x.col(i).head<2>().norm(), 0.2, 1e-12);
    EXPECT_NEAR(m.x(2, i), 1.0 + m.u(1, i), 1e-12);
    // Arc length along the circumference is the panel's x.
    EXPECT_NEAR(0.2 * std::atan2(m.x(1, i), m.x(0, i)), m.u(0, i), 1e-12);
  }
  // Chords: shorter than the 2D edges by at most the chord factor of their horizontal extent.
  for (const Tri& t : m.tris)
    for (int k = 0; k < 3; ++k) {
      const Index a = t[k], b = t[(k + 1) % 3];
      const double l2 = (m.u.col(a) - m.u.col(b)).norm(), l3 = (m.x.col(a) - m.x.col(b)).norm();
      EXPECT_LE(l3, l2 * (1.0 + 1e-12));
      EXPECT_GE(l3, l2 * (1.0 - l2 * l2 / (24.0 * 0.2 * 0.2)) - 1e-12);
    }
  // Too wide for the cylinder.
  EXPECT_TRUE(throws_input_error(
      [] { parse(R"({"panels": {"p": {"vertices": [[0,0],[0.7,0],[0.7,0.4],[0,0.4]], "wrap": {"radius": 0.2}}}})"); },
      {"test.json", "panel \"p\"", "wrap"}));
}

TEST(Pattern, BadInput) {
  auto expect = [](const std::string& text, const std::vector<std::string>& parts) {
    EXPECT_TRUE(throws_input_error([&] { parse(text); }, parts)) << text;
  };
  const std::string sq = R"("vertices": [[0,0],[1,0],[1,1],[0,1]])";
  expect(R"({"panels": {"p": {"vertices": [[0,0],[1,0]]}}})", {"test.json", "panels.p.vertices", "at least 3"});
  expect(R"({"panels": {"p": {"vertices": [[0,0],[0,1],[1,1],[1,0]]}}})", {"test.json", "panel \"p\"", "clockwise"});
  expect(R"({"panels": {"p": {"vertices": [[0,0],[1,0],[0,1],[1,1]]}}})",
         {"test.json", "panel \"p\"", "intersects itself", "edge 1", "edge 3"});
  expect(R"({"panels": {"p": {"vertices": [[0,0],[1,0],[1,0],[0,1]]}}})", {"test.json", "panel \"p\" edge 1", "zero length"});
  expect(R"({"panels": {"p": {"vertices": [[0,0],[1,0],[1,"a"],[0,1]]}}})", {"test.json", "panels.p.vertices[2]"});
  expect(R"({"panels": {"p": {)" + sq + R"(, "colour": 1}}})", {"test.json", "panels.p.colour", "unknown key"});
  expect(R"({"panels": {"p": {)" + sq + R"(, "edges": [{}, {}]}}})", {"test.json", "panels.p.edges", "one entry per"});
  expect(R"({"panels": {"p": {)" + sq + R"(, "edges": [{}, {"curve": {"type": "spline"}}, {}, {}]}}})",
         {"test.json", "panels.p.edges[1].curve.type", "spline"});
  expect(R"({"panels": {"p": {)" + sq + R"(, "edges": [{}, {"curve": {"type": "circle", "radius": 0.2}}, {}, {}]}}})",
         {"test.json", "panel \"p\" edge 1", "half the chord"});
  expect(R"({"panels": {"p": {)" + sq + R"(, "edges": [{}, {"curve": {"type": "circle", "radius": -1}}, {}, {}]}}})",
         {"test.json", "panels.p.edges[1].curve.radius"});
  expect(R"({"panels": {"p": {)" + sq + R"(, "edges": [{}, {"curve": {"type": "quadratic", "control": [-3, 0.5]}}, {}, {}]}}})",
         {"test.json", "panel \"p\"", "intersects itself"});
  expect(R"({"panels": {"p": {)" + sq + R"(, "placement": {"translation": [0, 0]}}}})",
         {"test.json", "panels.p.placement.translation", "3 numbers"});
  expect(R"({"panels": {"p": {)" + sq + R"(, "placement": {"translation": [0, 0, 1e999]}}}})", {"test.json"});
  expect(R"({"panels": {}})", {"test.json", "panels", "at least one panel"});
  expect(R"({"panels": {"a/b": {)" + sq + R"(}}})", {"test.json", "panel \"a/b\""});
  const std::string two = R"({"panels": {"a": {)" + sq + R"(}, "b": {)" + sq + R"(}}, "stitches": )";
  expect(two + R"([[{"panel": "a", "edge": 1}, {"panel": "c", "edge": 3}]]})",
         {"test.json", "stitches[0]", "unknown panel \"c\""});
  expect(two + R"([[{"panel": "a", "edge": 1}, {"panel": "b", "edge": 4}]]})",
         {"test.json", "stitches[0]", "panel \"b\" edge 4", "out of range"});
  expect(two + R"([[{"panel": "a", "edge": 1}, {"panel": "b", "edge": -1}]]})",
         {"test.json", "stitches[0][1].edge"});
  expect(two + R"([[{"panel": "a", "edge": 1}, {"panel": "a", "edge": 1}]]})",
         {"test.json", "stitches[0]", "panel \"a\" edge 1", "itself"});
  expect(two + R"([[{"panel": "a", "edge": 1}, {"panel": "b", "edge": 3}], [{"panel": "b", "edge": 0}, {"panel": "a", "edge": 1}]]})",
         {"test.json", "stitches[1]", "panel \"a\" edge 1", "already stitched in stitches[0]"});
  expect(two + R"([[{"panel": "a", "edge": 1}]]})", {"test.json", "stitches[0]", "pair of edges"});
  expect(two + R"([{"edges": [{"panel": "a", "edge": 1}, {"panel": "b", "edge": 3}], "reverse": true}]})",
         {"test.json", "stitches[0].reverse", "unknown key"});
  expect(R"({"panels": {"a": {)" + sq + R"(}, "b": {"vertices": [[0,0],[1,0],[1,1.2],[0,1.2]]}}, "stitches": )" +
             R"([[{"panel": "a", "edge": 1}, {"panel": "b", "edge": 3}]]})",
         {"test.json", "stitches[0]", "panel \"a\" edge 1", "panel \"b\" edge 3", "10%"});
  // 5% differ: accepted (a warning).
  EXPECT_NO_THROW(parse(R"({"panels": {"a": {)" + sq + R"(}, "b": {"vertices": [[0,0],[1,0],[1,1.05],[0,1.05]]}},
      "stitches": [[{"panel": "a", "edge": 1}, {"panel": "b", "edge": 3}]]})"));

  const SewingPattern ok = parse(R"({"panels": {"p": {)" + sq + R"(}}})");
  for (double r : {0.0, -1.0, std::nan(""), kInf, 1e-9})
    EXPECT_TRUE(throws_input_error([&] { triangulate_pattern(ok, r); }, {"test.json", "resolution"})) << r;
  EXPECT_TRUE(throws_input_error([&] { triangulate_pattern(ok, 1e-4); }, {"test.json", "resolution", "vertices"}));
  // Missing file.
  EXPECT_TRUE(throws_input_error([] { read_pattern("/nonexistent/pattern.json"); }, {"/nonexistent/pattern.json"}));
}

TEST(Pattern, FileErrorsNameTheFile) {
  test::TempDir dir;
  const auto path = dir.file("bad.json", R"({"panels": {"p": {"vertices": [[0,0],[0,1],[1,1],[1,0]]}}})");
  EXPECT_TRUE(throws_input_error([&] { read_pattern(path); }, {path.string(), "panel \"p\"", "clockwise"}));
}

}  // namespace
}  // namespace mgcloth::mesh
