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

hd::ObstacleData Obstacle::data(double t) const {
  if (!shape) throw_error("obstacle '{}': has no shape", name);
  const Pose pose = motion ? motion->pose(t) : Pose{};
  Vec3 linear = Vec3::Zero(), angular = Vec3::Zero();
  if (motion) motion->velocity(t, linear, angular);
  hd::ObstacleData o;
  o.kind = shape->kind();
  const auto p = shape->params();
  const Mat3 R = pose.rotation.toRotationMatrix();
  for (int i = 0; i < 3; ++i) {
    o.param[i] = p[static_cast<size_t>(i)];
    o.t[i] = pose.translation[i];
    o.v[i] = linear[i];
    o.w[i] = angular[i];
    for (int j = 0; j < 3; ++j) o.R[3 * i + j] = R(i, j);
  }
  o.friction = friction;
  return o;
}

}  // namespace mgcloth::geometry
