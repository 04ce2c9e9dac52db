#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/quad_mesh.hpp>

#include <gtest/gtest.h>

#include <string>
#include <unistd.h>

#include <cmath>
#include <map>
#include <set>
#include <algorithm>
#include <filesystem>
#include <fstream>

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
  EXPECT_THROW(make_notched_square(1.0, 0.3, 4, false), InputError);  // 1.2 cells need the ghost layer's lines
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

// A notch of 1.2 cells: one notch cell, grid lines spaced so that the limit lines fall at 0.7 m.
TEST(QuadMesh, NonWholeNotchUsesNonUniformGridLines) {
  const QuadMesh m = make_notched_square(1.0, 0.3, 4);
  Index real = 0;
  for (Index f = 0; f < m.num_faces(); ++f) real += m.is_ghost_face(f) ? 0 : 1;
  EXPECT_EQ(real, 15);
  // (c_{i-1} + 4 c_i + c_{i+1}) / 6 at the interior lines reproduces 0.7/3, 1.4/3, 0.7.
  std::vector<double> c;
  for (Index v = 0; v < m.num_vertices(); ++v)
    if (std::abs(m.u(1, v) - m.u.row(1).minCoeff()) < 1e-12) c.push_back(m.u(0, v));
  std::sort(c.begin(), c.end());
  ASSERT_EQ(c.size(), 7u);
  const std::vector<double> lines{0.0, 0.7 / 3, 1.4 / 3, 0.7, 1.0};
  for (int i = 0; i <= 4; ++i) EXPECT_NEAR((c[i] + 4 * c[i + 1] + c[i + 2]) / 6.0, lines[i], 1e-14) << i;
}

TEST(QuadMesh, GhostLayerOfAGeneralMeshMatchesTheGridGenerator) {
  QuadMesh bare = make_quad_rectangle(2.0, 1.0, 4, 2, false);
  add_ghost_layer(bare);
  const QuadMesh grid = make_quad_rectangle(2.0, 1.0, 4, 2, true);
  expect_valid(bare, 0.25);
  EXPECT_EQ(bare.num_vertices(), grid.num_vertices());
  EXPECT_EQ(bare.num_faces(), grid.num_faces());
  EXPECT_EQ(bare.num_real_vertices(), grid.num_real_vertices());
  std::set<std::pair<long, long>> a, b;
  for (Index v = 0; v < bare.num_vertices(); ++v) {
    a.insert({std::lround(bare.u(0, v) * 4), std::lround(bare.u(1, v) * 4)});
    b.insert({std::lround(grid.u(0, v) * 4), std::lround(grid.u(1, v) * 4)});
  }
  EXPECT_EQ(a, b);
  EXPECT_EQ(real_boundary_edges(bare).size(), 12u);
  QuadMesh notched = make_notched_square(1.0, 0.5, 4, false);
  EXPECT_THROW(add_ghost_layer(notched), InputError);  // a concave corner
}

TEST(QuadMesh, ValidateNamesTheBadElement) {
  QuadMesh m = make_quad_rectangle(1.0, 1.0, 2, 2, false);
  m.quads[1][2] = m.quads[1][0];
  EXPECT_THROW(validate(m, "x.obj"), InputError);
  m = make_quad_rectangle(1.0, 1.0, 2, 2, false);
  m.x(0, 3) = std::nan("");
  EXPECT_THROW(validate(m, "x.obj"), InputError);
  m = make_quad_rectangle(1.0, 1.0, 2, 2, false);
  std::swap(m.quads[0][1], m.quads[0][3]);  // flipped orientation
  EXPECT_THROW(validate(m, "x.obj"), InputError);
  try {
    m = make_quad_rectangle(1.0, 1.0, 2, 2, false);
    m.quads[2][0] = 40;
    validate(m, "x.obj");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("x.obj: quad 3"), std::string::npos) << e.what();
  }
}

std::filesystem::path write_temp(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / ("mgcloth_quad_" + std::to_string(::getpid()) + "_" + name);
  std::ofstream(path) << text;
  return path;
}

