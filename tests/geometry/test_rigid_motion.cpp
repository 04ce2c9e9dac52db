#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/rigid_motion.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

namespace mgcloth::geometry {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

Eigen::Quaterniond rotation(double angle, const Vec3& axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()));
}

/// Rotations compared as matrices, so that q and -q count as equal.
double rotation_gap(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return (a.toRotationMatrix() - b.toRotationMatrix()).norm();
}

/// The velocity of a material point by central differences of its world position over time must match
/// point_velocity: v = linear + angular × (p - c).
void expect_point_velocity_matches_fd(const RigidMotion& motion, double t, const Vec3& p_local) {
  const double h = 1e-6;
  const Vec3 fd = (motion.pose(t + h).to_world(p_local) - motion.pose(t - h).to_world(p_local)) / (2 * h);
  const Vec3 v = motion.point_velocity(t, motion.pose(t).to_world(p_local));
  EXPECT_LT((fd - v).norm(), 1e-7 * std::max(1.0, v.norm())) << "t = " << t << ": " << v.transpose() << " vs fd "
                                                              << fd.transpose();
}

// ---- Pose ----

TEST(Pose, ToLocalInvertsToWorld) {
  Pose pose;
  pose.rotation = rotation(0.7, Vec3(1, 2, -1));
  pose.translation = Vec3(0.3, -1, 2);
  const Vec3 p(0.1, 0.2, 0.3);
  EXPECT_TRUE(pose.to_local(pose.to_world(p)).isApprox(p, 1e-15));
}

// ---- ConstantVelocityMotion ----

TEST(ConstantVelocityMotion, StartsAtInitialPoseAndRotatesAboutItsOrigin) {
  Pose initial;
  initial.rotation = rotation(0.4, Vec3(0, 1, 1));
  initial.translation = Vec3(1, 2, 3);
  const ConstantVelocityMotion motion(initial, Vec3(0.5, 0, -1), Vec3(0, 0, std::numbers::pi));
  EXPECT_LT(rotation_gap(motion.pose(0.0).rotation, initial.rotation), 1e-15);
  EXPECT_TRUE(motion.pose(0.0).translation.isApprox(initial.translation, 0.0));
  // After 0.5 s at pi rad/s about world z: a quarter turn left-multiplied onto the initial rotation.
  const Pose half = motion.pose(0.5);
  EXPECT_LT(rotation_gap(half.rotation, rotation(std::numbers::pi / 2, Vec3::UnitZ()) * initial.rotation), 1e-14);
  EXPECT_TRUE(half.translation.isApprox(Vec3(1.25, 2, 2.5), 1e-15));
  // The body origin moves with the linear velocity only.
  EXPECT_TRUE(motion.point_velocity(0.5, half.translation).isApprox(Vec3(0.5, 0, -1), 1e-15));
}

TEST(ConstantVelocityMotion, PointVelocityMatchesFiniteDifferences) {
  Pose initial;
  initial.rotation = rotation(1.1, Vec3(1, -2, 0.5));
  initial.translation = Vec3(-0.2, 0.4, 1.0);
  const ConstantVelocityMotion motion(initial, Vec3(0.3, -0.7, 0.2), Vec3(1.5, -0.4, 2.0));
  for (double t : {0.0, 0.37, 2.5, -1.2}) {
    for (const Vec3& p : {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.3, -0.8, 1.7)}) {
      expect_point_velocity_matches_fd(motion, t, p);
    }
  }
}

TEST(ConstantVelocityMotion, ZeroAngularVelocityKeepsRotation) {
  Pose initial;
  initial.rotation = rotation(0.9, Vec3(1, 1, 0));
  const ConstantVelocityMotion motion(initial, Vec3(1, 0, 0), Vec3::Zero());
  EXPECT_LT(rotation_gap(motion.pose(3.0).rotation, initial.rotation), 1e-15);
  Vec3 linear, angular;
  motion.velocity(3.0, linear, angular);
  EXPECT_EQ(linear, Vec3(1, 0, 0));
  EXPECT_EQ(angular, Vec3::Zero());
}

