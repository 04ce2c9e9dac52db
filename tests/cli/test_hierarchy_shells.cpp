// `mgcloth hierarchy` on scenes with shells: the subdivision levels of each shell, with counts checked against the
// Catmull-Clark rule rather than against the library's own hierarchy.
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/json.hpp>

#include <fmt/format.h>

#include "cli_run.hpp"
#include "raster.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

namespace fs = std::filesystem;

namespace {

class HierarchyShells : public mgcloth::test::TempDirTest {
 protected:
  HierarchyShells() : TempDirTest("mgcloth_hierarchy_shells_") {}
  std::string write(const std::string& name, const std::string& content) {
    std::ofstream(dir / name) << content;
    return (dir / name).string();
  }
};

mgcloth::test::CliResult run(const std::string& args) { return mgcloth::test::run_cli(args); }

/// One level of a control mesh with one ghost layer around an n_u × n_v grid of real cells.
struct Expected {
  long points, ghost_points, faces, ghost_faces;
};

/// Subdividing quadruples the real cells (every quad becomes four); the ghost layer stays one ring of cells, corners
/// included, so the mesh is a grid of (n_u + 2) × (n_v + 2) cells and (n_u + 3) × (n_v + 3) points, of which the
/// (n_u + 1) × (n_v + 1) points of the real region are real.
Expected grid_level(long cells_u, long cells_v, int subdivisions) {
  const long nu = cells_u << subdivisions, nv = cells_v << subdivisions;
  const long points = (nu + 3) * (nv + 3), faces = (nu + 2) * (nv + 2);
  return {points, points - (nu + 1) * (nv + 1), faces, faces - nu * nv};
}

/// The table row of `level` (finest first) as printed: level, subdivision level, points, ghost points, faces,
/// ghost faces.
bool has_row(const std::string& out, int level, int subdivision, const Expected& e) {
  const std::regex row(fmt::format(R"((^|\n) +{} +{} +{} +{} +{} +{}\n)", level, subdivision, e.points, e.ghost_points,
                                   e.faces, e.ghost_faces));
  return std::regex_search(out, row);
}

}  // namespace

// The shipped trampoline: a 4 × 4 rectangle subdivided to its scene's level. Every level's control points and faces
// (ghost ones apart too) in the table and in hierarchy.json, finest first, and one panel per level in levels.png.
TEST_F(HierarchyShells, TheTrampolinesSubdivisionLevelsWithTheirCounts) {
  const std::string scene = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_trampoline.json";
  const mgcloth::Json spec = mgcloth::load_json(scene).at("shells").at(0);
  const long cells_u = spec.at("control_mesh").at("cells_u"), cells_v = spec.at("control_mesh").at("cells_v");
  const int levels = spec.at("level");
  ASSERT_GE(levels, 3);

  const auto r = run("hierarchy " + scene + " --out " + (dir / "h").string() + " --png-size 128");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find(fmt::format("(shell \"trampoline\"): {} subdivision levels", levels)), std::string::npos) << r.out;
  for (int l = 0; l < levels; ++l)
    EXPECT_TRUE(has_row(r.out, l, levels - l, grid_level(cells_u, cells_v, levels - 1 - l))) << l << "\n" << r.out;

  const fs::path out = dir / "h" / "trampoline";
  const auto report = mgcloth::load_json((out / "hierarchy.json").string());
  EXPECT_EQ(report.at("shell"), "trampoline");
  const auto& lv = report.at("levels");
  ASSERT_EQ(lv.size(), static_cast<size_t>(levels));
  for (int l = 0; l < levels; ++l) {
    const Expected e = grid_level(cells_u, cells_v, levels - 1 - l);
    EXPECT_EQ(lv[l].at("level").get<int>(), l);
    EXPECT_EQ(lv[l].at("subdivision_level").get<int>(), levels - l);
    EXPECT_EQ(lv[l].at("control_points").get<long>(), e.points) << l;
    EXPECT_EQ(lv[l].at("ghost_points").get<long>(), e.ghost_points) << l;
    EXPECT_EQ(lv[l].at("faces").get<long>(), e.faces) << l;
    EXPECT_EQ(lv[l].at("ghost_faces").get<long>(), e.ghost_faces) << l;
    EXPECT_EQ(lv[l].at("dofs").get<long>(), 3 * e.points) << l;
  }
  // At the scene's level 4: 32 × 32 real quads, 35 × 35 control points (3,675 dofs, the paper's Table 3 size).
  if (levels == 4 && cells_u == 4 && cells_v == 4) {
    EXPECT_EQ(lv[0].at("control_points").get<long>(), 1225);
  }

  const auto img = mgcloth::cli::Image::read_png(out / "levels.png");
  EXPECT_EQ(img.width(), 128 * levels);
  long dark = 0, blue = 0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) {
      const auto p = img.pixel(x, y);
      dark += p.r < 128 && p.g < 128 && p.b < 128;
      blue += p.b > 150 && p.r < 100;
    }
  EXPECT_GT(dark, 500);
  EXPECT_GT(blue, 100 * levels);  // the real region's boundary on every panel
}

