// End-to-end scenes with physical assertions.
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/sim/recorder.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <unistd.h>

using namespace mgcloth;
namespace fs = std::filesystem;

namespace {
/// A shipped scene with the resolution lowered so the suite stays fast; everything else is as shipped.
sim::Scene shipped(const std::string& name, int vertices, int frames) {
  const std::string path = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/" + name + ".json";
  Json j = load_json(path);
  j["cloths"][0]["mesh"]["vertices"] = vertices;
  j["frames"] = frames;
  return sim::parse_scene(j, path, fs::path(path).parent_path());
}

double angular_momentum_z(const bodies::ClothBody& c) {
  double L = 0.0;
  for (Index i = 0; i < c.mesh().num_vertices(); ++i) {
    const Vec3 x = c.x().segment<3>(3 * i), v = c.v().segment<3>(3 * i);
    L += c.mass()[i] * (x.x() * v.y() - x.y() * v.x());
  }
  return L;
}
}  // namespace

TEST(Simulation, DrapeSphereStaysOutsideTheSphere) {
  sim::Simulator s(shipped("drape_sphere", 900, 30));
  const double r = s.scene().obstacles[0].radius, thickness = s.scene().contact.thickness;
  for (int f = 0; f < 30; ++f) {
    s.advance_frame();
    const auto& x = s.cloths()[0]->x();
    for (Index i = 0; i < x.size() / 3; ++i) ASSERT_GE(x.segment<3>(3 * i).norm() - r, -thickness) << "frame " << f + 1 << " vertex " << i;
  }
  const auto& x = s.cloths()[0]->x();
  const auto cols = as_columns(x);
  // The cloth has fallen onto the sphere: its top rests at the sphere's top, its corners hang below it.
  EXPECT_NEAR(cols.row(2).maxCoeff(), r, 0.02);
  EXPECT_LT(cols.row(2).minCoeff(), 0.0);
  EXPECT_TRUE(x.allFinite());
}

TEST(Simulation, RotatingSphereDragsClothOnlyWithFriction) {
  auto with = shipped("rotating_sphere", 600, 25);
  auto without = with;
  without.obstacles[0].friction = 0.0;
  sim::Simulator a(with), b(without);
  for (int f = 0; f < 25; ++f) {
    a.advance_frame();
    b.advance_frame();
  }
  const double La = angular_momentum_z(*a.cloths()[0]);
  const double Lb = angular_momentum_z(*b.cloths()[0]);
  const double mass = a.cloths()[0]->mass().sum();
  // The sphere spins at ω = 3 rad/s about +z: with friction the cloth turns the same way; without, only
  // numerical asymmetry remains.
  EXPECT_GT(La, 1e-3 * mass);
  EXPECT_LT(std::abs(Lb), 0.05 * La);
}

TEST(Simulation, HangingClothStaysAttachedAndSwingsDown) {
  sim::Simulator s(shipped("hanging", 400, 20));
  const auto& body = *s.cloths()[0];
  std::vector<Vec3> pins;
  for (Index v : body.pinned_vertices()) pins.push_back(body.x().segment<3>(3 * v));
  for (int f = 0; f < 20; ++f) s.advance_frame();
  for (size_t p = 0; p < pins.size(); ++p)
    EXPECT_LT((body.x().segment<3>(3 * body.pinned_vertices()[p]) - pins[p]).norm(), 1e-3);
  EXPECT_LT(as_columns(body.x()).row(2).minCoeff(), 0.3);  // it fell from z = 1 and hangs below its pins
}

