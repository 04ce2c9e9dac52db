// Mesh obstacles end to end: cloth on an OBJ box, a zero-thickness plate pushing a pinned cloth up by many contact
// layers per step, and the scene errors of obstacle meshes. Every step is checked by the exact intersection checker
// with the obstacle's triangles.
#include <mgcloth/collision/intersections.hpp>
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/geometry/mannequin.hpp>
#include <mgcloth/mesh/pattern.hpp>
#include <mgcloth/sim/gltf_export.hpp>
#include <mgcloth/sim/gltf_skin.hpp>
#include <mgcloth/sim/recorder.hpp>
#include <mgcloth/sim/simulator.hpp>

#include "resume_fixture.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <string>

using namespace mgcloth;
namespace fs = std::filesystem;

namespace {

/// A folder of its own for the test's OBJ files, removed at the end.
struct Scratch {
  fs::path dir;
  explicit Scratch(const std::string& name)
      : dir(fs::temp_directory_path() / ("mgcloth_mesh_obstacles_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() { fs::remove_all(dir); }
};

/// A closed box of half extents h about the origin, 12 triangles, outward faces.
std::string box_obj(double h) {
  std::string s;
  for (int i = 0; i < 8; ++i)
    s += fmt::format("v {} {} {}\n", (i & 1 ? h : -h), (i & 2 ? h : -h), (i & 4 ? h : -h));
  for (const char* f : {"1 3 4 2", "5 6 8 7", "1 2 6 5", "3 7 8 4", "1 5 7 3", "2 4 8 6"}) s += fmt::format("f {}\n", f);
  return s;
}

/// A square plate of half side h in z = 0 (two triangles, no thickness).
std::string plate_obj(double h) {
  return fmt::format("v {0} {0} 0\nv {1} {0} 0\nv {1} {1} 0\nv {0} {1} 0\nf 1 2 3\nf 1 3 4\n", -h, h);
}

/// A 0.4 m cotton square of `vertices` at height z, centred over the origin.
Json cloth(int vertices, double z) {
  return Json{{"name", "sheet"},
              {"mesh", {{"generator", "rectangle"}, {"width", 0.4}, {"height", 0.4}, {"vertices", vertices}}},
              {"transform", {{"translation", {-0.2, -0.2, z}}}},
              {"material", {{"preset", "cotton"}}}};
}

Json scene(const Json& cloth_json, const Json& obstacle, int frames) {
  return Json{{"time_step", 1.0 / 30.0},
              {"frames", frames},
              {"cloths", Json::array({cloth_json})},
              {"obstacles", Json::array({obstacle})},
              {"cloth_contact", Json::object()},
              {"solver", {{"name", "fmg"}, {"rel_grad", 1e-3}, {"max_iters", 200}}}};
}

/// Every step: no intersection between the cloth and itself or the obstacle (the simulator's checker, and a second
/// call with the obstacle's triangles), a positive distance, and the obstacle where its motion puts it.
/// With `converged`, also every step's solve (re-solves after a moving obstacle keep the step's criterion).
void run_checked(sim::Simulator& s, int frames, bool converged = false) {
  for (int f = 0; f < frames; ++f) {
    for (const auto& st : s.advance_frame()) {
      ASSERT_EQ(st.intersections, 0) << "frame " << f + 1;
      ASSERT_GT(st.min_distance, 0.0) << "frame " << f + 1;
      if (converged) {
        EXPECT_EQ(st.report.status, "converged") << "frame " << f + 1;
      }
    }
    const auto& group = s.group(0);
    const physics::ClothContact* c = group.cloth_contact();
    ASSERT_TRUE(c);
    ASSERT_GT(c->num_kinematic(), 0);
    // The checker sees the garment as sewn: triangles across a closed seam share its point (joined_points).
    const VecX all = c->with_kinematic(group.x());
    ASSERT_EQ(collision::find_intersections(all, c->triangles(), 100, nullptr, c->cloth_triangles(), &c->joined_points())
                  .size(),
              0u)
        << "frame " << f + 1;
    const geometry::Obstacle& o = group.mesh_obstacles()[0];
    ASSERT_LE((c->kinematic_positions() - o.mesh_positions(s.time())).norm(), 1e-12) << "frame " << f + 1;
  }
}

/// The InputError a scene gives (files relative to `dir`), or "accepted".
std::string scene_error(const Json& j, const fs::path& dir) {
  try {
    sim::parse_scene(j, "bad.json", dir);
  } catch (const InputError& e) {
    return e.what();
  }
  return "accepted";
}

bool has(const std::string& message, const std::string& part) { return message.find(part) != std::string::npos; }

}  // namespace

TEST(MeshObstacles, AClothDropsOntoAnObjBoxAndDrapesOverItWithoutIntersecting) {
  Scratch scratch("box");
  const fs::path box = scratch.dir / "box.obj";
  write_file_atomic(box, box_obj(0.1));
  Json j = scene(cloth(400, 0.13), {{"name", "box"}, {"mesh", box.string()}, {"friction", 0.3}}, 20);
  sim::Simulator s(sim::parse_scene(j, "box.json", scratch.dir));
  run_checked(s, 20);
  const auto x = as_columns(s.cloths()[0]->x());
  // It rests on the top (z = 0.1) about the layer's thickness (1 mm) above it, and hangs over the sides.
  EXPECT_GT(x.row(2).maxCoeff(), 0.1);
  EXPECT_LT(x.row(2).maxCoeff(), 0.11);
  EXPECT_LT(x.row(2).minCoeff(), 0.05);
  for (Index i = 0; i < x.cols(); ++i)
    EXPECT_FALSE(std::abs(x(0, i)) < 0.1 && std::abs(x(1, i)) < 0.1 && x(2, i) < 0.1) << "vertex " << i << " inside";
}

// The plate rises 1.7 cm per step, 17 times the contact layer, into a cloth held at its corners; it has no
// thickness, so anything that let a vertex pass would show as an intersection.
TEST(MeshObstacles, AThinPlateRisingIntoAPinnedClothPushesItUpWithoutPassingThrough) {
  Scratch scratch("plate");
  const fs::path plate = scratch.dir / "plate.obj";
  write_file_atomic(plate, plate_obj(0.08));
  Json c = cloth(400, 0.15);
  c["pins"] = Json::array({{{"points", {{0.0, 0.0}, {0.4, 0.0}, {0.0, 0.4}, {0.4, 0.4}}}, {"stiffness", 1e4}}});
  Json j = scene(c,
                 {{"name", "plate"},
                  {"mesh", "plate.obj"},
                  {"position", {0.0, 0.0, 0.05}},
                  {"motion", {{"type", "constant_velocity"}, {"linear_velocity", {0.0, 0.0, 0.5}}}}},
                 18);
  sim::Simulator s(sim::parse_scene(j, "plate.json", scratch.dir));
  run_checked(s, 18, true);
  // The plate is at 0.05 + 0.5 · 0.6 = 0.35 m, 20 cm above the pins: the cloth over it is above it.
  const double top = 0.05 + 0.5 * s.time();
  const auto x = as_columns(s.cloths()[0]->x());
  Index over = 0;
  for (Index i = 0; i < x.cols(); ++i)
    if (std::abs(x(0, i)) < 0.07 && std::abs(x(1, i)) < 0.07) {
      ++over;
      EXPECT_GT(x(2, i), top) << "vertex " << i;
    }
  EXPECT_GT(over, 10);
}

// A deforming obstacle from an OBJ sequence: the plate of the test above, lifted 2 cm per frame file, 30 files per
// second. Its vertices follow the files, interpolated in time, held after the last (or looped), placed by its pose.
TEST(MeshObstacles, AnObjSequenceDeformsTheObstacleInTime) {
  Scratch scratch("sequence");
  const auto plate_at = [](double z) {
    return fmt::format("v -0.08 -0.08 {0}\nv 0.08 -0.08 {0}\nv 0.08 0.08 {0}\nv -0.08 0.08 {0}\nf 1 2 3\nf 1 3 4\n", z);
  };
  for (int k = 0; k < 4; ++k) write_file_atomic(scratch.dir / fmt::format("lift_{:03d}.obj", k), plate_at(0.02 * k));
  Json c = cloth(200, 0.15);
  c["pins"] = Json::array({{{"points", {{0.0, 0.0}, {0.4, 0.0}, {0.0, 0.4}, {0.4, 0.4}}}, {"stiffness", 1e4}}});
  Json j = scene(c, {{"name", "plate"}, {"mesh", "lift_%03d.obj"}, {"mesh_rate", 30.0}, {"position", {0.0, 0.0, 0.05}}},
                 6);
  {
    sim::Simulator s(sim::parse_scene(j, "sequence.json", scratch.dir));
    const geometry::Obstacle& o = s.group(0).mesh_obstacles()[0];
    ASSERT_EQ(o.mesh->frames.size(), 4u);
    const auto z = [&](double t) { return o.mesh_positions(t)[2]; };
    EXPECT_NEAR(z(0.0), 0.05, 1e-12);
    EXPECT_NEAR(z(1.5 / 30.0), 0.08, 1e-12);
    EXPECT_NEAR(z(3.0 / 30.0), 0.11, 1e-12);
    EXPECT_NEAR(z(1.0), 0.11, 1e-12);  // held after the last file
    run_checked(s, 6);
  }
  j["obstacles"][0]["mesh_loop"] = true;
  sim::Simulator looped(sim::parse_scene(j, "sequence.json", scratch.dir));
  const geometry::Obstacle& o = looped.group(0).mesh_obstacles()[0];
  EXPECT_NEAR(o.mesh_positions(4.0 / 30.0)[2], 0.05, 1e-12);       // the first file again after four
  EXPECT_NEAR(o.mesh_positions(3.5 / 30.0)[2], 0.05 + 0.03, 1e-12);  // half way from the last to the first
}

// The shipped scene at low resolution: the tablecloth lands on the round table's OBJ mesh and hangs over its edge.
TEST(MeshObstacles, TheShippedRoundTableRunsWithoutIntersections) {
  Json j = load_json(std::string(MGCLOTH_SOURCE_DIR) + "/scenes/round_table.json");
  j["cloths"][0]["mesh"]["vertices"] = 400;
  sim::Simulator s(sim::parse_scene(j, "round_table.json", fs::path(MGCLOTH_SOURCE_DIR) / "scenes"));
  run_checked(s, 15, true);  // a still obstacle: no step solves twice
  const auto x = as_columns(s.cloths()[0]->x());
  // Landed on the top (z = 0.75): the middle rests on it at about the layer's thickness; hanging over the rim
  // (radius 0.4) by far more than the 3 cm edge.
  Index middle = 0;
  (x.topRows<2>().colwise().squaredNorm()).minCoeff(&middle);
  EXPECT_GT(x(2, middle), 0.75);
  EXPECT_LT(x(2, middle), 0.755);
  EXPECT_LT(x.row(2).maxCoeff(), 0.8);
  EXPECT_LT(x.row(2).minCoeff(), 0.6);
  for (Index i = 0; i < x.cols(); ++i)
    EXPECT_FALSE(x.col(i).head<2>().norm() < 0.4 && x(2, i) < 0.75 && x(2, i) > 0.72) << "vertex " << i << " in the top";
}

// Resumed from a step's state, a run with a moving mesh obstacle repeats the uninterrupted one bit for bit: the
// obstacle is where its motion puts it at every step's end, so the state needs nothing of it.
TEST(MeshObstacles, AResumedRunRepeatsTheUninterruptedOneBitForBit) {
  Scratch scratch("resume");
  write_file_atomic(scratch.dir / "plate.obj", plate_obj(0.08));
  Json c = cloth(150, 0.15);
  c["pins"] = Json::array({{{"points", {{0.0, 0.0}, {0.4, 0.0}, {0.0, 0.4}, {0.4, 0.4}}}, {"stiffness", 1e4}}});
  const Json j = scene(c,
                       {{"name", "plate"},
                        {"mesh", "plate.obj"},
                        {"friction", 0.3},
                        {"position", {0.0, 0.0, 0.05}},
                        {"motion", {{"type", "constant_velocity"}, {"linear_velocity", {0.0, 0.0, 0.5}}}}},
                       10);
  const sim::Scene sc = sim::parse_scene(j, "resume.json", scratch.dir);
  sim::Simulator straight(sc), first(sc);
  for (int f = 0; f < 10; ++f) straight.advance_frame();
  for (int f = 0; f < 6; ++f) first.advance_frame();
  auto resumed = sim::fixtures::resumed_from(sc, first);
  for (int f = 6; f < 10; ++f) resumed->advance_frame();
  EXPECT_EQ(resumed->bodies()[0]->x(), straight.bodies()[0]->x());
  EXPECT_EQ(resumed->bodies()[0]->v(), straight.bodies()[0]->v());
}

TEST(MeshObstacles, ClothThatStartsThroughAnObstacleMeshIsRefusedByTriangle) {
  Scratch scratch("start");
  write_file_atomic(scratch.dir / "plate.obj", plate_obj(0.08));
  Json c = cloth(100, 0.0);
  c["transform"]["rotation_deg"] = {90.0, 0.0, 0.0};  // upright, through the plate
  c["transform"]["translation"] = {-0.2, 0.0, -0.2};
  const Json j = scene(c, {{"name", "plate"}, {"mesh", "plate.obj"}}, 1);
  try {
    sim::Simulator s(sim::parse_scene(j, "start.json", scratch.dir));
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("obstacle \"plate\" triangle"), std::string::npos) << m;
    EXPECT_NE(m.find("cloth \"sheet\" triangle"), std::string::npos) << m;
  }
}

TEST(MeshObstacles, SceneErrorsNameTheObstacle) {
  Scratch scratch("errors");
  write_file_atomic(scratch.dir / "plate.obj", plate_obj(0.08));
  const auto error = [&](const Json& j) { return scene_error(j, scratch.dir); };
  // A missing file, named with its path and the key.
  std::string m = error(scene(cloth(100, 0.2), {{"mesh", "nowhere.obj"}}, 1));
  EXPECT_TRUE(has(m, "obstacles[0].mesh") && has(m, "nowhere.obj") && has(m, "cannot open file")) << m;
  // Both a shape and a mesh.
  m = error(scene(cloth(100, 0.2), {{"mesh", "plate.obj"}, {"shape", {{"type", "sphere"}, {"radius", 0.1}}}}, 1));
  EXPECT_TRUE(has(m, "obstacles[0].shape") && has(m, "not both")) << m;
  // Without cloth contact.
  Json j = scene(cloth(100, 0.2), {{"mesh", "plate.obj"}}, 1);
  j.erase("cloth_contact");
  m = error(j);
  EXPECT_TRUE(has(m, "obstacles[0].mesh") && has(m, "cloth_contact")) << m;
  // The name of a cloth, and a thickness on a shape (where it is no key).
  m = error(scene(cloth(100, 0.2), {{"name", "sheet"}, {"mesh", "plate.obj"}}, 1));
  EXPECT_TRUE(has(m, "obstacles[0].name") && has(m, "cloths[0]")) << m;
  m = error(scene(cloth(100, 0.2), {{"shape", {{"type", "sphere"}, {"radius", 0.1}}}, {"contact_thickness", 0.001}}, 1));
  EXPECT_TRUE(has(m, "contact_thickness")) << m;
  // Sequences: a pattern that is not one integer field, no rate, no first file, a file of another topology.
  m = error(scene(cloth(100, 0.2), {{"mesh", "frame_%s.obj"}, {"mesh_rate", 30}}, 1));
  EXPECT_TRUE(has(m, "obstacles[0].mesh") && has(m, "%0Nd")) << m;
  write_file_atomic(scratch.dir / "f_1.obj", plate_obj(0.08));
  m = error(scene(cloth(100, 0.2), {{"mesh", "f_%d.obj"}}, 1));
  EXPECT_TRUE(has(m, "obstacles[0].mesh_rate")) << m;
  m = error(scene(cloth(100, 0.2), {{"mesh", "g_%d.obj"}, {"mesh_rate", 30}}, 1));
  EXPECT_TRUE(has(m, "g_1.obj") && has(m, "cannot open file")) << m;
  write_file_atomic(scratch.dir / "f_2.obj", box_obj(0.1));
  m = error(scene(cloth(100, 0.2), {{"mesh", "f_%d.obj"}, {"mesh_rate", 30}}, 1));
  EXPECT_TRUE(has(m, "f_2.obj") && has(m, "one topology")) << m;
  m = error(scene(cloth(100, 0.2), {{"mesh", "plate.obj"}, {"mesh_rate", 30}}, 1));
  EXPECT_TRUE(has(m, "mesh_rate")) << m;  // no key of a single file
  // A malformed OBJ: the file's own message with its line.
  write_file_atomic(scratch.dir / "bad.obj", "v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n");
  m = error(scene(cloth(100, 0.2), {{"mesh", "bad.obj"}}, 1));
  EXPECT_TRUE(has(m, "bad.obj") && has(m, "line 2")) << m;
}

namespace {

/// A poncho (a square with a hole for the head) over the shoulders of the generated body, coarse enough for a test.
Json poncho_scene(const Json& body_obstacle, int frames) {
  Json poncho = {{"name", "poncho"},
                 {"mesh",
                  {{"generator", "rectangle"},
                   {"width", 0.9},
                   {"height", 0.9},
                   {"vertices", 500},
                   {"unstructured", true},
                   {"holes", Json::array({{{"center", {0.45, 0.45}}, {"radius", 0.1}}})}}},
                 {"transform", {{"translation", {-0.45, -0.45, 1.5}}}},
                 {"material", {{"preset", "cotton"}}}};
  return scene(poncho, body_obstacle, frames);
}

}  // namespace

// The generated mannequin walks out from under a poncho dropped on its shoulders: the poncho rests on the body,
// never intersects it (the body moves 4 cm and its hands up to 10 cm per step), and is carried forward.
TEST(MeshObstacles, APonchoOnTheWalkingBodyIsCarriedAlongWithoutIntersecting) {
  Scratch scratch("body");
  const Json body = {{"name", "body"},
                     {"body", {{"resolution", 0.03}, {"walk", {{"stand", 0.3}, {"ramp", 0.3}}}}},
                     {"friction", 0.4}};
  sim::Simulator s(sim::parse_scene(poncho_scene(body, 30), "poncho.json", scratch.dir));
  run_checked(s, 10);
  // Standing: the poncho has dropped onto the shoulders (1.40–1.47 m) and hangs there.
  auto x = as_columns(s.cloths()[0]->x());
  EXPECT_GT(x.row(2).maxCoeff(), 1.40);
  EXPECT_LT(x.row(2).maxCoeff(), 1.50);
  const double x0 = x.row(0).mean();
  int rounds = 0;
  for (int f = 10; f < 30; ++f) {
    for (const auto& st : s.advance_frame()) {
      ASSERT_EQ(st.intersections, 0) << "frame " << f + 1;
      rounds += st.obstacle_rounds;
    }
  }
  x = as_columns(s.cloths()[0]->x());
  // About 0.7 s of walking at up to 1.35 m/s: the body went ~0.6 m, and the poncho with it, still on the shoulders.
  const VecX& y = s.group(0).cloth_contact()->kinematic_positions();
  const double body_x = Eigen::Map<const Mat3X>(y.data(), 3, y.size() / 3).row(0).mean();
  std::printf("walked %.3f m, poncho %.3f m, %d obstacle rounds\n", body_x, x.row(0).mean() - x0, rounds);
  EXPECT_GT(body_x, 0.4);
  EXPECT_NEAR(x.row(0).mean() - x0, body_x, 0.15);
  EXPECT_GT(x.row(2).maxCoeff(), 1.38);
  RecordProperty("obstacle_rounds", rounds);
}

// A skinned glb (here the mannequin, written by write_skinned_glb) is a deforming mesh obstacle: the scene's
// surface follows the file's skin at every time.
TEST(MeshObstacles, AGlbSkinIsAMeshObstacleThatFollowsItsAnimation) {
  if (!sim::glb_available()) GTEST_SKIP() << "built without tinygltf";
  Scratch scratch("glb");
  geometry::MannequinParams m;
  m.resolution = 0.03;
  geometry::WalkParams w;
  w.stand = 0.1;
  w.ramp = 0.2;
  w.duration = 1.0;
  const geometry::SkinnedMesh skin = geometry::make_mannequin(m, w);
  sim::write_skinned_glb(scratch.dir / "walker.glb", skin);
  const sim::Scene sc = sim::parse_scene(poncho_scene({{"name", "walker"}, {"mesh", "walker.glb"}}, 1), "glb.json", scratch.dir);
  const geometry::Obstacle ob = sc.obstacles[0].build();
  ASSERT_TRUE(ob.mesh && ob.mesh->skin);
  EXPECT_EQ(ob.mesh->tris.size(), skin.tris.size());
  for (const double t : {0.0, 0.25, 0.5, 0.9, 2.0}) {
    const Mat3X want = skin.at(t);
    const VecX got = ob.mesh_positions(t);
    ASSERT_EQ(got.size(), want.size());
    EXPECT_LT((got - want.reshaped()).cwiseAbs().maxCoeff(), 1e-5) << "t = " << t;
  }
  // And the file feeds a run.
  sim::Simulator s(sim::parse_scene(poncho_scene({{"name", "walker"}, {"mesh", "walker.glb"}}, 3), "glb.json", scratch.dir));
  run_checked(s, 3);
}

TEST(MeshObstacles, BodySceneErrorsNameTheKey) {
  Scratch scratch("body_errors");
  const auto error = [&](const Json& j) { return scene_error(j, scratch.dir); };
  std::string m = error(scene(cloth(100, 0.2), {{"body", {{"height", 3.0}}}}, 1));
  EXPECT_TRUE(has(m, "obstacles[0].body.height")) << m;
  m = error(scene(cloth(100, 0.2), {{"body", {{"walk", {{"speed", 2.0}}}}}}, 1));
  EXPECT_TRUE(has(m, "obstacles[0].body.walk.speed") && has(m, "unknown key")) << m;
  m = error(scene(cloth(100, 0.2), {{"body", Json::object()}, {"mesh", "x.obj"}}, 1));
  EXPECT_TRUE(has(m, "obstacles[0].mesh")) << m;
  Json j = scene(cloth(100, 0.2), {{"body", Json::object()}}, 1);
  j.erase("cloth_contact");
  m = error(j);
  EXPECT_TRUE(has(m, "obstacles[0].body") && has(m, "cloth_contact")) << m;
  write_file_atomic(scratch.dir / "junk.glb", "not a glb");
  m = error(scene(cloth(100, 0.2), {{"mesh", "junk.glb"}}, 1));
  EXPECT_TRUE(has(m, "obstacles[0].mesh") && has(m, "junk.glb")) << m;
}

// The shipped skirt pattern on the standing mannequin: its panels start apart around the hips, the seam springs
// sew them during the first frames, and the skirt then hangs from the hips, closed, never through the body.
TEST(MeshObstacles, ASkirtSewnFromItsPatternClosesItsSeamsAroundTheBody) {
  Scratch scratch("skirt");
  Json skirt = {{"name", "skirt"},
                {"mesh", {{"pattern", std::string(MGCLOTH_SOURCE_DIR) + "/scenes/patterns/skirt.json"}, {"resolution", 0.05}}},
                {"material", {{"preset", "cotton"}}}};
  Json j = scene(skirt, {{"name", "body"}, {"body", {{"resolution", 0.04}}}, {"friction", 0.4}}, 8);
  j["cloth_contact"] = {{"thickness", 0.002}};
  sim::Simulator s(sim::parse_scene(j, "skirt.json", scratch.dir));
  const mesh::PatternMesh pm =
      mesh::triangulate_pattern(mesh::read_pattern(std::string(MGCLOTH_SOURCE_DIR) + "/scenes/patterns/skirt.json"), 0.05);
  ASSERT_EQ(pm.mesh.num_vertices(), s.cloths()[0]->x().size() / 3);
  const auto widest_gap = [&] {
    const auto x = as_columns(s.cloths()[0]->x());
    double gap = 0.0;
    for (const auto& seam : pm.stitch_pairs)
      for (const auto& [a, b] : seam) gap = std::max(gap, (x.col(a) - x.col(b)).norm());
    return gap;
  };
  EXPECT_GT(widest_gap(), 0.25);  // the waist's side seams start a third of a metre apart
  // Sewn within four frames (0.14 mm measured), every step converged, and it stays sewn: every stitched pair within
  // a quarter of the cloths' 2 mm contact layer (springs, not constraints; the two sides of a seam are not contact
  // pairs, or the layer would hold them 2 mm apart against the springs); the skirt hangs on the hips.
  run_checked(s, 4, true);
  EXPECT_LT(widest_gap(), 0.0005);
  run_checked(s, 4, true);
  EXPECT_LT(widest_gap(), 0.0005);
  const auto x = as_columns(s.cloths()[0]->x());
  EXPECT_GT(x.row(2).maxCoeff(), 0.9);
  // A pattern the scene cannot read: the key and the file.
  skirt["mesh"]["pattern"] = "nowhere.json";
  const std::string m = scene_error(scene(skirt, {{"body", Json::object()}}, 1), scratch.dir);
  EXPECT_TRUE(has(m, "cloths[0].mesh.pattern") && has(m, "nowhere.json")) << m;
}

// A run must not resume with an edited pattern: the checkpoint's scene fingerprint holds the file's content.
TEST(MeshObstacles, ThePatternFilesContentIsPartOfTheScenesFingerprint) {
  Scratch scratch("pattern_fingerprint");
  const fs::path pattern = scratch.dir / "skirt.json";
  std::string text = read_file(fs::path(MGCLOTH_SOURCE_DIR) / "scenes/patterns/skirt.json");
  write_file_atomic(pattern, text);
  const Json skirt = {{"name", "skirt"},
                      {"mesh", {{"pattern", pattern.string()}, {"resolution", 0.05}}},
                      {"material", {{"preset", "cotton"}}}};
  const Json j = scene(skirt, {{"name", "body"}, {"body", {{"resolution", 0.05}}}}, 1);
  const std::uint64_t before = sim::scene_fingerprint(sim::parse_scene(j, "a.json", scratch.dir));
  EXPECT_EQ(sim::scene_fingerprint(sim::parse_scene(j, "a.json", scratch.dir)), before);
  const size_t at = text.find("0.36");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 4, "0.37");
  write_file_atomic(pattern, text);
  EXPECT_NE(sim::scene_fingerprint(sim::parse_scene(j, "a.json", scratch.dir)), before);
}