// The re-entrant corner (a notched square): every subdivision quadruples the real faces, whatever the ghost layer
// around the notch adds.
TEST_F(HierarchyShells, EverySubdivisionQuadruplesTheRealFaces) {
  const std::string scene = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_reentrant.json";
  const auto r = run("hierarchy " + scene + " --out " + dir.string() + " --png-size 64");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto lv = mgcloth::load_json((dir / "reentrant" / "hierarchy.json").string()).at("levels");
  ASSERT_GE(lv.size(), 3u);
  const auto real_faces = [&](size_t l) { return lv[l].at("faces").get<long>() - lv[l].at("ghost_faces").get<long>(); };
  EXPECT_EQ(real_faces(lv.size() - 1), 15);  // 4 × 4 cells, the notch one
  for (size_t l = 0; l + 1 < lv.size(); ++l) {
    EXPECT_EQ(real_faces(l), 4 * real_faces(l + 1)) << l;
    EXPECT_GT(lv[l].at("control_points").get<long>(), lv[l + 1].at("control_points").get<long>()) << l;
  }
}

// A scene with a cloth and a shell shows both, each in its folder; --body picks either by name, --cloth only cloths,
// and a name that is no body is refused in one line naming the bodies.
TEST_F(HierarchyShells, BodiesOfASceneAreChosenByName) {
  const auto scene = write("both.json", R"({ "cloths": [ { "name": "sheet", "mesh": { "vertices": 300 } } ],
      "shells": [ { "name": "plate", "control_mesh": { "generator": "rectangle", "cells_u": 3, "cells_v": 2 },
                    "level": 2 } ] })");
  const auto all = run("hierarchy " + scene + " --max-coarse 150 --min-coarse 30 --png-size 64 --out " + (dir / "all").string());
  ASSERT_EQ(all.code, 0) << all.out;
  EXPECT_TRUE(fs::exists(dir / "all" / "sheet" / "level0.obj"));
  EXPECT_TRUE(fs::exists(dir / "all" / "plate" / "hierarchy.json"));
  EXPECT_TRUE(has_row(all.out, 0, 2, grid_level(3, 2, 1))) << all.out;
  EXPECT_TRUE(has_row(all.out, 1, 1, grid_level(3, 2, 0))) << all.out;

  const auto shell = run("hierarchy " + scene + " --body plate --png-size 64 --out " + (dir / "shell").string());
  ASSERT_EQ(shell.code, 0) << shell.out;
  EXPECT_TRUE(fs::exists(dir / "shell" / "plate" / "levels.png"));
  EXPECT_FALSE(fs::exists(dir / "shell" / "sheet"));
  const auto cloth = run("hierarchy " + scene + " --cloth sheet --png-size 64 --out " + (dir / "cloth").string());
  ASSERT_EQ(cloth.code, 0) << cloth.out;
  EXPECT_TRUE(fs::exists(dir / "cloth" / "sheet" / "levels.png"));
  EXPECT_FALSE(fs::exists(dir / "cloth" / "plate"));

  const auto bad = run("hierarchy " + scene + " --body nope --out " + (dir / "bad").string());
  EXPECT_EQ(bad.code, 1) << bad.out;
  EXPECT_NE(bad.out.find("--body: no cloth or shell named \"nope\""), std::string::npos) << bad.out;
  EXPECT_NE(bad.out.find("\"sheet\", \"plate\""), std::string::npos) << bad.out;
  EXPECT_EQ(std::count(bad.out.begin(), bad.out.end(), '\n'), 1) << bad.out;
  EXPECT_FALSE(fs::exists(dir / "bad"));
  EXPECT_EQ(run("hierarchy " + scene + " --cloth plate --out " + (dir / "bad").string()).code, 1);
}