// The check's reading against an independent one: the distance of a loosely stopped step to the same step solved by
// FMG to round-off.
TEST(Simulation, AccuracyCheckMeasuresTheDistanceToTheStepsMinimizer) {
  sim::Scene loose = shipped("hanging", 400, 1), tight = loose;
  loose.solver.stop.rel_grad = 1e-1;
  tight.solver.stop.rel_grad = 1e-11;
  tight.solver.stop.max_iters = 1000;
  sim::Simulator a(loose), b(tight);
  a.set_accuracy_check(true);
  const std::vector<sim::StepStats> sa = a.step();
  const std::vector<sim::StepStats> sb = b.step();
  ASSERT_TRUE(sb[0].report.converged) << sb[0].report.status;
  const double h = loose.step_size();
  const VecX &xa = a.cloths()[0]->x(), &xb = b.cloths()[0]->x();
  const double largest = solvers::max_vertex_distance(xa, xb) / h;
  const double rms = (xa - xb).norm() / std::sqrt(static_cast<double>(xa.size() / 3)) / h;
  ASSERT_GT(largest, 1e-5) << "a step stopped at 1e-1 is measurably off";
  EXPECT_NEAR(sa[0].true_velocity_error, largest, 1e-3 * largest);
  EXPECT_NEAR(sa[0].true_velocity_rms, rms, 1e-3 * rms);
  EXPECT_TRUE(std::isnan(sb[0].true_velocity_error)) << "off unless asked for";
}

// solver.velocity_rms_tol: each step stops once its Newton decrement puts the mass-weighted RMS velocity error within
// the tolerance, the estimate is reported whatever the rule, and solvers that measure no decrement stop by the
// gradient's bound of the same error.
TEST(Simulation, AnRmsVelocityToleranceStopsEachStepByTheNewtonDecrement) {
  sim::Scene scene = shipped("hanging", 400, 1);
  scene.solver.stop.rel_grad = 0.0;
  scene.solver.velocity_rms_tol = 1e-3;
  sim::Simulator a(scene);
  a.set_accuracy_check(true);
  for (int k = 0; k < 3; ++k) {
    const sim::StepStats s = a.step()[0];
    EXPECT_EQ(s.report.status, "converged");
    EXPECT_LE(s.velocity_rms_error, 1e-3);
    EXPECT_GT(s.velocity_rms_error, 0.0);
    // The vertices' RMS against the step's minimizer (masses nearly uniform on this mesh).
    EXPECT_LT(s.true_velocity_rms, 2e-3) << "step " << k;
  }
  sim::Scene rel = shipped("hanging", 400, 1);
  sim::Simulator b(rel);
  EXPECT_TRUE(std::isfinite(b.step()[0].velocity_rms_error)) << "reported under rel_grad too";
  // Solvers that measure no decrement stop where the gradient bounds the error, a stricter rule: the same tolerance,
  // met with room to spare (a single-level smoother takes some 700-1,000 sweeps per step for it).
  for (const char* name : {"gs-chebyshev", "tr"}) {
    scene.solver.name = name;
    scene.solver.stop.max_iters = 5000;
    sim::Simulator c(scene);
    c.set_accuracy_check(true);
    for (int k = 0; k < 2; ++k) {
      const sim::StepStats s = c.step()[0];
      EXPECT_EQ(s.report.status, "converged") << name << " step " << k;
      EXPECT_LE(s.velocity_rms_error, 1e-3) << name << " step " << k;
      EXPECT_GT(s.velocity_rms_error, 0.0) << name << " step " << k;
      EXPECT_LT(s.true_velocity_rms, 1e-3) << name << " step " << k;
    }
  }
}

TEST(Simulation, ResumeReproducesAnUninterruptedRun) {
  const fs::path root = fs::temp_directory_path() / ("mgcloth_resume_test_" + std::to_string(::getpid()));
  fs::remove_all(root);
  auto scene = shipped("drape_sphere", 400, 6);
  {
    sim::Simulator s(scene);
    sim::Recorder rec(root / "full", s);
    rec.start(s);
    while (s.frame() < 6) rec.record_frame(s, s.advance_frame());
  }
  {
    sim::Simulator s(scene);
    sim::Recorder rec(root / "split", s);
    rec.start(s);
    while (s.frame() < 3) rec.record_frame(s, s.advance_frame());
  }
  {
    sim::Simulator s(scene);
    sim::Recorder rec(root / "split", s);
    rec.resume(s);
    EXPECT_EQ(s.frame(), 3);
    while (s.frame() < 6) rec.record_frame(s, s.advance_frame());
  }
  for (int f = 0; f <= 6; ++f) {
    const auto a = read_file(sim::Recorder::frame_path(root / "full", f));
    const auto b = read_file(sim::Recorder::frame_path(root / "split", f));
    EXPECT_EQ(a, b) << "frame " << f;
  }
  // Stats of the resumed run cover every step exactly once.
  const auto stats = read_file(root / "split" / "stats.csv");
  EXPECT_EQ(std::count(stats.begin(), stats.end(), '\n'), 7);
  // A different scene must not resume this checkpoint.
  auto other = scene;
  other.cloths[0].material.youngs_modulus *= 2;
  sim::Simulator s(other);
  sim::Recorder rec(root / "split", s);
  EXPECT_THROW(rec.resume(s), InputError);
  fs::remove_all(root);
}

