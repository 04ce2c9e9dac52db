// Drives the built `mgcloth` executable the way a user does: exit codes, one-line errors, outputs on disk.
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/json.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/bodies/shell_body.hpp>

#include <fmt/format.h>

#include "cli_run.hpp"
#include "raster.hpp"

#include <gtest/gtest.h>

#include <string>
#include <unistd.h>

#include <regex>

#include <array>
#include <cstdio>
#include <filesystem>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <sys/wait.h>

namespace fs = std::filesystem;

namespace {
using Result = mgcloth::test::CliResult;

Result run(const std::string& args) { return mgcloth::test::run_cli(args); }

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() / ("mgcloth_cli_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
                                           std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string write(const std::string& name, const std::string& content) {
    std::ofstream(dir / name) << content;
    return (dir / name).string();
  }
  /// A small hanging-cloth scene (fast) writing into `out`.
  std::string small_scene(const std::string& extra = "") {
    return write("scene.json", R"({ "frames": 4, "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 120 },
      "pins": [ { "points": [[0, 1], [1, 1]] } ] } ],
      "obstacles": [ { "shape": { "type": "sphere", "radius": 0.2 }, "position": [0.5, 0.5, -0.3] } ] )" + extra + "}");
  }
  fs::path dir;
};
}  // namespace

TEST_F(Cli, RunWritesFramesStatsResolvedSceneAndCheckpoint) {
  const auto r = run("run " + small_scene() + " --out " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.out;
  for (int f = 0; f <= 4; ++f) EXPECT_TRUE(fs::exists(dir / "out" / fmt::format("frame_{:05d}.obj", f))) << f;
  EXPECT_TRUE(fs::exists(dir / "out" / "scene.resolved.json"));
  EXPECT_TRUE(fs::exists(dir / "out" / "checkpoint.bin"));
  const auto stats = mgcloth::read_file(dir / "out" / "stats.csv");
  EXPECT_EQ(stats.rfind("frame,step,sim_time,solver,iterations,energy,grad_norm,wall_ms", 0), 0u);
  EXPECT_EQ(std::count(stats.begin(), stats.end(), '\n'), 5);
  // A cloth without seams leaves seam_gap empty rather than claiming a gap of 0; the last column is the solver's
  // estimate of its velocity error, a number (or inf) whatever the stop rule.
  std::istringstream lines(stats);
  std::string header, row;
  std::getline(lines, header);
  std::getline(lines, row);
  EXPECT_TRUE(header.ends_with(",seam_gap,velocity_error,velocity_rms_error,true_velocity_error,true_velocity_rms")) << header;
  // Without --check-accuracy the two last columns are empty; before them the decrement's RMS and the step estimate.
  ASSERT_TRUE(row.ends_with(",,")) << row;
  row.resize(row.size() - 2);
  const size_t last = row.rfind(',');
  ASSERT_NE(last, std::string::npos);
  EXPECT_GE(std::stod(row.substr(last + 1)), 0.0) << "velocity_rms_error, fmg measures it: " << row;
  row.resize(last);
  const size_t before = row.rfind(',');
  ASSERT_NE(before, std::string::npos);
  EXPECT_EQ(row[before - 1], ',') << "seam_gap empty: " << row;
  const std::string verr = row.substr(before + 1);
  EXPECT_TRUE(verr == "inf" || std::stod(verr) >= 0.0) << row;
  // Not a terminal: one progress line per frame.
  EXPECT_NE(r.out.find("frame 4/4"), std::string::npos) << r.out;
  // Frames keep the material coordinates.
  EXPECT_NE(mgcloth::read_file(dir / "out" / "frame_00004.obj").find("\nvt "), std::string::npos);
  // No temporary files are left behind.
  for (const auto& e : fs::directory_iterator(dir / "out")) EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos);
}

TEST_F(Cli, TraceRecordsEveryIteration) {
  const auto r = run("run " + small_scene() + " -q --trace --frames 2 --out " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.out;
  const auto trace = mgcloth::read_file(dir / "out" / "trace.csv");
  EXPECT_EQ(trace.rfind("frame,step,cloth,iteration,energy,grad_norm,wall_ms,alpha", 0), 0u);
  // Every step contributes its iteration-0 row plus one per iteration.
  long expected = 0;
  const auto stats = mgcloth::read_file(dir / "out" / "stats.csv");
  std::istringstream in(stats);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::istringstream cols(line);
    std::string c;
    for (int k = 0; k < 5; ++k) std::getline(cols, c, ',');
    expected += 1 + std::stol(c);
  }
  EXPECT_EQ(std::count(trace.begin(), trace.end(), '\n'), expected + 1);
}

TEST_F(Cli, OutputFramesAreValidInputMeshes) {
  ASSERT_EQ(run("run " + small_scene() + " -q --frames 1 --out " + (dir / "a").string()).code, 0);
  // A scene whose cloth is read from the first run's frame (relative path: resolved against the scene's folder).
  const auto scene = write("from_obj.json", R"({ "frames": 2, "cloths": [ { "mesh": { "file": "a/frame_00001.obj" },
    "pins": [ { "region": { "min": [0, 0.9], "max": [1, 1] } } ] } ] })");
  const auto r = run("run " + scene + " -q --out " + (dir / "b").string());
  ASSERT_EQ(r.code, 0) << r.out;
  const auto a = mgcloth::read_file(dir / "a" / "frame_00001.obj");
  const auto b = mgcloth::read_file(dir / "b" / "frame_00000.obj");
  // Same vertex, uv and face counts: the material coordinates survived the round trip.
  for (const char* tag : {"\nv ", "\nvt ", "\nf "}) {
    size_t ca = 0, cb = 0;
    for (size_t p = a.find(tag); p != std::string::npos; p = a.find(tag, p + 1)) ++ca;
    for (size_t p = b.find(tag); p != std::string::npos; p = b.find(tag, p + 1)) ++cb;
    EXPECT_EQ(ca, cb) << tag;
    EXPECT_GT(ca, 0u);
  }
}

TEST_F(Cli, QuietPrintsNothing) {
  const auto r = run("run " + small_scene() + " --frames 1 --quiet --out " + (dir / "out").string());
  EXPECT_EQ(r.code, 0);
  EXPECT_EQ(r.out, "");
}