TEST(ConstantVelocityMotion, RejectsNonFiniteInput) {
  EXPECT_THROW(ConstantVelocityMotion(Pose{}, Vec3(kNan, 0, 0), Vec3::Zero()), InputError);
  EXPECT_THROW(ConstantVelocityMotion(Pose{}, Vec3::Zero(), Vec3(0, 0, kNan)), InputError);
  Pose degenerate;
  degenerate.rotation.coeffs().setZero();
  EXPECT_THROW(ConstantVelocityMotion(degenerate, Vec3::Zero(), Vec3::Zero()), InputError);
}

// ---- KeyframedMotion ----

std::vector<Keyframe> three_keys() {
  std::vector<Keyframe> keys(3);
  keys[0].time = 0.5;
  keys[0].pose.rotation = rotation(0.3, Vec3(1, 0, 0));
  keys[0].pose.translation = Vec3(0, 0, 0);
  keys[1].time = 1.5;
  keys[1].pose.rotation = rotation(1.2, Vec3(0, 1, 1));
  keys[1].pose.translation = Vec3(1, -2, 0.5);
  keys[2].time = 2.0;
  // Stored as the negated quaternion of a rotation close to keys[1]: the motion must take the short way.
  keys[2].pose.rotation.coeffs() = -rotation(1.4, Vec3(0, 1, 1.2)).coeffs();
  keys[2].pose.translation = Vec3(1, -1, 1.5);
  return keys;
}

TEST(KeyframedMotion, HitsKeysExactly) {
  const std::vector<Keyframe> keys = three_keys();
  const KeyframedMotion motion(keys);
  for (const Keyframe& key : keys) {
    const Pose p = motion.pose(key.time);
    EXPECT_EQ(p.translation, key.pose.translation);
    EXPECT_LT(rotation_gap(p.rotation, key.pose.rotation), 1e-15);
  }
}

TEST(KeyframedMotion, InterpolatesMidpoint) {
  const std::vector<Keyframe> keys = three_keys();
  const KeyframedMotion motion(keys);
  for (int i = 0; i + 1 < 3; ++i) {
    const Pose& a = keys[i].pose;
    const Pose& b = keys[i + 1].pose;
    const Pose mid = motion.pose(0.5 * (keys[i].time + keys[i + 1].time));
    EXPECT_TRUE(mid.translation.isApprox(0.5 * (a.translation + b.translation), 1e-15));
    // Halfway along the geodesic: equal (and half the total) angle to both ends, as Eigen's slerp gives.
    const double total = a.rotation.angularDistance(b.rotation);
    EXPECT_NEAR(mid.rotation.angularDistance(a.rotation), 0.5 * total, 1e-12);
    EXPECT_NEAR(mid.rotation.angularDistance(b.rotation), 0.5 * total, 1e-12);
    EXPECT_LT(rotation_gap(mid.rotation, a.rotation.slerp(0.5, b.rotation)), 1e-12);
  }
  // The short way between keys[1] and keys[2] despite the sign flip: well under a radian.
  EXPECT_LT(keys[1].pose.rotation.angularDistance(keys[2].pose.rotation), 0.5);
}

TEST(KeyframedMotion, VelocityMatchesFiniteDifferencesInsideIntervals) {
  const KeyframedMotion motion(three_keys());
  for (double t : {0.6, 1.0, 1.45, 1.55, 1.9}) {
    for (const Vec3& p : {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(-0.4, 0.9, 0.3)}) {
      expect_point_velocity_matches_fd(motion, t, p);
    }
    // The body origin moves with the linear velocity: the translation's slope.
    Vec3 linear, angular;
    motion.velocity(t, linear, angular);
    const double h = 1e-6;
    const Vec3 fd = (motion.pose(t + h).translation - motion.pose(t - h).translation) / (2 * h);
    EXPECT_LT((fd - linear).norm(), 1e-8);
  }
  Vec3 linear, angular;
  motion.velocity(1.0, linear, angular);
  EXPECT_TRUE(linear.isApprox(Vec3(1, -2, 0.5), 1e-15));
}