TEST(Simulation, SurfacesJsonNamesEachClothsVerticesAndTrianglesOfTheFrames) {
  // Two of the stacked sheets at different resolutions: a viewer colours each by its ranges in the frame files.
  const std::string path = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/layers_sphere.json";
  Json j = load_json(path);
  j["cloths"] = Json::array({j["cloths"][0], j["cloths"][1]});
  j["cloths"][0]["mesh"]["vertices"] = 150;
  j["cloths"][1]["mesh"]["vertices"] = 240;
  j["frames"] = 1;
  sim::Simulator s(sim::parse_scene(j, path, fs::path(path).parent_path()));
  const fs::path root = fs::temp_directory_path() / ("mgcloth_surfaces_test_" + std::to_string(::getpid()));
  fs::remove_all(root);
  sim::Recorder rec(root, s);
  rec.start(s);
  const Json surfaces = load_json((root / "surfaces.json").string());
  ASSERT_EQ(surfaces.size(), 2u);
  Index vertices = 0, triangles = 0;
  for (size_t k = 0; k < 2; ++k) {
    const auto& body = *s.cloths()[k];
    EXPECT_EQ(surfaces[k]["name"], body.name());
    EXPECT_EQ(surfaces[k]["vertices"][0].get<Index>(), vertices);
    EXPECT_EQ(surfaces[k]["vertices"][1].get<Index>(), body.mesh().num_vertices());
    EXPECT_EQ(surfaces[k]["triangles"][0].get<Index>(), triangles);
    EXPECT_EQ(surfaces[k]["triangles"][1].get<Index>(), body.mesh().num_triangles());
    vertices += body.mesh().num_vertices();
    triangles += body.mesh().num_triangles();
  }
  EXPECT_NE(vertices, 2 * s.cloths()[0]->mesh().num_vertices());
  // The frame file holds exactly those vertices and triangles, and the second cloth's faces use its own range.
  const std::string obj = read_file(sim::Recorder::frame_path(root, 0));
  EXPECT_NE(obj.find(fmt::format("# mgcloth: {} vertices, {} triangles", vertices, triangles)), std::string::npos);
  const auto& second = s.cloths()[1]->mesh().tris[0];
  const Index first = surfaces[1]["vertices"][0].get<Index>() + 1;
  EXPECT_NE(obj.find(fmt::format("\nf {0}/{0} {1}/{1} {2}/{2}\n", second[0] + first, second[1] + first,
                                 second[2] + first)),
            std::string::npos);
  // A resumed run rewrites it the same.
  const std::string written = read_file(root / "surfaces.json");
  fs::remove(root / "surfaces.json");
  sim::Simulator again(sim::parse_scene(j, path, fs::path(path).parent_path()));
  sim::Recorder(root, again).resume(again);
  EXPECT_EQ(read_file(root / "surfaces.json"), written);
  fs::remove_all(root);
}

TEST(Simulation, DivergingSolveIsASolveErrorNamingTheStep) {
  auto scene = shipped("hanging", 100, 1);
  scene.cloths[0].initial_velocity = Vec3(0, 0, 1e300);
  sim::Simulator s(scene);
  try {
    s.advance_frame();
    FAIL() << "no error";
  } catch (const SolveError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("frame 1"), std::string::npos) << msg;
    EXPECT_NE(msg.find("non-finite"), std::string::npos) << msg;
  }
}

