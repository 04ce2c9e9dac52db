#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/obstacle.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth::geometry {

Mat3X TriangleSurface::at(double t) const {
  if (skin) {
    const double period = skin->duration();
    return skin->at(loop && period > 0.0 ? std::fmod(std::max(t, 0.0), period) : t);
  }
  if (frames.size() < 2 || !(rate > 0.0)) return frames.empty() ? vertices : frames.front();
  const double n = static_cast<double>(frames.size());
  double s = std::max(t, 0.0) * rate;
  // A loop of n frames has period n / rate: after the last frame comes the first again.
  if (loop) s = std::fmod(s, n);
  else if (s >= n - 1.0) return frames.back();
  const auto k = std::min(static_cast<size_t>(s), frames.size() - 1);
  const double w = s - static_cast<double>(k);
  return (1.0 - w) * frames[k] + w * frames[(k + 1) % frames.size()];
}

VecX TriangleSurface::placed(const Pose& pose, double t) const {
  const Mat3X v = at(t);
  VecX out(3 * v.cols());
  for (Index i = 0; i < v.cols(); ++i) out.segment<3>(3 * i) = pose.to_world(v.col(i));
  return out;
}

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