std::string error_of(const std::filesystem::path& path, bool ghosts = true) {
  try {
    read_quad_obj(path, 1.0, ghosts);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// A 2 x 1 quad strip with vt: read with its material coordinates, ghost layer added (a 4 x 3 grid of cells), or
// with the ghost faces given as group "ghost".
TEST(QuadObj, ReadsQuadsWithMaterialCoordinatesAndGhosts) {
  const std::string strip =
      "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\n"
      "vt 0 0\nvt 0.5 0\nvt 1 0\nvt 0 0.5\nvt 0.5 0.5\nvt 1 0.5\n";
  const auto path = write_temp("strip.obj", strip + "f 1/1 2/2 5/5 4/4\nf 2/2 3/3 6/6 5/5\n");
  const QuadMesh m = read_quad_obj(path, 2.0);
  EXPECT_EQ(m.num_faces(), 4 * 3);
  EXPECT_EQ(m.num_vertices(), 5 * 4);
  EXPECT_EQ(m.num_real_vertices(), 6);
  EXPECT_NEAR(m.u(0, 2), 2.0, 1e-15);  // vt 1 0 scaled by 2
  EXPECT_NEAR(m.u(1, 5), 1.0, 1e-15);
  EXPECT_NEAR(m.u.row(0).minCoeff(), -1.0, 1e-15);  // ghost ring, one cell of 1 m out
  expect_valid(m, 1.0);
  const QuadMesh bare = read_quad_obj(path, 1.0, false);
  EXPECT_EQ(bare.num_faces(), 2);
  EXPECT_TRUE(bare.ghost_face.empty());

  // Ghost faces modelled in the file: the real strip with a ghost quad on each side.
  const auto given = write_temp("given.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 0 0\nv 2 1 0\n"
                                             "f 1 2 4 3\ng ghost\nf 2 5 6 4\n");
  const QuadMesh g = read_quad_obj(given);
  ASSERT_EQ(g.num_faces(), 2);
  EXPECT_FALSE(g.is_ghost_face(0));
  EXPECT_TRUE(g.is_ghost_face(1));
  EXPECT_TRUE(g.is_ghost_vertex(4));
  EXPECT_FALSE(g.is_ghost_vertex(1));
}

TEST(QuadObj, BadFilesNameTheFileAndElement) {
  EXPECT_NE(error_of("/nonexistent/mesh.obj").find("/nonexistent/mesh.obj"), std::string::npos);
  const auto tri = write_temp("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\nf 1 2 3\n");
  EXPECT_NE(error_of(tri).find("face 2 has 3 corners"), std::string::npos) << error_of(tri);
  const auto seam = write_temp("seam.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 0 0\nv 2 1 0\n"
                                           "vt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvt 5 5\nvt 2 0\nvt 2 1\n"
                                           "f 1/1 2/2 4/4 3/3\nf 2/5 5/6 6/7 4/4\n");
  EXPECT_NE(error_of(seam).find("point 2 has two texture coordinates"), std::string::npos) << error_of(seam);
  const auto nonmanifold = write_temp("nm.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 1 0 1\nv 0 0 1\n"
                                                "v 0 0 -1\nv 1 0 -1\nf 1 2 4 3\nf 2 1 6 5\nf 1 2 8 7\n");
  EXPECT_NE(error_of(nonmanifold, false).find("edge (1, 2)"), std::string::npos) << error_of(nonmanifold, false);
  const auto unused = write_temp("unused.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 5 5 5\nf 1 2 4 3\n");
  EXPECT_NE(error_of(unused).find("point 5 belongs to no quad"), std::string::npos) << error_of(unused);
}

// Found by fuzz/fuzz_obj: tinyobjloader only warns about a vt index past the last vt line, and the reader read
// past the end of the texture coordinates (a heap overflow under AddressSanitizer, garbage material coordinates
// without it).
TEST(QuadObj, TextureIndexPastTheLastVtIsAnError) {
  const auto past = write_temp("vt_past.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\n"
                                              "f 1/1 2/2 3/3 4/4\n");
  EXPECT_EQ(error_of(past), past.string() + ": face 1 refers to texture coordinate 3, but there are 2 (vt lines)");
  // The input the fuzzer found, as it found it.
  const auto found = write_temp("vt_fuzz.obj", "# a quad with texture coordinates\nv 0 0 0\nv 1 0 0\nv 1 1 0.5\n"
                                               "v 0 1 0.5\nvv 0 0\nvt 1 0\nvt 1 1.1\nvt'0 1.1\nvn 0 0 1\n"
                                               "g cl\xefth\nf 1/1/1 2/2/1 3/3/1 4/4/1\n");
  EXPECT_NE(error_of(found).find("face 1 refers to texture coordinate 3, but there are 2"), std::string::npos)
      << error_of(found);
}

// The control mesh is read as strictly as a cloth's OBJ (check_obj_statements): tinyobjloader alone reads "nan" as
// 0 and "4x" as 4.
TEST(QuadObj, MalformedStatementsNameTheLine) {
  const auto nan = write_temp("nan.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 nan 0\nf 1 2 4 3\n");
  EXPECT_NE(error_of(nan).find("nan.obj: line 4: `v` coordinate 2 is not finite"), std::string::npos) << error_of(nan);
  const auto index = write_temp("index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4x 3\n");
  EXPECT_NE(error_of(index).find("index.obj: line 5: cannot parse the `f` statement: corner 3"), std::string::npos)
      << error_of(index);
}

}  // namespace
}  // namespace mgcloth::mesh
