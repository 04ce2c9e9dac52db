#include "mesh/mesh_checks.hpp"

#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/mesh/topology.hpp>

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <map>

namespace mgcloth::mesh {
namespace {

using test::throws_input_error;

std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

/// An OBJ with positions and faces only (no vt), 1-based.
std::string positions_only_obj(const Mat3X& x, const std::vector<Tri>& tris) {
  std::string s;
  for (Index i = 0; i < x.cols(); ++i) s += fmt::format("v {} {} {}\n", x(0, i), x(1, i), x(2, i));
  for (const Tri& t : tris) s += fmt::format("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
  return s;
}

TriMesh small_unstructured() {
  RectangleSpec spec;
  spec.unstructured = true;
  spec.target_vertices = 400;
  spec.width = 1.3;
  spec.height = 0.7;
  spec.holes = {{{0.4, 0.35}, 0.1}};
  return make_rectangle(spec);
}

TEST(ObjIo, RoundTrip) {
  test::TempDir dir;
  const TriMesh m = small_unstructured();
  // Positions that differ from the rest state, with values that need all 17 digits.
  Mat3X x = m.x;
  for (Index i = 0; i < x.cols(); ++i) x.col(i) += Vec3(0.1, -1.0 / 3.0, std::sin(3.0 * m.u(0, i)) / 7.0);
  for (double scale : {1.0, 0.25}) {
    const auto path = dir.path(fmt::format("round_trip_{}.obj", scale));
    write_obj(path, m, x, scale);
    const TriMesh r = read_obj(path, scale);
    ASSERT_EQ(r.num_vertices(), m.num_vertices());
    EXPECT_EQ(r.tris, m.tris);
    // tinyobjloader's number parser is not always correctly rounded: allow a few ulps.
    EXPECT_LE((r.x - x).cwiseAbs().maxCoeff(), 1e-15 * x.cwiseAbs().maxCoeff() * 4);
    EXPECT_LE((r.u - m.u).cwiseAbs().maxCoeff(), 1e-15 * m.u.cwiseAbs().maxCoeff() * 4);
    for (Index i = 0; i < r.num_vertices(); ++i) EXPECT_EQ(r.source_vertex[i], i);
  }
  // Material coordinates are stored divided by the scale.
  const std::string text = read_text(dir.path("round_trip_0.25.obj"));
  EXPECT_NE(text.find(fmt::format("\nvt {} {}\n", m.u(0, 0) / 0.25, m.u(1, 0) / 0.25)), std::string::npos);
  // Atomic write: no temporary file is left behind.
  Index files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir.path(""))) ++files;
  EXPECT_EQ(files, 2);
}

TEST(ObjIo, WriteRejectsWrongSize) {
  test::TempDir dir;
  const TriMesh m = test::unit_square();
  EXPECT_THROW(write_obj(dir.path("bad.obj"), m, Mat3X::Zero(3, 3)), Error);
}

TEST(ObjIo, SeamsSplitVertices) {
  test::TempDir dir;
  // Two quads sharing the edge 2-5 in space; in UV they are separate charts, so positions 2 and 5 each get two
  // vertices. Quads are fanned from their first corner.
  const std::string obj =
      "# two panels sewn along one seam\n"
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0.5\nv 1 1 0\nv 2 1 0.5\n"
      "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
      "vt 3 0\nvt 4 0\nvt 4 1\nvt 3 1\n"
      "f 1/1 2/2 3/3 4/4\n"
      "f 2/5 5/6 7/7 3/8\n";
  const auto path = dir.file("seam.obj", obj);
  const TriMesh m = read_obj(path);
  // Position 6 (a duplicate of 3) is used by no face and dropped; positions 2 and 3 carry two vt each.
  EXPECT_EQ(m.num_vertices(), 8);
  EXPECT_EQ(m.num_triangles(), 4);
  EXPECT_EQ(m.source_vertex, (std::vector<Index>{0, 1, 1, 2, 2, 3, 4, 6}));
  EXPECT_TRUE(m.x.col(1) == m.x.col(2));
  EXPECT_TRUE(m.x.col(3) == m.x.col(4));
  EXPECT_NE(m.u.col(1), m.u.col(2));
  // (v, vt) order: vertex 1 = (v 2, vt 2), vertex 2 = (v 2, vt 5).
  EXPECT_EQ(m.u.col(1), Vec2(1, 0));
  EXPECT_EQ(m.u.col(2), Vec2(3, 0));
  // Fan of the first quad: (1, 2, 3), (1, 3, 4) in OBJ numbering.
  EXPECT_EQ(m.tris[0], (Tri{0, 1, 3}));
  EXPECT_EQ(m.tris[1], (Tri{0, 3, 5}));
  const Topology topo = build_topology(m);
  EXPECT_EQ(topo.boundary_loops.size(), 2u);  // the seam is open in material space
  EXPECT_NEAR(m.total_material_area(), 2.0, 1e-15);
}

TEST(ObjIo, PlanarWithoutTextureCoordinatesIsFlattened) {
  test::TempDir dir;
  const TriMesh flat = small_unstructured();
  // Rotate the sheet into a tilted plane and move it away from the origin.
  const Mat3 rot = (Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()) * Eigen::AngleAxisd(0.3, Vec3::UnitX()))
                       .toRotationMatrix();
  const Mat3X x = (rot * flat.x).colwise() + Vec3(3.0, -2.0, 5.0);
  const auto path = dir.file("tilted.obj", positions_only_obj(x, flat.tris));
  const TriMesh m = read_obj(path);
  ASSERT_EQ(m.num_vertices(), flat.num_vertices());
  EXPECT_EQ(m.tris, flat.tris);  // the file winds CCW about the plane normal, so nothing is flipped
  for (Index t = 0; t < m.num_triangles(); ++t)
    for (int k = 0; k < 3; ++k) {
      const Index a = m.tris[t][k], b = m.tris[t][(k + 1) % 3];
      EXPECT_NEAR((m.u.col(b) - m.u.col(a)).norm(), (flat.u.col(b) - flat.u.col(a)).norm(), 1e-12);
    }
  EXPECT_NEAR(m.total_material_area(), flat.total_material_area(), 1e-12);
  // tinyobjloader's number parser can be off by an ulp or so.
  EXPECT_LE((m.x - x).cwiseAbs().maxCoeff(), 4e-15 * x.cwiseAbs().maxCoeff());