TEST(Simulation, KeyframedPinsCarryTheCloth) {
  // Pins lifted by 0.2 m over the first 0.5 s drag the pinned corners along; the cloth follows.
  Json j = Json::parse(R"({ "frames": 20, "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 200 },
    "pins": [ { "points": [[0, 1], [1, 1]], "motion": { "type": "keyframes",
      "keys": [ { "time": 0.0, "offset": [0, 0, 0] }, { "time": 0.5, "offset": [0, 0, 0.2] } ] } } ] } ] })");
  sim::Simulator s(sim::parse_scene(j, "pins.json", "."));
  const auto& body = *s.cloths()[0];
  const auto start = body.pin_targets(0.0);
  for (int f = 0; f < 20; ++f) s.advance_frame();
  const auto end = body.pin_targets(s.time());
  for (size_t p = 0; p < start.size(); ++p) {
    EXPECT_NEAR(end[p].z() - start[p].z(), 0.2, 1e-12);
    EXPECT_LT((body.x().segment<3>(3 * body.pinned_vertices()[p]) - end[p]).norm(), 2e-3);
  }
}

TEST(Simulation, RotatingPinsTurnAboutTheirAxisAndHoldAfterTheirDuration) {
  // The pinned top edge (y = 1) turns about the x axis through (0, 0, 0) at π/2 rad/s for 0.5 s, while the centre
  // moves 0.1 m/s along x: a quarter turn in 1 s would take (x, 1, 0) to (x, 0, 1); half of it is 45°.
  Json j = Json::parse(R"({ "frames": 30, "gravity": [0, 0, 0], "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 200 },
    "pins": [ { "region": { "min": [0, 0.999], "max": [1, 1] }, "motion": { "type": "rotation", "axis": [2, 0, 0],
      "center": [0, 0, 0], "angular_velocity": 1.5707963267948966, "velocity": [0.1, 0, 0], "duration": 0.5 } } ] } ] })");
  sim::Simulator s(sim::parse_scene(j, "pins.json", "."));
  const auto& body = *s.cloths()[0];
  const auto rest = body.pin_targets(0.0);
  ASSERT_GT(rest.size(), 5u);
  for (double t : {0.25, 0.5, 1.0}) {
    const double angle = 1.5707963267948966 * std::min(t, 0.5), shift = 0.1 * std::min(t, 0.5);
    const auto at = body.pin_targets(t);
    for (size_t p = 0; p < rest.size(); ++p) {
      const Vec3 expected(rest[p].x() + shift, std::cos(angle) * rest[p].y() - std::sin(angle) * rest[p].z(),
                          std::sin(angle) * rest[p].y() + std::cos(angle) * rest[p].z());
      EXPECT_LT((at[p] - expected).norm(), 1e-12) << "t " << t << " pin " << p;
    }
  }
  // The cloth follows its pins.
  for (int f = 0; f < 30; ++f) s.advance_frame();
  const auto end = body.pin_targets(s.time());
  for (size_t p = 0; p < end.size(); ++p)
    EXPECT_LT((body.x().segment<3>(3 * body.pinned_vertices()[p]) - end[p]).norm(), 2e-3) << p;
  Json bad = j;
  bad["cloths"][0]["pins"][0]["motion"]["axis"] = Json::array({0, 0, 0});
  EXPECT_THROW(sim::parse_scene(bad, "pins.json", "."), InputError);
}

TEST(Simulation, TableclothRestsOnTheTableAndHangsOverItsEdges) {
  sim::Simulator s(shipped("tablecloth", 600, 20));
  const double thickness = s.scene().contact.thickness;
  const auto& table = s.obstacles()[0];
  for (int f = 0; f < 20; ++f) {
    s.advance_frame();
    const auto& x = s.cloths()[0]->x();
    for (Index i = 0; i < x.size() / 3; ++i) {
      ASSERT_GE(table.sdf(x.segment<3>(3 * i), s.time()).phi, -thickness) << "frame " << f + 1 << " vertex " << i;
      ASSERT_GE(x[3 * i + 2], -thickness) << "below the floor";
    }
  }
  const auto cols = as_columns(s.cloths()[0]->x());
  EXPECT_NEAR(cols.row(2).maxCoeff(), 0.8, 0.02);  // on the table top
  EXPECT_LT(cols.row(2).minCoeff(), 0.7);          // draped over the edges
}