TEST_F(Cli, ResumeContinuesToTheSameFrames) {
  const std::string scene = small_scene();
  ASSERT_EQ(run("run " + scene + " -q --out " + (dir / "a").string()).code, 0);
  ASSERT_EQ(run("run " + scene + " -q --frames 2 --out " + (dir / "b").string()).code, 0);
  const auto r = run("run " + scene + " -q --resume --out " + (dir / "b").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(mgcloth::read_file(dir / "a" / "frame_00004.obj"), mgcloth::read_file(dir / "b" / "frame_00004.obj"));
  EXPECT_EQ(run("run " + scene + " -q --resume --out " + (dir / "nothing").string()).code, 1);
}

TEST_F(Cli, BadInputGivesOneLineAndNonZeroExit) {
  const auto unknown = run("run " + small_scene(R"(, "solver": { "nmae": "newton" })") + " -q --out " + (dir / "o").string());
  EXPECT_EQ(unknown.code, 1);
  EXPECT_NE(unknown.out.find("solver.nmae: unknown key"), std::string::npos) << unknown.out;
  EXPECT_EQ(std::count(unknown.out.begin(), unknown.out.end(), '\n'), 1) << unknown.out;

  const auto malformed = run("run " + write("bad.json", "{ \"frames\": 3,, }") + " -q");
  EXPECT_EQ(malformed.code, 1);
  EXPECT_NE(malformed.out.find("bad.json:1:"), std::string::npos) << malformed.out;

  const auto missing_mesh = run("run " + write("m.json", R"({ "cloths": [ { "mesh": { "file": "nope.obj" } } ] })") + " -q --out " + (dir / "o2").string());
  EXPECT_EQ(missing_mesh.code, 1);
  EXPECT_NE(missing_mesh.out.find("nope.obj"), std::string::npos) << missing_mesh.out;

  EXPECT_NE(run("run " + (dir / "absent.json").string()).code, 0);
  const auto solver = run("run " + small_scene() + " -q --solver nonsense --out " + (dir / "o3").string());
  EXPECT_EQ(solver.code, 1);
  EXPECT_NE(solver.out.find("unknown solver \"nonsense\""), std::string::npos) << solver.out;

  const auto diverge = run("run " + write("d.json", R"({ "frames": 2, "cloths": [ { "mesh": { "vertices": 50 }, "initial_velocity": [0, 0, 1e300], "pins": [ { "vertices": [0] } ] } ] })") + " -q --out " + (dir / "o4").string());
  EXPECT_EQ(diverge.code, 1);
  EXPECT_NE(diverge.out.find("diverged"), std::string::npos) << diverge.out;
}

TEST_F(Cli, FmgCudaRunsOnTheGpuOrSaysWhyItCannot) {
  const std::string scene = small_scene(R"(, "hierarchy": { "min_coarse_vertices": 20, "max_coarse_vertices": 40 })");
  const auto gpu = run("run " + scene + " -q --frames 2 --solver fmg-cuda --out " + (dir / "gpu").string());
  if (gpu.code == 0) GTEST_SKIP() << "a GPU ran fmg-cuda here; the message for machines without one is not tested";
  EXPECT_EQ(gpu.code, 1);
  EXPECT_NE(gpu.out.find("fmg-cuda: no GPU to run on"), std::string::npos) << gpu.out;
  EXPECT_EQ(std::count(gpu.out.begin(), gpu.out.end(), '\n'), 1) << gpu.out;
  // The same pipeline on the host backend runs the scene (pins, contact) through the CLI.
  const auto host = run("run " + write("host.json", R"({ "frames": 2, "cloths": [ { "mesh": { "vertices": 300 },
      "pins": [ { "points": [[0, 1], [1, 1]] } ] } ],
      "obstacles": [ { "shape": { "type": "sphere", "radius": 0.2 }, "position": [0.5, 0.5, -0.3] } ],
      "hierarchy": { "min_coarse_vertices": 20, "max_coarse_vertices": 40 },
      "solver": { "name": "fmg-cuda", "params": { "backend": "host" } } })") + " -q --out " + (dir / "host").string());
  EXPECT_EQ(host.code, 0) << host.out;
  const auto stats = mgcloth::read_file(dir / "host" / "stats.csv");
  EXPECT_NE(stats.find("fmg-cuda"), std::string::npos) << stats;
}

TEST_F(Cli, InfoReportsMeshAndRejectsBrokenFiles) {
  const auto good = write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n");
  const auto r = run("info " + good);
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("4"), std::string::npos);
  const auto broken = run("info " + write("broken.obj", "v 0 0 0\nf 1 2 3\n"));
  EXPECT_EQ(broken.code, 1) << broken.out;
  EXPECT_NE(broken.out.find("broken.obj"), std::string::npos) << broken.out;
  EXPECT_EQ(run("info " + (dir / "missing.obj").string()).code, 1);
}

namespace {
/// How many of `points`' columns have a column of `pool` within `tol` (brute force; small meshes only).
long count_found(const mgcloth::Mat2X& points, const mgcloth::Mat2X& pool, double tol = 1e-12) {
  long found = 0;
  for (mgcloth::Index i = 0; i < points.cols(); ++i)
    if ((pool.colwise() - points.col(i)).colwise().squaredNorm().minCoeff() <= tol * tol) ++found;
  return found;
}
long count_lines(const std::string& s) { return std::count(s.begin(), s.end(), '\n'); }
}  // namespace

