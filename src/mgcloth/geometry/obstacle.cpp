#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/obstacle.hpp>

namespace mgcloth::geometry {

SdfSample Obstacle::sdf(const Vec3& p, double t) const { return sdf(p, motion ? motion->pose(t) : Pose{}); }

SdfSample Obstacle::sdf(const Vec3& p, const Pose& pose) const {
  if (!shape) throw_error("obstacle '{}': has no shape", name);
  const Mat3 rot = pose.rotation.toRotationMatrix();
  SdfSample s = shape->eval(rot.transpose() * (p - pose.translation));
  // Rigid maps preserve distance, so phi carries over unchanged; derivatives follow the chain rule through
  // p_local = Rᵀ(p - c).
  s.grad = rot * s.grad;
  s.hess = rot * s.hess * rot.transpose();
  return s;
}

}  // namespace mgcloth::geometry