TEST(Simulation, TubeGarmentStaysStitchedOnASphere) {
  // A two-panel skirt (tube) dropped over a sphere, solved by Newton with multigrid-PCG on its stitched hierarchy:
  // the seams must stay closed, and the skirt must come to rest on top of the sphere, not pass through it.
  const Json j = {{"frames", 12},
                  {"cloths", {{{"name", "skirt"},
                               {"mesh", {{"generator", "tube"}, {"circumference", 1.2}, {"height", 0.3}, {"vertices", 1600}}},
                               {"transform", {{"translation", {0.0, 0.0, 0.3}}}}}}},
                  {"obstacles", {{{"shape", {{"type", "sphere"}, {"radius", 0.25}}}}}},
                  {"solver", {{"name", "newton"}, {"rel_grad", 1e-3}, {"max_iters", 30}, {"params", {{"linear_solver", "pcg-mg"}}}}},
                  {"hierarchy", {{"max_coarse_vertices", 150}, {"min_coarse_vertices", 50}}}};
  sim::Simulator s(sim::parse_scene(j, "skirt.json", "."));
  const auto& body = *s.cloths()[0];
  ASSERT_FALSE(body.topology().stitch_groups.empty());
  EXPECT_GE(s.cloths()[0]->hierarchy().num_levels(), 3);
  int converged = 0;
  while (s.frame() < 12)
    for (const auto& st : s.advance_frame()) converged += st.report.converged;
  EXPECT_GE(converged, 10);  // the impact frames may hit the iteration cap
  double gap = 0.0, min_distance = 1e9;
  for (const auto& g : body.topology().stitch_groups)
    for (Index v : g) gap = std::max(gap, (body.x().segment<3>(3 * v) - body.x().segment<3>(3 * g[0])).norm());
  for (Index i = 0; i < body.mesh().num_vertices(); ++i)
    min_distance = std::min(min_distance, body.x().segment<3>(3 * i).norm());
  EXPECT_LT(gap, 1e-3) << "seam opened";
  EXPECT_GT(min_distance, 0.25 - 1e-6) << "cloth inside the sphere";
  // The hem (radius 0.19 m, narrower than the sphere) falls from z = 0.3 onto the sphere, which it meets at
  // z = sqrt(0.25² − 0.19²) = 0.16, and stays there (free fall would have taken it 0.8 m down).
  const double hem = body.x().reshaped(3, body.mesh().num_vertices()).row(2).minCoeff();
  EXPECT_LT(hem, 0.2);
  EXPECT_GT(hem, 0.1);
}

TEST(Simulation, AClothStartingInsideAnObstacleIsAnInputErrorNamingBoth) {
  // The drape with its cloth lowered through the sphere's centre: projecting it out would pile vertices onto the
  // surface, so the scene is refused before any solve, naming the cloth, the obstacle and the deepest vertex.
  const std::string path = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/drape_sphere.json";
  Json j = load_json(path);
  j["cloths"][0]["mesh"]["vertices"] = 400;
  j["cloths"][0]["transform"]["translation"] = {-0.5, -0.5, 0.0};
  const sim::Scene scene = sim::parse_scene(j, path, fs::path(path).parent_path());
  try {
    sim::Simulator s(scene);
    FAIL() << "a cloth through the sphere was accepted";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("cloths[0]"), std::string::npos) << msg;
    EXPECT_NE(msg.find("starts inside obstacle \"" + scene.obstacles[0].name + "\""), std::string::npos) << msg;
    EXPECT_NE(msg.find("deepest vertex"), std::string::npos) << msg;
  }
  // Resting within the contact layer is allowed: the shipped drape starts above the sphere.
  EXPECT_NO_THROW(sim::Simulator(shipped("drape_sphere", 400, 1)));
}