TEST_F(Cli, HierarchyOfASceneWritesNestedLevelsPictureAndReport) {
  const auto scene = write("h.json", R"({ "cloths": [ { "name": "sheet",
      "mesh": { "generator": "rectangle", "vertices": 2000, "unstructured": true },
      "transform": { "translation": [0, 0, 1] }, "pins": [ { "points": [[0.5, 0.5]] } ] } ] })");
  const auto r = run("hierarchy " + scene + " --out " + (dir / "h").string() + " --min-coarse 30 --max-coarse 150 --png-size 128");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("boundary loops"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("colors"), std::string::npos) << r.out;
  const fs::path out = dir / "h" / "sheet";

  const auto report = mgcloth::parse_json(mgcloth::read_file(out / "hierarchy.json"), "hierarchy.json");
  const auto& levels = report.at("levels");
  ASSERT_GE(levels.size(), 3u);
  EXPECT_EQ(report.at("cloth"), "sheet");
  EXPECT_GE(report.at("build_seconds").get<double>(), 0.0);
  ASSERT_EQ(report.at("kept_vertices").size(), 1u);

  const auto finest = mgcloth::mesh::read_obj(out / "level0.obj");
  const mgcloth::Index pinned = report.at("kept_vertices")[0].get<mgcloth::Index>();
  mgcloth::Index prev = 0;
  for (size_t l = 0; l < levels.size(); ++l) {
    const auto world = mgcloth::mesh::read_obj(out / fmt::format("level{}.obj", l));
    const auto flat = mgcloth::mesh::read_obj(out / fmt::format("level{}_material.obj", l));
    const mgcloth::Index n = world.num_vertices();
    EXPECT_EQ(levels[l].at("vertices").get<mgcloth::Index>(), n) << l;
    EXPECT_EQ(levels[l].at("triangles").get<mgcloth::Index>(), world.num_triangles()) << l;
    EXPECT_EQ(levels[l].at("boundary_loops").get<int>(), 1) << l;
    EXPECT_GE(levels[l].at("colors").get<int>(), 2) << l;
    // World positions as the simulator places the cloth (translated to z = 1); material file: (u, v, 0).
    EXPECT_LT((world.x.row(2).array() - 1.0).abs().maxCoeff(), 1e-12) << l;
    EXPECT_EQ(flat.num_vertices(), n);
    EXPECT_LT((flat.x.topRows<2>() - flat.u).cwiseAbs().maxCoeff(), 1e-12) << l;
    EXPECT_LT(flat.x.row(2).cwiseAbs().maxCoeff(), 1e-15) << l;
    EXPECT_LT((flat.u - world.u).cwiseAbs().maxCoeff(), 1e-12) << l;
    // Nested: every vertex of a coarse level is a vertex of the finest, by material coordinates; the pinned vertex
    // is on every level.
    EXPECT_EQ(count_found(world.u, finest.u), n) << l;
    EXPECT_EQ(count_found(finest.u.col(pinned), world.u), 1) << l;
    if (l == 0) {
      EXPECT_NEAR(n, 2000, 100);
    } else {
      const double ratio = static_cast<double>(prev) / n;
      EXPECT_GE(ratio, 2.5) << l;
      EXPECT_LE(ratio, 6.0) << l;
    }
    prev = n;
  }
  EXPECT_LE(prev, 150);
  EXPECT_FALSE(fs::exists(out / fmt::format("level{}.obj", levels.size())));

  // levels.png: a PNG with one 128-pixel panel per level, with dark edges and red pin dots on white.
  const auto png = mgcloth::read_file(out / "levels.png");
  ASSERT_GE(png.size(), 33u);
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_EQ(png.substr(12, 4), "IHDR");
  const auto img = mgcloth::cli::Image::read_png(out / "levels.png");
  EXPECT_EQ(img.width(), 128 * static_cast<int>(levels.size()));
  EXPECT_GT(img.height(), 128);
  long dark = 0, red = 0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) {
      const auto p = img.pixel(x, y);
      dark += p.r < 128 && p.g < 128 && p.b < 128;
      red += p.r > 180 && p.g < 100 && p.b < 100;
    }
  EXPECT_GT(dark, 1000);
  EXPECT_GT(red, 10 * static_cast<long>(levels.size()));
  for (const auto& e : fs::directory_iterator(out)) EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos);
}

TEST_F(Cli, HierarchyOfAnObjMeshAndOfOneSceneCloth) {
  mgcloth::mesh::RectangleSpec spec;
  spec.target_vertices = 600;
  spec.width = 2.0;
  const auto m = mgcloth::mesh::make_rectangle(spec);
  mgcloth::mesh::write_obj(dir / "rect.obj", m, m.x);
  const auto r = run("hierarchy " + (dir / "rect.obj").string() + " --material-scale 0.5 --min-coarse 20 --max-coarse 100 --out " +
                     (dir / "o").string());
  ASSERT_EQ(r.code, 0) << r.out;
  // An OBJ's levels go straight into --out, with vt in the input's UV units.
  const auto input = mgcloth::mesh::read_obj(dir / "rect.obj", 0.5);
  const auto level0 = mgcloth::mesh::read_obj(dir / "o" / "level0.obj", 0.5);
  EXPECT_EQ(level0.num_vertices(), input.num_vertices());
  EXPECT_LT((level0.u - input.u).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_TRUE(fs::exists(dir / "o" / "level1.obj"));
  EXPECT_TRUE(fs::exists(dir / "o" / "levels.png"));
  EXPECT_TRUE(fs::exists(dir / "o" / "hierarchy.json"));

  const auto scene = write("two.json", R"({ "cloths": [
      { "name": "a", "mesh": { "vertices": 300 } }, { "name": "b", "mesh": { "vertices": 500 } } ] })");
  const auto one = run("hierarchy " + scene + " --cloth b --max-coarse 150 --min-coarse 30 --out " + (dir / "s").string());
  ASSERT_EQ(one.code, 0) << one.out;
  EXPECT_TRUE(fs::exists(dir / "s" / "b" / "hierarchy.json"));
  EXPECT_FALSE(fs::exists(dir / "s" / "a"));
  const auto all = run("hierarchy " + scene + " --max-coarse 150 --min-coarse 30 --out " + (dir / "all").string());
  ASSERT_EQ(all.code, 0) << all.out;
  EXPECT_TRUE(fs::exists(dir / "all" / "a" / "levels.png"));
  EXPECT_TRUE(fs::exists(dir / "all" / "b" / "levels.png"));
}

TEST_F(Cli, HierarchyRejectsBadInputWithOneLine) {
  const auto scene = small_scene();
  const std::string out = " --out " + (dir / "o").string();
  const auto expect_error = [](const Result& r, const std::string& text) {
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(text), std::string::npos) << r.out;
    EXPECT_EQ(count_lines(r.out), 1) << r.out;
  };
  expect_error(run("hierarchy " + (dir / "absent.json").string() + out), "absent.json: no such file");
  expect_error(run("hierarchy " + write("mesh.txt", "v 0 0 0\n") + out), "mesh.txt: unknown input type");
  expect_error(run("hierarchy " + write("bad.json", "{ \"frames\": 3,, }") + out), "bad.json:1:");
  expect_error(run("hierarchy " + write("broken.obj", "v 0 0 0\nf 1 2 3\n") + out), "broken.obj");
  expect_error(run("hierarchy " + scene + out + " --ratio 1"), "--ratio");
  expect_error(run("hierarchy " + scene + out + " --min-coarse 2"), "--min-coarse");
  expect_error(run("hierarchy " + scene + out + " --min-coarse 200 --max-coarse 100"), "--max-coarse");
  expect_error(run("hierarchy " + scene + out + " --png-size 8"), "--png-size");
  expect_error(run("hierarchy " + scene + out + " --seed -1"), "--seed");
  expect_error(run("hierarchy " + scene + out + " --cloth nope"), "no cloth named \"nope\"");
  expect_error(run("hierarchy " + scene + out + " --material-scale 2"), "--material-scale");
  const auto quad = write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n");
  expect_error(run("hierarchy " + quad + out + " --cloth x"), "--cloth");
  expect_error(run("hierarchy " + quad + out + " --material-scale 0"), "--material-scale");
  expect_error(run("hierarchy " + scene + " --out " + quad), "not a folder");
  EXPECT_NE(run("hierarchy " + scene).code, 0);  // --out is required
  EXPECT_FALSE(fs::exists(dir / "o"));
}

