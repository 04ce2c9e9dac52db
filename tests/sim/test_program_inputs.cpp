// What a program driving the simulator (the Python module) adds to a scene: meshes given in memory, scripted pin
// targets and steered obstacles.
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <gtest/gtest.h>

using namespace mgcloth;

namespace {

/// A 0.5 m cloth of 64 vertices pinned at two corners, over a sphere, solved tightly so that pins sit where pulled.
sim::Scene small_scene() {
  const Json j = {
      {"time_step", 1.0 / 30.0},
      {"threads", 1},
      {"cloths",
       {{{"name", "c"},
         {"mesh", {{"generator", "rectangle"}, {"width", 0.5}, {"height", 0.5}, {"vertices", 64}}},
         {"transform", {{"translation", {-0.25, -0.25, 0.1}}}},
         {"pins", {{{"vertices", {0, 7}}, {"stiffness", 1e5}}}}}}},
      {"obstacles", {{{"name", "ball"}, {"shape", {{"type", "sphere"}, {"radius", 0.1}}}, {"position", {0, 0, -0.2}}}}},
      {"solver", {{"name", "newton-direct"}, {"rel_grad", 1e-8}}}};
  return sim::parse_scene(j, "test", ".");
}

Vec3 vertex_of(const bodies::ClothBody& c, Index v) { return c.x().segment<3>(3 * v); }

}  // namespace

TEST(ProgramInputs, MeshInMemoryStepsExactlyLikeTheGeneratedOne) {
  const sim::Scene scene = small_scene();
  sim::Simulator generated(scene);
  auto mesh = std::make_shared<mesh::TriMesh>(mesh::make_rectangle(scene.cloths[0].mesh.rectangle));
  sim::Scene given = scene;
  given.cloths[0].mesh.generator = "tube";  // must not be used: the mesh given replaces it
  sim::Simulator in_memory(given, {mesh});
  for (int f = 0; f < 3; ++f) {
    generated.advance_frame();
    in_memory.advance_frame();
  }
  const VecX& a = generated.cloths()[0]->x();
  const VecX& b = in_memory.cloths()[0]->x();
  ASSERT_EQ(a.size(), b.size());
  EXPECT_TRUE((a.array() == b.array()).all());
}

TEST(ProgramInputs, BadMeshInMemoryIsAnInputErrorNamingTheCloth) {
  auto mesh = std::make_shared<mesh::TriMesh>(mesh::make_rectangle(small_scene().cloths[0].mesh.rectangle));
  mesh->tris[3][2] = mesh->tris[3][1];  // a repeated vertex
  try {
    sim::Simulator s(small_scene(), {mesh});
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cloths[0] (\"c\"): mesh arrays: triangle 3"), std::string::npos) << what;
  }
  EXPECT_THROW(sim::Simulator(small_scene(), {mesh, mesh}), InputError);  // more meshes than cloths
}

TEST(ProgramInputs, ScriptedPinTargetsMoveThePinsOverTheFrame) {
  sim::Simulator s(small_scene());
  const auto& body = *s.cloths()[0];
  const auto& pins = body.pinned_vertices();
  std::vector<Vec3> targets = body.pin_targets(0.0);
  const Vec3 start = targets[0];
  for (int f = 0; f < 5; ++f) {
    for (auto& t : targets) t += Vec3(0.02, 0.0, 0.01);
    s.set_pin_targets(0, targets);
    // Halfway through the frame the targets are halfway from where they pulled to where they go.
    const auto mid = body.pin_targets(s.time() + 0.5 * s.scene().frame_time);
    EXPECT_LT((mid[0] - (targets[0] - Vec3(0.01, 0.0, 0.005))).norm(), 1e-12);
    s.advance_frame();
    for (size_t p = 0; p < pins.size(); ++p) EXPECT_LT((vertex_of(body, pins[p]) - targets[p]).norm(), 2e-3) << f;
  }
  EXPECT_LT((body.pin_targets(s.time())[0] - (start + Vec3(0.1, 0.0, 0.05))).norm(), 1e-12);
  EXPECT_THROW(s.set_pin_targets(0, {Vec3::Zero()}), InputError);  // two pins
  EXPECT_THROW(s.set_pin_targets(0, {Vec3::Zero(), Vec3(kInf, 0, 0)}), InputError);
  EXPECT_THROW(s.set_pin_targets(1, targets), InputError);
}

TEST(ProgramInputs, SteerableMotionKeysThePosesItIsGiven) {
  geometry::Pose start;
  auto base = std::make_shared<geometry::ConstantVelocityMotion>(start, Vec3(1, 0, 0), Vec3::Zero());
  sim::SteerableMotion m(base);
  Vec3 lin, ang;
  m.velocity(0.05, lin, ang);
  EXPECT_EQ(lin, Vec3(1, 0, 0));  // the scene's motion until steered

  geometry::Pose up;
  up.translation = Vec3(0, 0, 1);
  m.steer(0.1, 0.2, up);
  EXPECT_LT((m.pose(0.05).translation - Vec3(0.05, 0, 0)).norm(), 1e-15);
  EXPECT_LT((m.pose(0.15).translation - Vec3(0.05, 0, 0.5)).norm(), 1e-12);
  // The step that ends on the key moved along the segment before it.
  m.velocity(0.2, lin, ang);
  EXPECT_LT((lin - Vec3(-1, 0, 10)).norm(), 1e-9);
  m.velocity(0.25, lin, ang);
  EXPECT_EQ(lin, Vec3::Zero());
  EXPECT_EQ(m.pose(0.3).translation, up.translation);

  // Steered again before the step was taken: the new pose replaces the old one, from the same start.
  geometry::Pose side;
  side.translation = Vec3(0, 1, 0);
  side.rotation = Eigen::AngleAxisd(0.5, Vec3::UnitZ());
  m.steer(0.1, 0.2, side);
  EXPECT_LT((m.pose(0.15).translation - Vec3(0.05, 0.5, 0)).norm(), 1e-12);
  m.velocity(0.2, lin, ang);
  EXPECT_LT((ang - Vec3(0, 0, 5)).norm(), 1e-9);
  geometry::Pose bad;
  bad.rotation.coeffs().setZero();
  EXPECT_THROW(m.steer(0.2, 0.3, bad), InputError);
}

TEST(ProgramInputs, SteeredSphereLiftsTheCloth) {
  sim::Simulator s(small_scene());
  for (int f = 0; f < 6; ++f) {
    geometry::Pose p;
    p.translation = Vec3(0, 0, -0.2 + 0.06 * (f + 1));
    s.set_obstacle_pose(0, p);
    s.advance_frame();
    EXPECT_LT((s.obstacles()[0].motion->pose(s.time()).translation - p.translation).norm(), 1e-12);
  }
  // The sphere's top rose from -0.1 to 0.26, through the cloth's start at z = 0.1: the cloth's middle lies on it.
  const auto x = as_columns(s.cloths()[0]->x());
  Index middle = 0;
  x.topRows(2).colwise().squaredNorm().minCoeff(&middle);
  EXPECT_GT(x(2, middle), 0.25);
  geometry::Pose nan_pose;
  nan_pose.translation.x() = std::nan("");
  EXPECT_THROW(s.set_obstacle_pose(0, nan_pose), InputError);
  EXPECT_THROW(s.set_obstacle_pose(1, geometry::Pose{}), InputError);
}
