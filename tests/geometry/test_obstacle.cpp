#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/obstacle.hpp>

#include <geometry/sdf_checks.hpp>
#include <gtest/gtest.h>

namespace mgcloth::geometry {
namespace {

using test::derivatives_match;
using test::random_point;

Pose some_pose() {
  Pose pose;
  pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.9, Vec3(1, -2, 0.7).normalized()));
  pose.translation = Vec3(0.3, -0.5, 0.8);
  return pose;
}

std::vector<std::shared_ptr<const Shape>> all_shapes() {
  return {std::make_shared<Plane>(), std::make_shared<Sphere>(0.6), std::make_shared<Box>(Vec3(0.4, 0.7, 1.1)),
          std::make_shared<Capsule>(0.3, 0.5)};
}

TEST(Obstacle, PosedSdfIsLocalSdfAtTransformedPoint) {
  const Pose pose = some_pose();
  const Mat3 rot = pose.rotation.toRotationMatrix();
  std::mt19937 rng(3);
  for (const auto& shape : all_shapes()) {
    const Obstacle obstacle{"o", shape, nullptr, 0.0, nullptr, 0.0};
    for (int i = 0; i < 200; ++i) {
      const Vec3 p_local = random_point(rng, 1.5);
      const Vec3 p_world = pose.to_world(p_local);
      const SdfSample local = shape->eval(p_local);
      const SdfSample world = obstacle.sdf(p_world, pose);
      EXPECT_NEAR(world.phi, local.phi, 1e-14) << shape->type();
      EXPECT_TRUE(world.grad.isApprox(rot * local.grad, 1e-14)) << shape->type();
      EXPECT_LT((world.hess - rot * local.hess * rot.transpose()).norm(), 1e-13 * std::max(1.0, local.hess.norm()));
    }
  }
}

TEST(Obstacle, WorldDerivativesMatchFiniteDifferences) {
  const Pose pose = some_pose();
  std::mt19937 rng(11);
  // Points sampled where every shape is smooth in its local frame (see test_shapes.cpp for the sets).
  const auto sphere = std::make_shared<Sphere>(0.6);
  const auto capsule = std::make_shared<Capsule>(0.3, 0.5);
  const auto box = std::make_shared<Box>(Vec3(0.4, 0.7, 1.1));
  const std::vector<std::pair<std::shared_ptr<const Shape>, std::function<bool(const Vec3&)>>> cases = {
      {std::make_shared<Plane>(), [](const Vec3&) { return true; }},
      {sphere, [](const Vec3& p) { return p.norm() > 0.05; }},
      {capsule,
       [](const Vec3& p) {
         const double beyond = std::abs(p.z()) - 0.5;
         return std::abs(beyond) > 1e-2 && Vec3(p.x(), p.y(), std::max(beyond, 0.0)).norm() > 0.05;
       }},
      {box, [](const Vec3& p) {
         const Vec3 q = p.cwiseAbs() - Vec3(0.4, 0.7, 1.1);
         if (q.cwiseAbs().minCoeff() < 1e-2 || p.cwiseAbs().minCoeff() < 1e-2) return false;
         Vec3 s = q;
         std::sort(s.data(), s.data() + 3);
         return q.maxCoeff() > 0 || s[2] - s[1] > 1e-2;
       }}};
  for (const auto& [shape, is_smooth_there] : cases) {
    const Obstacle obstacle{shape->type(), shape, nullptr, 0.0, nullptr, 0.0};
    int checked = 0;
    for (int i = 0; i < 500; ++i) {
      const Vec3 p_local = random_point(rng, 1.5);
      if (!is_smooth_there(p_local)) continue;
      ++checked;
      EXPECT_TRUE(derivatives_match([&](const Vec3& x) { return obstacle.sdf(x, pose); }, pose.to_world(p_local)))
          << shape->type();
    }
    EXPECT_GT(checked, 200) << shape->type();
  }
}

TEST(Obstacle, TimeOverloadUsesMotionPose) {
  Pose initial = some_pose();
  const auto motion = std::make_shared<ConstantVelocityMotion>(initial, Vec3(0.2, 0, -0.3), Vec3(0.5, 1.0, -0.2));
  const Obstacle obstacle{"mover", std::make_shared<Box>(Vec3(0.5, 0.3, 0.2)), motion, 0.4, nullptr, 0.0};
  const Vec3 p(0.9, -0.1, 0.4);
  for (double t : {0.0, 0.7}) {
    const SdfSample a = obstacle.sdf(p, t);
    const SdfSample b = obstacle.sdf(p, motion->pose(t));
    EXPECT_EQ(a.phi, b.phi);
    EXPECT_EQ(a.grad, b.grad);
    EXPECT_EQ(a.hess, b.hess);
  }
  // Without a motion the obstacle sits at the identity pose.
  const Obstacle fixed{"fixed", std::make_shared<Sphere>(1.0), nullptr, 0.0, nullptr, 0.0};
  EXPECT_EQ(fixed.sdf(Vec3(0, 0, 3), 5.0).phi, 2.0);
}

TEST(Obstacle, SdfRateIsMinusGradientDotPointVelocity) {
  // phi(p, t) = phi_local(R(t)ᵀ(p - c(t))) at a fixed world point: dphi/dt = -grad · v(p), the velocity of the
  // material point at p. Ties the obstacle's sdf to its motion's point_velocity.
  const auto motion =
      std::make_shared<ConstantVelocityMotion>(some_pose(), Vec3(0.4, -0.3, 0.1), Vec3(0.8, -0.6, 1.3));
  const Obstacle obstacle{"capsule", std::make_shared<Capsule>(0.3, 0.5), motion, 0.0, nullptr, 0.0};
  const Vec3 p(1.1, -0.2, 0.9);
  const double t = 0.4, h = 1e-6;
  const double rate = (obstacle.sdf(p, t + h).phi - obstacle.sdf(p, t - h).phi) / (2 * h);
  EXPECT_NEAR(rate, -obstacle.sdf(p, t).grad.dot(motion->point_velocity(t, p)), 1e-8);
}

TEST(Obstacle, MissingShapeThrows) {
  Obstacle obstacle;
  obstacle.name = "empty";
  EXPECT_THROW(obstacle.sdf(Vec3::Zero(), 0.0), Error);
}

}  // namespace
}  // namespace mgcloth::geometry