namespace {
/// The rows of a convergence.csv per solver, in file order: (iteration, rel_energy_error).
std::map<std::string, std::vector<std::pair<int, double>>> convergence_rows(const std::string& csv) {
  std::map<std::string, std::vector<std::pair<int, double>>> rows;
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::vector<std::string> cols;
    std::istringstream cs(line);
    for (std::string c; std::getline(cs, c, ',');) cols.push_back(c);
    EXPECT_EQ(cols.size(), 6u) << line;
    if (cols.size() == 6) rows[cols[0]].emplace_back(std::stoi(cols[1]), std::stod(cols[5]));
  }
  return rows;
}
bool plot_unavailable(const Result& r) {
  return r.code != 0 && r.out.find("convergence.png") != std::string::npos &&
         (r.out.find("matplotlib") != std::string::npos || r.out.find("not found") != std::string::npos);
}
/// A picture with something drawn on it (not one flat colour).
void expect_plot(const fs::path& png) {
  const auto img = mgcloth::cli::Image::read_png(png);
  EXPECT_GT(img.width(), 200);
  EXPECT_GT(img.height(), 200);
  long dark = 0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) dark += img.pixel(x, y).r < 128;
  EXPECT_GT(dark, 500);
}
}  // namespace

TEST_F(Cli, BenchConvergenceWritesCsvJsonAndPlot) {
  const fs::path out = dir / "conv";
  const auto r = run("bench convergence " + small_scene() +
                     " --step 2 --vertices 300 --solvers newton,newton@linear_solver=pcg-jacobi --budget 3 --max-iters 40 "
                     "--warmup-solver fmg --threads 1 --quiet --out " + out.string());
  ASSERT_TRUE(r.code == 0 || plot_unavailable(r)) << r.out;
  const auto csv = mgcloth::read_file(out / "convergence.csv");
  EXPECT_EQ(csv.substr(0, csv.find('\n')), "solver,iteration,wall_s,energy,grad_norm,rel_energy_error");
  const auto rows = convergence_rows(csv);
  ASSERT_EQ(rows.size(), 2u);
  for (const auto& [solver, points] : rows) {
    ASSERT_GE(points.size(), 2u) << solver;
    EXPECT_EQ(points.front().first, 0) << solver;
    EXPECT_EQ(points.front().second, 1.0) << solver;
    EXPECT_LT(std::abs(points.back().second), 1e-6) << solver;
  }
  EXPECT_TRUE(rows.count("newton@linear_solver=pcg-jacobi"));
  const auto report = mgcloth::parse_json(mgcloth::read_file(out / "convergence.json"), "convergence.json");
  EXPECT_EQ(report.at("step"), 2);
  EXPECT_EQ(report.at("steps_before_by"), "fmg");  // --warmup-solver
  EXPECT_EQ(report.at("references")[0].at("form"), "elastic");
  EXPECT_TRUE(report.at("references")[0].at("energy").is_number());
  ASSERT_EQ(report.at("solvers").size(), 2u);
  for (const auto& s : report.at("solvers")) {
    EXPECT_TRUE(s.at("time_to").at("1e-04").is_number()) << s.dump();
    EXPECT_GE(s.at("iterations").get<int>(), 1);
  }
  // The table names both solvers.
  EXPECT_NE(r.out.find("newton@linear_solver=pcg-jacobi"), std::string::npos) << r.out;
  for (const auto& e : fs::directory_iterator(out)) EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos);
  if (r.code != 0) GTEST_SKIP() << "no convergence.png: python3 with matplotlib is unavailable: " << r.out;
  expect_plot(out / "convergence.png");
}

// A step late in a long run is benchmarked from the run's checkpoint, with nothing simulated again: the frozen
// problem is the one the run's own steps lead to (the same start energy as simulating them with the run's solver).
TEST_F(Cli, BenchConvergenceStartsFromARunsCheckpoint) {
  const auto scene = small_scene();
  ASSERT_EQ(run("run " + scene + " -q -j 1 --frames 2 --out " + (dir / "run").string()).code, 0);
  const std::string bench = "bench convergence " + scene + " --solvers newton --budget 2 --max-iters 30 -j 1 -q";
  const auto a = run(bench + " --from-checkpoint " + (dir / "run" / "checkpoint.bin").string() + " --out " +
                     (dir / "a").string());
  ASSERT_TRUE(a.code == 0 || plot_unavailable(a)) << a.out;
  const auto b = run(bench + " --step 3 --warmup-solver fmg --out " + (dir / "b").string());
  ASSERT_TRUE(b.code == 0 || plot_unavailable(b)) << b.out;
  const auto ra = mgcloth::parse_json(mgcloth::read_file(dir / "a" / "convergence.json"), "a");
  const auto rb = mgcloth::parse_json(mgcloth::read_file(dir / "b" / "convergence.json"), "b");
  EXPECT_EQ(ra.at("step"), 3);  // two frames of one step each, then the benchmarked one
  EXPECT_EQ(ra.at("start_state"), "checkpoint");
  EXPECT_EQ(rb.at("start_state"), "simulated");
  const double ea = ra.at("references")[0].at("initial_energy").get<double>();
  const double eb = rb.at("references")[0].at("initial_energy").get<double>();
  EXPECT_NEAR(ea, eb, 1e-9 * std::abs(eb));
  EXPECT_NEAR(ra.at("references")[0].at("energy").get<double>(), rb.at("references")[0].at("energy").get<double>(),
              1e-9 * std::abs(eb));

  const auto expect_error = [](const Result& r, const std::string& text) {
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(text), std::string::npos) << r.out;
  };
  const std::string from = " --out " + (dir / "c").string() + " --from-checkpoint ";
  const std::string ckpt = (dir / "run" / "checkpoint.bin").string();
  expect_error(run(bench + from + ckpt + " --step 2"), "holds the start of step 3");
  expect_error(run(bench + from + (dir / "none.bin").string()), "none.bin: no such checkpoint");
  expect_error(run(bench + from + ckpt + " --vertices 200"), "--vertices");
  expect_error(run(bench + from + ckpt + " --warmup-solver fmg"), "--warmup-solver");
  // The run of another scene (here: another time step) wrote it.
  const auto other = write("other.json", mgcloth::read_file(scene).insert(1, R"( "time_step": 0.02, )"));
  expect_error(run("bench convergence " + other + " --solvers newton -q" + from + ckpt), "different scene");
  expect_error(run(bench + " --out " + (dir / "c").string()), "--step is required");
}

