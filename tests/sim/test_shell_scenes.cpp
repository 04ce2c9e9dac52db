// Subdivision shells end to end: scene parsing, the classical Kirchhoff plate solutions under refinement,
// boundary conditions, probes and the trust-region solve of the Trampoline (Kopaničáková 2019, §5, §7).
#include <mgcloth/core/error.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <gtest/gtest.h>

#include <string>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

using namespace mgcloth;

namespace {

/// A 1 m square St. Venant-Kirchhoff plate (E = 1e7 Pa, ν = 0.3, t = 1 cm) under a uniform pressure of 1 mPa:
/// deflections ~1e-6 m, so the plate is in the linear Kirchhoff regime (w/t ~ 1e-4, membrane action ~(w/t)²).
/// Against O(1 m) coordinates and β = h^-5, double precision limits the solve to a relative gradient of ~1e-5 at
/// level 4 (the limiting accuracy of §7.2): the trust region ends "stalled" there, which is accepted below 1e-4.
Json plate(const std::string& support, int level) {
  Json j = Json::parse(R"({
    "gravity": [0, 0, 0], "time_step": 1.0, "frames": 1,
    "shells": [{
      "name": "plate",
      "control_mesh": {"generator": "rectangle", "width": 1.0, "height": 1.0, "cells_u": 4, "cells_v": 4},
      "material": {"preset": "stvk", "young": 1e7, "poisson": 0.3, "thickness": 0.01, "density": 1.0},
      "analysis": "static",
      "loads": [{"type": "pressure", "pressure": 1e-3}],
      "probes": [[0.5, 0.5]]
    }],
    "solver": {"name": "tr-dogleg", "rel_grad": 1e-8, "abs_grad": 0, "max_iters": 200}
  })");
  j["shells"][0]["level"] = level;
  j["shells"][0]["boundary"] = Json::array({{{"type", support}, {"sides", "all"}}});
  return j;
}

double centre_deflection(const Json& scene) {
  sim::Simulator sim(sim::parse_scene(scene, "plate.json", "."));
  const auto stats = sim.step();
  const auto& r = stats.back().report;
  EXPECT_TRUE(r.converged || (r.status == "stalled" && r.grad_norm < 1e-4 * r.initial_grad_norm))
      << r.status << " at relative gradient " << r.grad_norm / r.initial_grad_norm;
  return sim.shells()[0]->probes()[0].u.z();
}

// Navier / Timoshenko & Woinowsky-Krieger, Table 8 and Table 35: w_max = α q a⁴ / D with D = E t³ / (12 (1 − ν²)),
// α = 0.00406235 (simply supported) and 0.00126532 (clamped) for ν = 0.3. The penalty boundary conditions
// (β = h^-5) and the bicubic limit surface converge to them under refinement: measured relative errors per level
// 1-4 (147-3,675 dofs) in bench/RESULTS.md.
TEST(ShellPlate, CentreDeflectionConvergesToKirchhoffSolutions) {
  const double D = 1e7 * 1e-6 / (12.0 * (1.0 - 0.09));
  const struct {
    const char* support;
    double alpha;
  } cases[] = {{"fixed", 0.00406235}, {"clamped", 0.00126532}};
  for (const auto& c : cases) {
    const double reference = c.alpha * 1e-3 / D;
    double previous = kInf;
    for (int level = 1; level <= 4; ++level) {
      const double w = centre_deflection(plate(c.support, level));
      const double error = std::abs(w - reference) / reference;
      std::printf("plate %-7s level %d: w = %.6e m, Kirchhoff %.6e m, relative error %.3e\n", c.support, level, w,
                  reference, error);
      EXPECT_LT(error, previous) << c.support << " level " << level;
      previous = error;
    }
    EXPECT_LT(previous, 0.02) << c.support;
  }
}

// Static load stepping: step k of K applies the load factor k / K (recorded in the step's statistics); in the
// linear regime the deflection follows it.
TEST(ShellPlate, StaticLoadSteppingScalesTheLoad) {
  Json j = plate("fixed", 2);
  j["frames"] = 4;
  sim::Simulator sim(sim::parse_scene(j, "plate.json", "."));
  std::vector<double> w, factor;
  for (int k = 0; k < 4; ++k) {
    const auto st = sim.advance_frame();
    factor.push_back(st.back().load_factor);
    w.push_back(sim.shells()[0]->probes()[0].u.z());
  }
  for (int k = 0; k < 4; ++k) {
    EXPECT_DOUBLE_EQ(factor[k], (k + 1) / 4.0);
    EXPECT_NEAR(w[k] / w[3], (k + 1) / 4.0, 1e-4) << "step " << k + 1;
  }
  EXPECT_EQ(sim.shells()[0]->v().norm(), 0.0);
}

