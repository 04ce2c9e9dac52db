#pragma once
#include <mgcloth/geometry/rigid_motion.hpp>
#include <mgcloth/geometry/sdf_kernels.hpp>
#include <mgcloth/geometry/shapes.hpp>

#include <memory>
#include <string>

namespace mgcloth::geometry {

/// A moving rigid obstacle: a shape, its motion, and its contact parameters.
struct Obstacle {
  std::string name;
  std::shared_ptr<const Shape> shape;
  std::shared_ptr<const RigidMotion> motion;  ///< null: fixed at the identity pose
  double friction = 0.0;  ///< Coulomb coefficient

  /// World-frame signed distance at time t (gradient and Hessian rotated into the world frame).
  SdfSample sdf(const Vec3& p, double t) const;
  /// Same at a pose computed once (motion->pose(t)), for evaluating many points at one time:
  /// phi(p) = phi_local(Rᵀ(p - c)), grad = R grad_local, H = R H_local Rᵀ.
  SdfSample sdf(const Vec3& p, const Pose& pose) const;
  /// phi alone at a pose (no derivatives), the cheap test before sdf().
  double distance(const Vec3& p, const Pose& pose) const { return shape->distance(pose.to_local(p)); }
  /// The obstacle at time t (pose and velocity) as plain data for the shared kernels (hd::contact_psd,
  /// hd::project_out, hd::filter_velocity).
  hd::ObstacleData data(double t) const;
};

}  // namespace mgcloth::geometry