TEST_F(Cli, BenchWithoutPythonStillWritesTheDataAndFails) {
  ::setenv("MGCLOTH_PYTHON", "/nonexistent/python3", 1);
  const auto r = run("bench convergence " + small_scene() + " --step 1 --vertices 100 --solvers newton --budget 1 -q -j 1 --out " +
                     (dir / "o").string());
  ::unsetenv("MGCLOTH_PYTHON");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("could not make"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("/nonexistent/python3 not found"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(dir / "o" / "convergence.csv"));
  EXPECT_TRUE(fs::exists(dir / "o" / "convergence.json"));
  EXPECT_FALSE(fs::exists(dir / "o" / "convergence.png"));
}

TEST_F(Cli, BenchScalabilityWritesCsvAndPlot) {
  const fs::path out = dir / "scal";
  const auto r = run("bench scalability " + small_scene() + " --vertices 100,200 --solver newton --steps 1 --warmup 0 -j 1 -q --out " +
                     out.string());
  ASSERT_TRUE(r.code == 0 || (r.code == 1 && r.out.find("scalability.png") != std::string::npos)) << r.out;
  const auto csv = mgcloth::read_file(out / "scalability.csv");
  EXPECT_EQ(csv.rfind("vertices,solver,ms_per_step,iterations_per_step,", 0), 0u) << csv;
  EXPECT_EQ(count_lines(csv), 3) << csv;
  EXPECT_NE(csv.find(",newton,"), std::string::npos) << csv;
  if (r.code != 0) GTEST_SKIP() << "no scalability.png: python3 with matplotlib is unavailable: " << r.out;
  expect_plot(out / "scalability.png");
}

TEST_F(Cli, BenchRejectsBadInputWithOneLine) {
  const auto scene = small_scene();
  const std::string out = " --out " + (dir / "o").string();
  const auto expect_error = [](const Result& r, const std::string& text) {
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(text), std::string::npos) << r.out;
    EXPECT_EQ(count_lines(r.out), 1) << r.out;
  };
  const std::string conv = "bench convergence " + scene + out;
  expect_error(run(conv + " --step 2 --solvers newton,nonsense"), "unknown solver \"nonsense\"");
  expect_error(run(conv + " --step 2 --solvers newton@linear_slver=cholmod"), "linear_slver: unknown key");
  expect_error(run(conv + " --step 0 --solvers newton"), "--step: must be at least 1");
  expect_error(run(conv + " --step 2 --solvers ,"), "--solvers");
  expect_error(run(conv + " --step 2 --solvers newton@oops"), "not key=value");
  expect_error(run(conv + " --step 2 --solvers newton --reference-seconds 0"), "--reference-seconds: must be a positive");
  expect_error(run(conv + " --step 2 --solvers newton --warmup-solver fgm"), "unknown solver \"fgm\"");
  expect_error(run("bench convergence " + (dir / "absent.json").string() + out + " --step 2 --solvers newton"),
               "absent.json: no such file");
  expect_error(run("bench convergence " + scene + " --out " + scene + " --step 2 --solvers newton"), "not a folder");
  const std::string scal = "bench scalability " + scene + out;
  expect_error(run(scal + " --vertices 100,2k --solver newton"), "--vertices: \"2k\" is not a vertex count");
  expect_error(run(scal + " --vertices 100,,200 --solver newton"), "--vertices");
  expect_error(run(scal + " --vertices 100 --solver nonsense"), "unknown solver \"nonsense\"");
  expect_error(run("bench convergence " + scene + " --solvers newton" + out), "--step is required");
  EXPECT_NE(run("bench").code, 0);
  EXPECT_FALSE(fs::exists(dir / "o"));
}

