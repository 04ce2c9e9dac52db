#pragma once
#include <mgcloth/core/types.hpp>

#include <Eigen/Geometry>
#include <vector>

namespace mgcloth::geometry {

/// World placement of a rigid body: p_world = rotation * p_local + translation.
/// The rotation of XYZ Euler angles in degrees: about X first, then Y, then Z (extrinsic), R = Rz Ry Rx (the
/// scene format's `rotation`).
Eigen::Quaterniond euler_xyz_deg(const Vec3& degrees);

struct Pose {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Vec3 translation = Vec3::Zero();

  Vec3 to_world(const Vec3& p) const { return rotation * p + translation; }
  Vec3 to_local(const Vec3& p) const { return rotation.conjugate() * (p - translation); }
};

/// Pose and velocity of a rigid body over time.
class RigidMotion {
 public:
  virtual ~RigidMotion() = default;
  virtual Pose pose(double t) const = 0;
  /// Linear velocity of the body's origin and angular velocity (world frame, rad/s) at time t.
  virtual void velocity(double t, Vec3& linear, Vec3& angular) const = 0;
  /// Velocity of the material point of the body currently at world position p.
  Vec3 point_velocity(double t, const Vec3& p) const;
};

/// Starts at `initial` and moves with constant linear velocity and constant angular velocity about its origin.
class ConstantVelocityMotion final : public RigidMotion {
 public:
  ConstantVelocityMotion(const Pose& initial, const Vec3& linear, const Vec3& angular);
  Pose pose(double t) const override;
  void velocity(double t, Vec3& linear, Vec3& angular) const override;

 private:
  Pose m_initial;
  Vec3 m_linear, m_angular;
};

struct Keyframe {
  double time = 0.0;
  Pose pose;
};

/// Piecewise interpolation between keyframes (linear in translation, slerp in rotation); held constant before
/// the first and after the last keyframe. Keyframe times must be strictly increasing.
class KeyframedMotion final : public RigidMotion {
 public:
  explicit KeyframedMotion(std::vector<Keyframe> keys);
  Pose pose(double t) const override;
  void velocity(double t, Vec3& linear, Vec3& angular) const override;

 private:
  std::vector<Keyframe> m_keys;
};

/// Piecewise linear curve of points over time (for keyframed pin targets), constant outside its range.
class PointCurve {
 public:
  PointCurve() = default;
  PointCurve(std::vector<double> times, std::vector<Vec3> values);
  Vec3 operator()(double t) const;
  bool empty() const { return m_times.empty(); }

 private:
  std::vector<double> m_times;
  std::vector<Vec3> m_values;
};

}  // namespace mgcloth::geometry