  // A sheet in z = 0 gets u = (x, y) exactly, so material axes follow the world axes.
  const auto path_xy = dir.file("xy.obj", positions_only_obj(flat.x, flat.tris));
  const TriMesh xy = read_obj(path_xy);
  EXPECT_TRUE(xy.u == xy.x.topRows<2>());
  EXPECT_LE((xy.u - flat.u).cwiseAbs().maxCoeff(), 4e-15 * flat.u.cwiseAbs().maxCoeff());
}

TEST(ObjIo, NonPlanarWithoutTextureCoordinatesFails) {
  test::TempDir dir;
  TriMesh m = small_unstructured();
  m.x.row(2) = 0.1 * m.x.row(0).array().square().matrix();
  const auto path = dir.file("curved.obj", positions_only_obj(m.x, m.tris));
  EXPECT_TRUE(throws_input_error([&] { read_obj(path); },
                                 {path.string(), "has no texture coordinates (vt) and is not planar",
                                  "cannot infer material coordinates"}));
}

TEST(ObjIo, MissingFile) {
  test::TempDir dir;
  const auto path = dir.path("nowhere.obj");
  EXPECT_TRUE(throws_input_error([&] { read_obj(path); }, {path.string() + ": cannot open file"}));
}

TEST(ObjIo, GarbageFile) {
  test::TempDir dir;
  std::string bytes;
  for (int i = 0; i < 4096; ++i) bytes += static_cast<char>((i * 7919 + 13) % 256);
  const auto binary = dir.file("binary.obj", bytes);
  EXPECT_TRUE(throws_input_error([&] { read_obj(binary); }, {binary.string()}));
  const auto prose = dir.file("prose.obj", "This is not a mesh.\nIt has words, not faces.\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj(prose); }, {prose.string(), "no faces"}));
  const auto bad_face = dir.file("bad_face.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj(bad_face); }, {bad_face.string(), "line 4", "cannot parse the `f` statement"}));
  const auto short_face = dir.file("short.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj(short_face); }, {short_face.string(), "line 5", "fewer than three"}));
}

// tinyobjloader alone reads all of these without a word: a bad number as 0, a short statement padded with zeros,
// "3.5" and "3x" as 3, 4294967299 wrapped to 3. Each is an error naming the line, also for `mgcloth info`
// (check = false), and a non-finite coordinate is reported as such, not as the zero-area triangle it would make.
TEST(ObjIo, MalformedStatementsNameTheLine) {
  test::TempDir dir;
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  const struct {
    std::string name, text;
    std::vector<std::string> parts;
  } cases[] = {
      {"nan", "v nan 1 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", {"line 1", "`v` coordinate 1 is not finite", "\"nan\""}},
      {"inf", tri + "v 1 -inf 0\nf 1 2 3\n", {"line 4", "`v` coordinate 2 is not finite", "\"-inf\""}},
      {"overflow", tri + "v 1 1 1e400\nf 1 2 3\n", {"line 4", "coordinate 3 is not finite", "1e400"}},
      {"garbage", "v 0 0 0\nv 1 0 0\nv 0 abc 0\nf 1 2 3\n", {"line 3", "`v` coordinate 2 is not a number", "\"abc\""}},
      {"trailing", "v 0 0 0\nv 1 0 0\nv 0 1.5x 0\nf 1 2 3\n", {"line 3", "coordinate 2 is not a number", "1.5x"}},
      {"short_v", "v 0 0 0\nv 1 0 0\nv 0 1\nf 1 2 3\n", {"line 3", "`v` needs 3 coordinates", "got 2 numbers"}},
      {"long_v", "v 0 0 0 1 2\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", {"line 1", "`v` needs 3 coordinates", "got 5"}},
      {"short_vt", tri + "vt 0 0\nvt 1\nvt 0 1\nf 1/1 2/2 3/3\n", {"line 5", "`vt` needs 2 coordinates", "got 1 number"}},
      {"nan_vt", tri + "vt 0 0\nvt 1 0\nvt NaN 1\nf 1/1 2/2 3/3\n", {"line 6", "`vt` coordinate 1 is not finite"}},
      {"bad_vn", tri + "vn 0 0 x\nf 1//1 2//1 3//1\n", {"line 4", "`vn` coordinate 3 is not a number"}},
      {"fraction", tri + "f 1 2 3.5\n", {"line 4", "`f` statement", "corner 3 (\"3.5\")", "not an integer"}},
      {"suffix", tri + "f 1 2 3x\n", {"line 4", "corner 3 (\"3x\")", "vertex index is not an integer"}},
      {"wrap", tri + "f 1 2 4294967299\n", {"line 4", "corner 3 (\"4294967299\")", "out of range"}},
      {"huge", tri + "f 1 2 99999999999999999999999\n", {"line 4", "corner 3", "out of range"}},
      {"zero", tri + "f 0 1 2\n", {"line 4", "corner 1", "is 0"}},
      {"vt_index", tri + "vt 0 0\nf 1/1 2/1x 3/1\n", {"line 5", "corner 2", "texture-coordinate index is not an integer"}},
      {"empty_vt", tri + "f 1/ 2/ 3/\n", {"line 4", "corner 1", "texture-coordinate index is missing"}},
      {"four_indices", tri + "f 1/1/1/1 2 3\n", {"line 4", "corner 1", "more than three indices"}},
      {"nul", tri + std::string("f 1 2 3\0\n", 9), {"line 4", "corner 3 (\"3?\")"}},
  };
  for (const auto& c : cases) {
    const auto path = dir.file(c.name + ".obj", c.text);
    std::vector<std::string> parts = c.parts;
    parts.push_back(path.string() + ": line ");
    EXPECT_TRUE(throws_input_error([&] { read_obj(path); }, parts)) << c.name;
    EXPECT_TRUE(throws_input_error([&] { read_obj(path, 1.0, /*check=*/false); }, parts)) << c.name;
  }
  // What stays legal: comments after a statement, a leading '+', CRLF line ends, a weight or a colour on `v`,
  // relative indices, an underflowing coordinate (it reads as the nearest double, 0).
  const auto ok = dir.file("ok.obj",
                           "v +0 0 0 1 # origin\r\nv 1 0 0 0.5 0.5 0.5\r\nv 0 1 1e-400\r\nvt 0 0 0\r\nvt 1 0\r\n"
                           "vt 0 1\r\nf -3/-3 -2/-2 -1/-1\r\n");
  const TriMesh m = read_obj(ok);
  EXPECT_EQ(m.num_triangles(), 1);
  EXPECT_EQ(m.x(2, 2), 0.0);
}

TEST(ObjIo, FaceIndexOutOfRange) {
  test::TempDir dir;
  const auto path = dir.file("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\nf 1 2 3\nf 2 4 9\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj(path); },
                                 {path.string(), "line 7", "refers to vertex 9", "has 4 vertices"}));
  const auto vt_path = dir.file("vt_range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nf 1/1 2/2 3/3\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj(vt_path); }, {vt_path.string(), "line 6", "texture coordinate 3"}));
  const auto negative = dir.file("negative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -5\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj(negative); }, {negative.string(), "line 4", "before the first vertex"}));
  const auto normal = dir.file("normal.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj(normal); }, {normal.string(), "vertex normal (vn)"}));
}

TEST(ObjIo, MixedTextureCoordinates) {
  test::TempDir dir;
  const auto path =
      dir.file("mixed.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\nf 2 4 3\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj(path); }, {path.string(), "line 9", "texture coordinates"}));
}

TEST(ObjIo, DegenerateTriangle) {
  test::TempDir dir;
  // The second face's texture coordinates are collinear.
  const auto path = dir.file("degenerate.obj",
                             "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 -1 0\n"
                             "vt 0 0\nvt 1 0\nvt 0 1\nvt 0.5 0\n"
                             "f 1/1 2/2 3/3\nf 1/1 4/4 2/2\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj(path); },
                                 {path.string(), "triangle 1 (vertices 0, 3, 1)", "zero area in material space"}));
  // check = false returns it as read.
  const TriMesh m = read_obj(path, 1.0, false);
  EXPECT_EQ(m.num_triangles(), 2);
}

TEST(ObjIo, NonManifoldEdge) {
  test::TempDir dir;
  const auto path = dir.file("fin.obj", positions_only_obj(test::flat_mesh({{0, 0}, {1, 0}, {0.5, 1}, {0.5, -1}, {0.6, 2}},
                                                                            {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}})
                                                               .x,
                                                           {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}}));
  EXPECT_TRUE(throws_input_error([&] { read_obj(path); }, {path.string(), "edge (0, 1)", "3 triangles"}));
}

TEST(ObjIo, MaterialsAndGroupsAreIgnored) {
  test::TempDir dir;
  const auto path = dir.file("blender.obj",
                             "# Blender export\nmtllib missing.mtl\no Cloth\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                             "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nusemtl Fabric\ns off\n"
                             "f 1/1/1 2/2/1 3/3/1\ng second\nf 1/1/1 3/3/1 4/4/1\n");
  const TriMesh m = read_obj(path, 0.5);
  EXPECT_EQ(m.num_vertices(), 4);
  EXPECT_EQ(m.num_triangles(), 2);
  EXPECT_NEAR(m.total_material_area(), 0.25, 1e-15);
}

TEST(ObjIo, RejectsBadScale) {
  test::TempDir dir;
  const auto path = dir.file("s.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj(path, 0.0); }, {path.string(), "material_scale"}));
}

// An obstacle's surface: a closed cube with UV seams (vt differing per face) stays one closed surface numbered by
// position, polygons are fanned, unused and repeated vertices and zero-area faces are dropped, and what a cloth would
// refuse (not planar, non-manifold, inconsistently oriented) is accepted.
TEST(ObjIo, SurfaceOfAClosedCubeWithSeams) {
  test::TempDir dir;
  std::string obj = "v 9 9 9\n";  // used by no face
  for (int i = 0; i < 8; ++i) obj += fmt::format("v {} {} {}\n", i & 1, (i >> 1) & 1, (i >> 2) & 1);
  obj += "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n";
  // Six quads (1-based: vertex i of the loop above is i + 2), each with its own vt: every edge is a UV seam. The
  // last face winds the wrong way.
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 5, 7, 3}};
  for (const auto& q : quads)
    obj += fmt::format("f {}/1 {}/2 {}/3 {}/4\n", q[0] + 2, q[1] + 2, q[2] + 2, q[3] + 2);
  obj += "f 2/1 2/2 3/3\n";  // a repeated vertex
  const auto path = dir.file("cube.obj", obj);
  const Surface s = read_obj_surface(path);
  EXPECT_EQ(s.x.cols(), 8);
  EXPECT_EQ(s.tris.size(), 12u);
  // Every edge of the 12 cube triangles is shared by exactly two of them: the seams did not split it.
  std::map<std::pair<Index, Index>, int> edges;
  for (size_t t = 0; t < 12; ++t)
    for (int k = 0; k < 3; ++k) {
      const Index a = s.tris[t][k], b = s.tris[t][(k + 1) % 3];
      ++edges[{std::min(a, b), std::max(a, b)}];
    }
  EXPECT_EQ(edges.size(), 18u);
  for (const auto& [e, n] : edges) EXPECT_EQ(n, 2);
  // The corners of the cube, each once, at its position in the file.
  EXPECT_EQ(s.x.col(0), Vec3(0, 0, 0));
  EXPECT_EQ(s.x.rowwise().maxCoeff(), Vec3(1, 1, 1));
}

TEST(ObjIo, SurfaceDropsZeroAreaFacesAndRejectsBadFiles) {
  test::TempDir dir;
  const auto path = dir.file("sliver.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 1 1 3\n");
  const Surface s = read_obj_surface(path);
  ASSERT_EQ(s.tris.size(), 1u);
  EXPECT_EQ(s.tris[0], (Tri{0, 1, 2}));
  const auto flat = dir.file("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj_surface(flat); }, {flat.string(), "every face has zero area"}));
  const auto missing = dir.path("nowhere.obj");
  EXPECT_TRUE(throws_input_error([&] { read_obj_surface(missing); }, {missing.string() + ": cannot open file"}));
  const auto prose = dir.file("prose.obj", "This is not a mesh.\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj_surface(prose); }, {prose.string(), "no faces"}));
  const auto nan = dir.file("nan.obj", "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj_surface(nan); }, {nan.string(), "line 1"}));
  const auto range = dir.file("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
  EXPECT_TRUE(throws_input_error([&] { read_obj_surface(range); }, {range.string(), "line 4", "vertex 7"}));
}

}  // namespace
}  // namespace mgcloth::mesh