// A shell scene from the CLI: frames of the limit surface, probes per step, resume to the same result, and the
// shell benchmark's table files.
TEST_F(Cli, ShellSceneRunsWritesProbesAndResumes) {
  const std::string scene = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_drape.json";
  const fs::path a = dir / "a", b = dir / "b";
  Result r = run(fmt::format("run {} --level 1 --frames 2 -q -o {}", scene, a.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  for (int f = 0; f <= 2; ++f) EXPECT_TRUE(fs::exists(a / fmt::format("frame_{:05d}.obj", f))) << f;
  const auto frame = mgcloth::mesh::read_obj(a / "frame_00002.obj");
  EXPECT_EQ(frame.num_triangles(), 16 * 9 * 2);  // 16 real faces, 3 x 3 display quads each
  std::ifstream probes(a / "probes.csv");
  std::string header, line;
  std::getline(probes, header);
  EXPECT_EQ(header, "step,load_factor,probe,x,y,z,ux,uy,uz");
  int rows = 0;
  while (std::getline(probes, line)) ++rows;
  EXPECT_EQ(rows, 3 * 2);  // three probes, two steps
  // Interrupted after frame 1 and resumed: the same final frame as the uninterrupted run.
  ASSERT_EQ(run(fmt::format("run {} --level 1 --frames 1 -q -o {}", scene, b.string())).code, 0);
  r = run(fmt::format("run {} --level 1 --frames 2 -q --resume -o {}", scene, b.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(mgcloth::read_file(a / "frame_00002.obj"), mgcloth::read_file(b / "frame_00002.obj"));
  EXPECT_EQ(mgcloth::read_file(a / "probes.csv"), mgcloth::read_file(b / "probes.csv"));

  r = run(fmt::format("bench shells {} --levels 1 --solvers tr-dogleg -q -o {}", scene, (dir / "bench").string()));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::exists(dir / "bench" / "shells.csv"));
  EXPECT_NE(r.out.find("drape"), std::string::npos) << r.out;
  r = run(fmt::format("bench shells {} --levels 0 -o {}", scene, (dir / "bench").string()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--levels: 0 is out of range [1, 9]"), std::string::npos) << r.out;
  r = run(fmt::format("run {} --level 12", scene));
  EXPECT_NE(r.code, 0);
}

// A shell study stopped by its iteration cap goes on with --resume from the iterate it left in OUT/states: the
// single-level TR's iterations add up to those of the uninterrupted solve (its state is the iterate alone, apart
// from the radius), a converged solve is not run again, and a state of another solve is refused by name.
TEST_F(Cli, ShellBenchResumesASolveStoppedByItsCap) {
  const std::string scene = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_trampoline.json";
  const fs::path whole = dir / "whole", parts = dir / "parts";
  const auto iterations = [](const fs::path& out) {
    const mgcloth::Json j = mgcloth::load_json((out / "shells.json").string());
    return std::make_pair(j["results"][0]["iterations"].get<int>(), j["results"][0]["status"].get<std::string>());
  };
  Result r = run(fmt::format("bench shells {} --levels 2 --solvers tr-dogleg -q -o {}", scene, whole.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto [total, status] = iterations(whole);
  ASSERT_EQ(status, "converged");
  ASSERT_GT(total, 4);
  r = run(fmt::format("bench shells {} --levels 2 --solvers tr-dogleg --max-iters 3 -q -o {}", scene, parts.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(iterations(parts), std::make_pair(3, std::string("max_iters")));
  const fs::path state = parts / "states" / "trampoline-L2-tr-dogleg.state.json";
  ASSERT_TRUE(fs::exists(state));
  r = run(fmt::format("bench shells {} --levels 2 --solvers tr-dogleg --resume -q -o {}", scene, parts.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto [resumed, resumed_status] = iterations(parts);
  EXPECT_EQ(resumed_status, "converged");
  EXPECT_GE(resumed, total);  // the radius restarts at delta0, so the second part can take a few more
  EXPECT_LE(resumed, total + 5);
  r = run(fmt::format("bench shells {} --levels 2 --solvers tr-dogleg --resume -q -o {}", scene, parts.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(iterations(parts).first, resumed);  // converged before: kept, not solved again

  // Another level's state under this name, and a truncated file: refused, naming the file.
  const std::string text = mgcloth::read_file(state);
  mgcloth::write_file_atomic(state, std::regex_replace(text, std::regex("\"level\":2"), "\"level\":3"));
  r = run(fmt::format("bench shells {} --levels 2 --solvers tr-dogleg --resume -q -o {}", scene, parts.string()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(state.string()), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("not of this solve"), std::string::npos) << r.out;
  mgcloth::write_file_atomic(state, text.substr(0, text.size() / 2));
  r = run(fmt::format("bench shells {} --levels 2 --solvers tr-dogleg --resume -q -o {}", scene, parts.string()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(state.string()), std::string::npos) << r.out;
}

// A long shell solve stopped by Ctrl-C (SIGINT) ends at its next iteration with its state and rows written and exit
// status 130; one killed without warning (SIGKILL) leaves its last checkpoint. --resume goes on from either.
TEST_F(Cli, ShellBenchKeepsItsStateWhenInterruptedOrKilled) {
  const std::string scene = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_drape.json";
  // The single-level TR needs thousands of iterations here (Table 3): it is still running when the signal comes.
  const auto bench = [&](const fs::path& out) {
    return fmt::format("{} bench shells {} --levels 4 --solvers tr-dogleg -j 1 -q -o {} --max-iters 1000000 "
                       "--checkpoint-seconds 0.2",
                       MGCLOTH_CLI, scene, out.string());
  };
  const auto state_file = [](const fs::path& out) { return out / "states" / "drape-L4-tr-dogleg.state.json"; };
  const auto state_of = [&](const fs::path& out) { return mgcloth::load_json(state_file(out).string()); };
  // The signal goes once the solve has written its first checkpoint, so that it lands inside the solve however
  // slow the machine is (a fixed delay once fell before the solve had begun on a loaded CI machine). The wait is
  // bounded (120 s); `wait` gives the bench's exit status, 128 + the signal where it was killed.
  const auto signal_once_solving = [&](const fs::path& out, const char* sig) {
    const std::string script = fmt::format(
        "{} > /dev/null 2>&1 & pid=$!; i=0; "
        "while [ ! -f '{}' ] && [ $i -lt 1200 ] && kill -0 $pid 2>/dev/null; do sleep 0.1; i=$((i+1)); done; "
        "kill -{} $pid; wait $pid",
        bench(out), state_file(out).string(), sig);
    const int status = std::system(script.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  const fs::path a = dir / "interrupted", b = dir / "killed";
  EXPECT_EQ(signal_once_solving(a, "INT"), 130);
  const auto row = mgcloth::load_json((a / "shells.json").string())["results"][0];
  EXPECT_EQ(row["status"], "interrupted");
  const mgcloth::Json sa = state_of(a);
  EXPECT_EQ(sa["status"], "interrupted");
  const int done = sa["iterations"].get<int>();
  EXPECT_GT(done, 0);
  EXPECT_EQ(row["iterations"].get<int>(), done);
  Result r = run(fmt::format("bench shells {} --levels 4 --solvers tr-dogleg -j 1 --max-iters 2 --resume -q -o {}",
                             scene, a.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(state_of(a)["iterations"].get<int>(), done + 2);

  EXPECT_EQ(signal_once_solving(b, "KILL"), 128 + 9);
  EXPECT_FALSE(fs::exists(b / "shells.json"));  // no solve finished
  const mgcloth::Json sb = state_of(b);
  EXPECT_EQ(sb["status"], "checkpoint");
  const int checkpointed = sb["iterations"].get<int>();
  EXPECT_GT(checkpointed, 0);
  r = run(fmt::format("bench shells {} --levels 4 --solvers tr-dogleg -j 1 --max-iters 2 --resume -q -o {}", scene,
                      b.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(state_of(b)["iterations"].get<int>(), checkpointed + 2);
  r = run(fmt::format("bench shells {} --levels 4 --checkpoint-seconds -1 -o {}", scene, b.string()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--checkpoint-seconds"), std::string::npos) << r.out;
}

// The time-step study from the command line: a row per tried dt in the CSV, the largest passing dt in the table,
// and one-line errors naming the offending option.
TEST_F(Cli, TimestepBenchWritesARowPerTriedStepAndRejectsBadInput) {
  const std::string scenes = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/";
  const std::string trampoline = scenes + "shell_trampoline.json", drooping = scenes + "shell_drooping.json";
  const fs::path out = dir / "ts";
  Result r = run(fmt::format("bench timestep {} {} --level 1 --solvers tr-dogleg,newton-damped --min-dt 0.25 "
                             "--window 0.5 --max-iters 3 -j 1 -q -o {}",
                             trampoline, drooping, out.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream csv(out / "timestep.csv");
  std::string header, line;
  std::getline(csv, header);
  EXPECT_EQ(header, "scene,shells,level,dofs,solver,time_step,window,steps,steps_run,passed,failed_step,status,"
                    "grad_norm,rel_grad,stalled_steps,iterations,max_step_iterations,wall_s");
  std::vector<std::vector<std::string>> rows;
  while (std::getline(csv, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    ASSERT_EQ(cells.size(), 18u) << line;
    rows.push_back(cells);
  }
  // Three TR iterations solve neither scene's first step to 1e-7, nor do three damped Newton iterations: every
  // (scene, solver) tries 1, 0.5 and 0.25.
  ASSERT_EQ(rows.size(), 2u * 2u * 3u);
  const char* dts[] = {"1", "0.5", "0.25"};
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i][5], dts[i % 3]) << i;
    EXPECT_EQ(rows[i][9], "0") << i;
    EXPECT_EQ(rows[i][11], "max_iters") << i;
  }
  EXPECT_TRUE(fs::exists(out / "timestep.json"));
  EXPECT_NE(r.out.find("none"), std::string::npos) << r.out;

  // Without the cap the trust region converges on the Trampoline at dt = 1: one row, and 1 in the table.
  r = run(fmt::format("bench timestep {} --level 2 --solvers tr-dogleg --window 1 -j 1 -q -o {}", trampoline,
                      out.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string table = mgcloth::read_file(out / "timestep.csv");
  EXPECT_EQ(count_lines(table), 2) << table;
  EXPECT_NE(table.find(",tr-dogleg,1,1,1,1,1,0,converged,"), std::string::npos) << table;
  // The summary row: shell, dofs, solver, largest dt, ...
  std::stringstream summary(r.out.substr(r.out.find("\ntrampoline") + 1));
  std::string shell, dofs, solver, largest;
  summary >> shell >> dofs >> solver >> largest;
  EXPECT_EQ(dofs + " " + solver + " " + largest, "363 tr-dogleg 1") << r.out;

  // Resumed with the same options, the try is taken from timestep.json; with other caps, refused.
  r = run(fmt::format("bench timestep {} --level 2 --solvers tr-dogleg --window 1 -j 1 --resume -o {}", trampoline,
                      out.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("taken from the earlier run"), std::string::npos) << r.out;
  EXPECT_EQ(mgcloth::read_file(out / "timestep.csv"), table);

  const auto expect_error = [](const Result& res, const std::string& text) {
    EXPECT_EQ(res.code, 1) << res.out;
    EXPECT_NE(res.out.find(text), std::string::npos) << res.out;
    EXPECT_EQ(count_lines(res.out), 1) << res.out;
  };
  expect_error(run(fmt::format("bench timestep {} --level 2 --solvers tr-dogleg --window 1 --max-seconds 5 --resume "
                               "-o {}", trampoline, out.string())),
               "--resume: " + (out / "timestep.json").string() + " was written with --max-seconds = 0");
  const std::string bad_out = " -o " + (dir / "bad").string();
  const std::string ts = "bench timestep " + trampoline + bad_out;
  expect_error(run(ts + " --min-dt 0"), "--min-dt: must be a positive");
  expect_error(run(ts + " --min-dt -0.5"), "--min-dt: must be a positive");
  expect_error(run(ts + " --min-dt 2"), "--min-dt: 2 is larger than --max-dt");
  expect_error(run(ts + " --window -1"), "--window");
  expect_error(run(ts + " --max-seconds -1"), "--max-seconds");
  expect_error(run(ts + " --max-try-seconds -1"), "--max-try-seconds");
  expect_error(run(ts + " --stall-rel-grad 1"), "--stall-rel-grad: must be in [0, 1)");
  expect_error(run(ts + " --level 0"), "--level: 0 is out of range");
  expect_error(run(ts + " --solvers tr-dogleg,nonsense"), "unknown solver \"nonsense\"");
  expect_error(run(ts + " --solvers tr-dogleg,tr-dogleg"), "--solvers: \"tr-dogleg\" is listed twice");
  expect_error(run("bench timestep " + scenes + "absent.json" + bad_out), "absent.json: no such file");
  expect_error(run("bench timestep " + small_scene() + bad_out), "the scene has no shells");
  EXPECT_NE(run("bench timestep " + trampoline).code, 0);  // --out is required
  EXPECT_FALSE(fs::exists(dir / "bad"));
}

// RMTR runs a shell scene from the command line, and the projections benchmark reports both operators per level.
TEST_F(Cli, RmtrRunsAShellSceneAndProjectionsBenchReportsBothOperators) {
  const std::string scene = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_trampoline.json";
  // The solver block of the scene file sets RMTR's parameters (a smoother strong enough for a quick test).
  mgcloth::Json j = mgcloth::Json::parse(mgcloth::read_file(scene));
  j["solver"] = {{"name", "rmtr"}, {"rel_grad", 0}, {"abs_grad", 1e-7}, {"max_iters", 300},
                 {"params", {{"scaling", "jacobi"}, {"smoother_cg_iters", 100}, {"projection", "least_squares"}}}};
  j["shells"][0]["level"] = 2;
  const fs::path rmtr_scene = dir / "rmtr.json";
  mgcloth::write_file_atomic(rmtr_scene, j.dump(2));
  Result r = run(fmt::format("run {} --frames 1 -q -o {}", rmtr_scene.string(), (dir / "rmtr").string()));
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string stats = mgcloth::read_file(dir / "rmtr" / "stats.csv");
  EXPECT_NE(stats.find(",rmtr,"), std::string::npos) << stats;
  EXPECT_NE(stats.find(",converged,"), std::string::npos) << stats;
  const std::string resolved = mgcloth::read_file(dir / "rmtr" / "scene.resolved.json");
  EXPECT_NE(resolved.find("\"smoother_cg_iters\": 100"), std::string::npos);
  EXPECT_NE(resolved.find("\"coarse_model\": \"first_order\""), std::string::npos);
  r = run(fmt::format("run {} --level 1 --frames 1 --solver rmtr -q -o {}", scene, (dir / "rmtr1").string()));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("needs at least two levels"), std::string::npos) << r.out;

  r = run(fmt::format("bench projections {} --level 3 -q -o {}", scene, (dir / "proj").string()));
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream csv(dir / "proj" / "projections.csv");
  std::string header, line;
  std::getline(csv, header);
  EXPECT_EQ(header, "operator,fine_level,fine_dofs,coarse_dofs,build_ms,apply_ms,memory_bytes,entries,exactness");
  int rows = 0;
  while (std::getline(csv, line)) {
    ++rows;
    const double exactness = std::stod(line.substr(line.rfind(',') + 1));
    EXPECT_LT(exactness, 1e-12) << line;
  }
  EXPECT_EQ(rows, 4);  // two level pairs, two operators each
}

// `bench shells --start-from`: a finer solve starts from a coarser solve's solution, prolongated by subdivision
// (reverse subdivision of the start gives that solution back exactly); RMTR then skips nested iteration. Bad starts
// name the file and what is wrong with it.
TEST_F(Cli, ShellBenchStartsFromACoarserSolveAndRejectsBadStarts) {
  const std::string scene = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_trampoline.json";
  const std::string B = "rmtr@smoother=dogleg@initial=nested@coarse_start=best";
  const auto state_in = [](const fs::path& out) {
    for (const auto& e : fs::directory_iterator(out / "states")) return e.path();
    return fs::path();
  };
  Result r = run(fmt::format("bench shells {} --levels 2 --solvers {} -j 1 --max-iters 2000 -q -o {}", scene, B,
                             (dir / "l2").string()));
  ASSERT_EQ(r.code, 0) << r.out;
  const fs::path s2 = state_in(dir / "l2");
  const mgcloth::Json j2 = mgcloth::load_json(s2.string());
  ASSERT_TRUE(j2["converged"].get<bool>());
  const auto x2 = j2["x"].get<std::vector<double>>();

  // The start itself: a trust-region solve stopped by its time cap before its first iteration keeps it.
  r = run(fmt::format("bench shells {} --levels 3 --solvers tr-dogleg -j 1 --max-seconds 1e-9 -q -o {} --start-from {}",
                      scene, (dir / "start").string(), s2.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  const mgcloth::Json start = mgcloth::load_json(state_in(dir / "start").string());
  EXPECT_EQ(start["iterations"].get<int>(), 0);
  EXPECT_EQ(start["counters"]["started_from_level"].get<double>(), 2.0);
  mgcloth::sim::Scene sc = mgcloth::sim::load_scene(scene);
  sc.shells.front().level = 3;
  mgcloth::bodies::ShellBody body(sc.shells.front(), sc.gravity, sc.file);
  const auto x3 = start["x"].get<std::vector<double>>();
  ASSERT_EQ(static_cast<mgcloth::Index>(x3.size()), 3 * body.hierarchy().subdivision(1).num_rows);
  mgcloth::VecX back;
  body.project(1, Eigen::Map<const mgcloth::VecX>(x3.data(), static_cast<mgcloth::Index>(x3.size())), back);
  ASSERT_EQ(back.size(), static_cast<mgcloth::Index>(x2.size()));
  const mgcloth::VecX q = Eigen::Map<const mgcloth::VecX>(x2.data(), static_cast<mgcloth::Index>(x2.size()));
  EXPECT_LE((back - q).norm(), 1e-12 * q.norm());

  // RMTR from it: converged, no nested iteration, the start recorded.
  r = run(fmt::format("bench shells {} --levels 3 --solvers {} -j 1 --max-iters 2000 -o {} --start-from {}", scene, B,
                      (dir / "l3").string(), s2.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("starts from the level-2 solution"), std::string::npos) << r.out;
  const mgcloth::Json l3 = mgcloth::load_json((dir / "l3" / "shells.json").string());
  EXPECT_EQ(l3["start_from"][0].get<std::string>(), s2.string());
  const auto& row = l3["results"][0];
  EXPECT_TRUE(row["converged"].get<bool>()) << row.dump();
  EXPECT_EQ(row["counters"]["started_from_level"].get<double>(), 2.0);
  for (const auto& [k, v] : row["counters"].items()) EXPECT_EQ(k.find("nested_cycles"), std::string::npos) << k;

  // Bad starts: not coarser, missing, an unknown shell, one shell twice, a state whose size is not its level's.
  const fs::path s3 = state_in(dir / "l3");
  const auto bench3 = [&](const std::string& starts) {
    return run(fmt::format("bench shells {} --levels 3 --solvers {} -j 1 -q -o {} {}", scene, B,
                           (dir / "bad").string(), starts));
  };
  r = bench3("--start-from " + s3.string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("level 3 of shell \"trampoline\" is not coarser than this run's levels (3)"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find(s3.string()), std::string::npos) << r.out;
  r = bench3("--start-from " + (dir / "missing.json").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("missing.json: no such file"), std::string::npos) << r.out;
  mgcloth::Json other = j2;
  other["shell"] = "nosuch";
  const std::string renamed = write("renamed.json", other.dump());
  r = bench3("--start-from " + renamed);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("no scene has a shell named \"nosuch\""), std::string::npos) << r.out;
  r = bench3(fmt::format("--start-from {} --start-from {}", s2.string(), s2.string()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("already starts from"), std::string::npos) << r.out;
  // RMTR's settings serve every shell of a scene: a start for one of two shells is refused.
  mgcloth::Json two = mgcloth::Json::parse(mgcloth::read_file(scene));
  two["shells"].push_back(two["shells"][0]);
  two["shells"][1]["name"] = "second";
  const std::string two_scene = write("two.json", two.dump());
  r = run(fmt::format("bench shells {} --levels 3 --solvers {} -j 1 -q -o {} --start-from {}", two_scene, B,
                      (dir / "two").string(), s2.string()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("has 2 shells and starts for 1 of them at level 3"), std::string::npos) << r.out;
  mgcloth::Json cut = j2;
  auto x = x2;
  x.resize(x.size() - 3);
  cut["x"] = x;
  cut["dofs"] = x.size();
  const std::string cut_file = write("cut.json", cut.dump());
  r = bench3("--start-from " + cut_file);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(fmt::format("{} dofs, level 2 of shell \"trampoline\" has {}", x.size(), x2.size())),
            std::string::npos)
      << r.out;
}

// `mgcloth body`: the generated mannequin as OBJ frames a scene can read back as a sequence, and a skinned glb.
TEST_F(Cli, BodyWritesObjFramesAndASkinnedGlbThatScenesRead) {
  const auto out = dir / "body";
  const auto r = run(fmt::format("body --out {} --resolution 0.03 --seconds 0.2 --fps 20 --height 1.8", out.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  for (int k = 0; k <= 4; ++k) EXPECT_TRUE(fs::exists(out / fmt::format("body_{:04d}.obj", k))) << k;
  EXPECT_FALSE(fs::exists(out / "body_0005.obj"));
  const auto mesh = mgcloth::mesh::read_obj_surface((out / "body_0000.obj").string());
  EXPECT_NEAR(mesh.x.row(2).maxCoeff(), 1.8, 0.03);
  EXPECT_NEAR(mesh.x.row(2).minCoeff(), 0.0, 0.005);
  if (fs::exists(out / "body.glb")) {
    // Both forms of the body are mesh obstacles a scene accepts.
    for (const std::string obstacle : {R"({"mesh": "body/body_%04d.obj", "mesh_rate": 20})", R"({"mesh": "body/body.glb"})"}) {
      const auto scene = write("walk.json", R"({ "frames": 1, "cloth_contact": {}, "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 100 },
        "transform": { "translation": [-0.5, -0.5, 2.0] } } ], "obstacles": [ )" + obstacle + "] }");
      const auto run_r = run(fmt::format("run {} --out {} --quiet", scene, (dir / "run").string()));
      EXPECT_EQ(run_r.code, 0) << obstacle << ": " << run_r.out;
    }
  }
  const auto bad = run(fmt::format("body --out {} --height 3", out.string()));
  EXPECT_EQ(bad.code, 1);
  EXPECT_NE(bad.out.find("--height"), std::string::npos) << bad.out;
  EXPECT_EQ(run("body --height 1.7").code, 1);  // --out is required
}
