#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/rigid_motion.hpp>

#include <algorithm>
#include <cmath>
#include <string_view>

namespace mgcloth::geometry {

Eigen::Quaterniond euler_xyz_deg(const Vec3& degrees) {
  const Vec3 r = degrees * (M_PI / 180.0);
  return Eigen::AngleAxisd(r.z(), Vec3::UnitZ()) * Eigen::AngleAxisd(r.y(), Vec3::UnitY()) *
         Eigen::AngleAxisd(r.x(), Vec3::UnitX());
}
namespace {

/// Unit rotation quaternion; a zero or non-finite quaternion is a user error, a non-unit one is only rounding.
Eigen::Quaterniond normalized_rotation(const Eigen::Quaterniond& q, std::string_view what) {
  const double n = q.norm();
  if (!std::isfinite(n) || n == 0.0) {
    throw_input_error("{}: rotation quaternion must be finite and non-zero (got [{}, {}, {}, {}])", what, q.w(),
                      q.x(), q.y(), q.z());
  }
  return Eigen::Quaterniond(q.coeffs() / n);
}

void require_finite(const Vec3& v, std::string_view what) {
  if (!v.allFinite()) throw_input_error("{} must be finite (got [{}, {}, {}])", what, v.x(), v.y(), v.z());
}

/// Rotation by the vector w (axis w/|w|, angle |w|): exp([w]×).
Eigen::Quaterniond rotation_exp(const Vec3& w) {
  const double angle = w.norm();
  if (angle == 0.0) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, w / angle));
}

/// World-frame rotation vector of q1 q0⁻¹ along the shorter arc (angle in [0, π]).
Vec3 relative_rotation_vector(const Eigen::Quaterniond& q0, const Eigen::Quaterniond& q1) {
  // AngleAxis of a quaternion takes angle = 2 atan2(|v|, |w|), so q and -q give the same (shortest) rotation.
  const Eigen::AngleAxisd aa(q1 * q0.conjugate());
  return aa.angle() * aa.axis();
}

}  // namespace

Vec3 RigidMotion::point_velocity(double t, const Vec3& p) const {
  Vec3 linear, angular;
  velocity(t, linear, angular);
  return linear + angular.cross(p - pose(t).translation);
}

ConstantVelocityMotion::ConstantVelocityMotion(const Pose& initial, const Vec3& linear, const Vec3& angular)
    : m_initial(initial), m_linear(linear), m_angular(angular) {
  m_initial.rotation = normalized_rotation(initial.rotation, "constant-velocity motion");
  require_finite(initial.translation, "constant-velocity motion: initial translation");
  require_finite(linear, "constant-velocity motion: linear velocity");
  require_finite(angular, "constant-velocity motion: angular velocity");
}

Pose ConstantVelocityMotion::pose(double t) const {
  // Rotation about the body's own origin: R(t) = exp([w]× t) R0, c(t) = c0 + v t.
  Pose p;
  p.rotation = rotation_exp(m_angular * t) * m_initial.rotation;
  p.translation = m_initial.translation + m_linear * t;
  return p;
}

void ConstantVelocityMotion::velocity(double /*t*/, Vec3& linear, Vec3& angular) const {
  linear = m_linear;
  angular = m_angular;
}

KeyframedMotion::KeyframedMotion(std::vector<Keyframe> keys) : m_keys(std::move(keys)) {
  if (m_keys.empty()) throw_input_error("keyframed motion: needs at least one keyframe");
  for (std::size_t i = 0; i < m_keys.size(); ++i) {
    Keyframe& key = m_keys[i];
    if (!std::isfinite(key.time)) throw_input_error("keyframed motion: keyframe {} has non-finite time", i);
    if (i > 0 && !(key.time > m_keys[i - 1].time)) {
      throw_input_error("keyframed motion: keyframe times must be strictly increasing (key {} at t={} follows t={})",
                        i, key.time, m_keys[i - 1].time);
    }
    key.pose.rotation = normalized_rotation(key.pose.rotation, "keyframed motion");
    require_finite(key.pose.translation, "keyframed motion: keyframe translation");
  }
}

Pose KeyframedMotion::pose(double t) const {
  if (!(t > m_keys.front().time)) return m_keys.front().pose;  // also NaN, which must not reach the search
  if (t >= m_keys.back().time) return m_keys.back().pose;
  // First key after t; t lies in [k0.time, k1.time).
  const auto next = std::upper_bound(m_keys.begin(), m_keys.end(), t,
                                     [](double time, const Keyframe& key) { return time < key.time; });
  const Keyframe& k0 = *(next - 1);
  const Keyframe& k1 = *next;
  const double s = (t - k0.time) / (k1.time - k0.time);
  Pose p;
  p.translation = k0.pose.translation + s * (k1.pose.translation - k0.pose.translation);
  // Slerp written as exp(s log(q1 q0⁻¹)) q0: the same geodesic as Eigen's slerp, but with the angle from atan2
  // rather than acos (accurate for small steps) and by construction the integral of velocity() below.
  p.rotation = rotation_exp(s * relative_rotation_vector(k0.pose.rotation, k1.pose.rotation)) * k0.pose.rotation;
  return p;
}

void KeyframedMotion::velocity(double t, Vec3& linear, Vec3& angular) const {
  linear.setZero();
  angular.setZero();
  // Right-continuous: the velocity of [t_i, t_{i+1}) applies at t_i; zero before the first and from the last key.
  if (!(t >= m_keys.front().time) || t >= m_keys.back().time) return;
  const auto next = std::upper_bound(m_keys.begin(), m_keys.end(), t,
                                     [](double time, const Keyframe& key) { return time < key.time; });
  const Keyframe& k0 = *(next - 1);
  const Keyframe& k1 = *next;
  const double dt = k1.time - k0.time;
  linear = (k1.pose.translation - k0.pose.translation) / dt;
  angular = relative_rotation_vector(k0.pose.rotation, k1.pose.rotation) / dt;
}

PointCurve::PointCurve(std::vector<double> times, std::vector<Vec3> values)
    : m_times(std::move(times)), m_values(std::move(values)) {
  if (m_times.size() != m_values.size()) {
    throw_input_error("point curve: {} times but {} values", m_times.size(), m_values.size());
  }
  for (std::size_t i = 0; i < m_times.size(); ++i) {
    if (!std::isfinite(m_times[i])) throw_input_error("point curve: time {} is not finite", i);
    if (i > 0 && !(m_times[i] > m_times[i - 1])) {
      throw_input_error("point curve: times must be strictly increasing (time {} is {} after {})", i, m_times[i],
                        m_times[i - 1]);
    }
    require_finite(m_values[i], "point curve: value");
  }
}

Vec3 PointCurve::operator()(double t) const {
  if (m_times.empty()) throw Error("point curve: evaluated an empty curve");
  if (!(t > m_times.front())) return m_values.front();  // also NaN, which must not reach the search
  if (t >= m_times.back()) return m_values.back();
  const auto i = static_cast<std::size_t>(std::upper_bound(m_times.begin(), m_times.end(), t) - m_times.begin());
  const double s = (t - m_times[i - 1]) / (m_times[i] - m_times[i - 1]);
  return m_values[i - 1] + s * (m_values[i] - m_values[i - 1]);
}

}  // namespace mgcloth::geometry