TEST(KeyframedMotion, ConstantOutsideKeyRange) {
  const std::vector<Keyframe> keys = three_keys();
  const KeyframedMotion motion(keys);
  for (double t : {-3.0, 0.0, 0.4999}) {
    EXPECT_EQ(motion.pose(t).translation, keys.front().pose.translation);
    EXPECT_LT(rotation_gap(motion.pose(t).rotation, keys.front().pose.rotation), 1e-15);
  }
  for (double t : {2.0, 2.0001, 10.0}) {
    EXPECT_EQ(motion.pose(t).translation, keys.back().pose.translation);
    EXPECT_LT(rotation_gap(motion.pose(t).rotation, keys.back().pose.rotation), 1e-15);
  }
  for (double t : {-3.0, 0.4999, 2.0, 10.0}) {
    Vec3 linear, angular;
    motion.velocity(t, linear, angular);
    EXPECT_EQ(linear, Vec3::Zero()) << t;
    EXPECT_EQ(angular, Vec3::Zero()) << t;
    EXPECT_EQ(motion.point_velocity(t, Vec3(1, 2, 3)), Vec3::Zero());
  }
}

TEST(KeyframedMotion, SingleKeyIsStatic) {
  std::vector<Keyframe> keys(1);
  keys[0].time = 1.0;
  keys[0].pose.translation = Vec3(1, 2, 3);
  const KeyframedMotion motion(keys);
  for (double t : {0.0, 1.0, 5.0}) {
    EXPECT_EQ(motion.pose(t).translation, Vec3(1, 2, 3));
    EXPECT_EQ(motion.point_velocity(t, Vec3(0, 0, 0)), Vec3::Zero());
  }
}

TEST(KeyframedMotion, RejectsBadKeys) {
  EXPECT_THROW(KeyframedMotion(std::vector<Keyframe>{}), InputError);
  std::vector<Keyframe> keys = three_keys();
  keys[1].time = keys[0].time;  // equal times: not strictly increasing
  EXPECT_THROW(KeyframedMotion{keys}, InputError);
  keys = three_keys();
  keys[2].time = 1.0;  // decreasing
  EXPECT_THROW(KeyframedMotion{keys}, InputError);
  keys = three_keys();
  keys[0].time = kNan;
  EXPECT_THROW(KeyframedMotion{keys}, InputError);
  keys = three_keys();
  keys[1].pose.translation.x() = kNan;
  EXPECT_THROW(KeyframedMotion{keys}, InputError);
}

// ---- PointCurve ----

TEST(PointCurve, InterpolatesLinearlyAndClamps) {
  const PointCurve curve({0.0, 1.0, 3.0}, {Vec3(0, 0, 0), Vec3(1, 2, 3), Vec3(1, 0, 3)});
  EXPECT_FALSE(curve.empty());
  EXPECT_EQ(curve(1.0), Vec3(1, 2, 3));
  EXPECT_TRUE(curve(0.5).isApprox(Vec3(0.5, 1, 1.5), 1e-15));
  EXPECT_TRUE(curve(2.5).isApprox(Vec3(1, 0.5, 3), 1e-15));
  EXPECT_EQ(curve(-1.0), Vec3(0, 0, 0));
  EXPECT_EQ(curve(7.0), Vec3(1, 0, 3));
  EXPECT_TRUE(PointCurve().empty());
}

TEST(PointCurve, RejectsBadInput) {
  EXPECT_THROW(PointCurve({0.0, 1.0}, {Vec3::Zero()}), InputError);
  EXPECT_THROW(PointCurve({0.0, 0.0}, {Vec3::Zero(), Vec3::Ones()}), InputError);
  EXPECT_THROW(PointCurve({1.0, 0.0}, {Vec3::Zero(), Vec3::Ones()}), InputError);
  EXPECT_THROW(PointCurve({0.0, kNan}, {Vec3::Zero(), Vec3::Ones()}), InputError);
  EXPECT_THROW(PointCurve()(0.0), Error);
}

}  // namespace
}  // namespace mgcloth::geometry