// TR converges on the Trampoline at level 3 (1,083 dofs, dt = 1 s): the sag is physical (about 3 cm under the
// cloth's weight), symmetric, and the fixed edges stay put.
TEST(ShellScenes, TrustRegionConvergesOnTheTrampolineAtLevel3) {
  sim::Scene scene = sim::load_scene(std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_trampoline.json");
  scene.shells[0].level = 3;
  scene.shells[0].probes = {{0.5, 0.5}, {0.25, 0.5}, {0.75, 0.5}, {0.5, 0.25}, {0.0, 0.5}, {0.5, 0.75}};
  sim::Simulator sim(scene);
  EXPECT_EQ(3 * sim.shells()[0]->x().size() / 3, 1083);
  const auto stats = sim.step();
  ASSERT_TRUE(stats.back().report.converged) << stats.back().report.status;
  EXPECT_LT(stats.back().report.grad_norm, 1e-7);
  const auto p = sim.shells()[0]->probes();
  EXPECT_LT(p[0].u.z(), -0.005);
  EXPECT_GT(p[0].u.z(), -0.2);
  EXPECT_NEAR(p[1].u.z(), p[2].u.z(), 1e-6 * std::abs(p[1].u.z()));
  EXPECT_NEAR(p[3].u.z(), p[5].u.z(), 1e-6 * std::abs(p[3].u.z()));  // mirror symmetric (denim is orthotropic)
  EXPECT_LT(p[0].u.z(), p[1].u.z());
  EXPECT_LT(p[4].u.norm(), 1e-3 * std::abs(p[0].u.z()));
}

// Prescribed displacements move the held points to their targets (Drape-style corners, ramped).
TEST(ShellScenes, PrescribedDisplacementMovesTheHeldEdge) {
  Json j = plate("fixed", 2);
  j["shells"][0]["analysis"] = "dynamic";
  j["shells"][0]["loads"] = Json::array();
  j["gravity"] = {0, 0, -9.81};
  j["shells"][0]["material"] = {{"preset", "stvk"}, {"young", 1e6}, {"poisson", 0.3}, {"thickness", 1e-3}, {"density", 0.2}};
  j["shells"][0]["boundary"] = Json::array({{{"type", "fixed"}, {"sides", "left"}},
                                            {{"type", "fixed"}, {"sides", "right"}, {"displacement", {-0.1, 0, 0.05}}, {"ramp_time", 2.0}}});
  j["shells"][0]["probes"] = Json::array({{1.0, 0.5}, {0.0, 0.5}});
  j["time_step"] = 0.5;
  sim::Simulator sim(sim::parse_scene(j, "move.json", "."));
  for (int s = 0; s < 4; ++s) {
    const auto st = sim.step();
    ASSERT_TRUE(st.back().report.converged) << st.back().report.status;
    const double f = std::min(1.0, 0.5 * (s + 1) / 2.0);
    const auto p = sim.shells()[0]->probes();
    EXPECT_NEAR(p[0].u.x(), -0.1 * f, 2e-3) << "step " << s;
    EXPECT_NEAR(p[0].u.z(), 0.05 * f, 2e-3) << "step " << s;
    EXPECT_LT(p[1].u.norm(), 2e-3);
  }
}

std::string error_of(const Json& j) {
  try {
    sim::Simulator sim(sim::parse_scene(j, "bad.json", "."));
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(ShellScenes, BadShellInputNamesTheField) {
  Json j = plate("fixed", 1);
  j["shells"][0]["boundry"] = Json::array();
  EXPECT_NE(error_of(j).find("bad.json: shells[0].boundry: unknown key"), std::string::npos) << error_of(j);
  j = plate("fixed", 1);
  j["shells"][0]["level"] = 0;
  EXPECT_NE(error_of(j).find("shells[0].level"), std::string::npos) << error_of(j);
  j = plate("fixed", 1);
  j["shells"][0]["material"]["thickness"] = -1;
  EXPECT_NE(error_of(j).find("shells[0].material.thickness"), std::string::npos) << error_of(j);
  j = plate("fixed", 1);
  j["shells"][0]["probes"] = Json::array({{2.0, 2.0}});
  EXPECT_NE(error_of(j).find("probes: material point (2, 2) is not on the shell"), std::string::npos) << error_of(j);
  j = plate("fixed", 1);
  j["shells"][0]["boundary"] = Json::array({{{"type", "fixed"}, {"region", {{"min", {5, 5}}, {"max", {6, 6}}}}}});
  EXPECT_NE(error_of(j).find("boundary[0]: the region selects no boundary segment"), std::string::npos) << error_of(j);
  j = plate("fixed", 1);
  j["shells"][0]["control_mesh"] = {{"file", "does_not_exist.obj"}};
  EXPECT_NE(error_of(j).find("does_not_exist.obj"), std::string::npos) << error_of(j);
  j = plate("fixed", 1);
  j["shells"][0]["boundary"][0]["sides"] = "middle";
  EXPECT_NE(error_of(j).find("shells[0].boundary[0].sides"), std::string::npos) << error_of(j);
}

TEST(ShellScenes, ShellNamesAreCheckedLikeClothNames) {
  Json j = plate("fixed", 1);
  j["shells"][0]["name"] = "plate,1";
  EXPECT_NE(error_of(j).find("bad.json: shells[0].name: \"plate,1\" contains ','"), std::string::npos) << error_of(j);
}

// An OBJ without faces was reported as "every quad is a ghost quad".
TEST(ShellScenes, EmptyControlMeshIsNamedEmpty) {
  const auto path = std::filesystem::temp_directory_path() / ("mgcloth_empty_control_mesh_" + std::to_string(::getpid()) + ".obj");
  std::ofstream(path) << "# nothing here\nv 0 0 0\n";
  Json j = plate("fixed", 1);
  j["shells"][0]["control_mesh"] = {{"file", path.string()}};
  EXPECT_NE(error_of(j).find("bad.json: shells[0] (\"plate\"): " + path.string() +
                             ": the control mesh is empty: it has no quads (f lines)"),
            std::string::npos)
      << error_of(j);
  std::filesystem::remove(path);
}

TEST(ShellScenes, ResolvedShellSceneRoundTrips) {
  for (const char* name : {"shell_trampoline", "shell_drooping", "shell_reentrant", "shell_drape"}) {
    const sim::Scene s = sim::load_scene(std::string(MGCLOTH_SOURCE_DIR) + "/scenes/" + name + ".json");
    const Json resolved = sim::to_json(s);
    EXPECT_EQ(sim::to_json(sim::parse_scene(resolved, "resolved.json", ".")), resolved) << name;
    EXPECT_EQ(s.solver.name, "tr-dogleg");
  }
}

}  // namespace
