#pragma once
#include <mgcloth/geometry/rigid_motion.hpp>
#include <mgcloth/geometry/shapes.hpp>

#include <memory>
#include <string>

namespace mgcloth::geometry {

/// A moving rigid obstacle: a shape, its motion, and its contact parameters.
struct Obstacle {
  std::string name;
  std::shared_ptr<const Shape> shape;
  std::shared_ptr<const RigidMotion> motion;
  double friction = 0.0;  ///< Coulomb coefficient

  /// World-frame signed distance at time t (gradient and Hessian rotated into the world frame).
  SdfSample sdf(const Vec3& p, double t) const;
};

}  // namespace mgcloth::geometry
