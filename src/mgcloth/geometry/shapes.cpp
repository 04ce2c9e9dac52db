#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/shapes.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth::geometry {
namespace {

bool is_positive_finite(double v) { return std::isfinite(v) && v > 0.0; }

// sign(0) = +1 so that points on a symmetry plane still get a unit gradient.
double sign_of(double v) { return v < 0.0 ? -1.0 : 1.0; }

/// phi = |v| - radius for the distance to a point; H = (I - n nᵀ)/|v| with n = v/|v|.
/// At v = 0 the gradient is undefined: `fallback` keeps the result a finite unit vector.
SdfSample point_distance(const Vec3& v, double radius, const Vec3& fallback) {
  SdfSample s;
  const double r = v.norm();
  s.phi = r - radius;
  if (r == 0.0) {
    s.grad = fallback;
    return s;
  }
  s.grad = v / r;
  s.hess = (Mat3::Identity() - s.grad * s.grad.transpose()) / r;
  return s;
}

}  // namespace

SdfSample Plane::eval(const Vec3& p) const {
  SdfSample s;
  s.phi = p.z();
  s.grad = Vec3::UnitZ();
  return s;
}

double Plane::distance(const Vec3& p) const { return p.z(); }

Sphere::Sphere(double radius) : m_radius(radius) {
  if (!is_positive_finite(radius)) throw_input_error("sphere: radius must be positive and finite (got {})", radius);
}

SdfSample Sphere::eval(const Vec3& p) const { return point_distance(p, m_radius, Vec3::UnitZ()); }

double Sphere::distance(const Vec3& p) const { return p.norm() - m_radius; }

Box::Box(const Vec3& half_extents) : m_half(half_extents) {
  for (int i = 0; i < 3; ++i) {
    if (!is_positive_finite(half_extents[i])) {
      throw_input_error("box: half extents must be positive and finite (got [{}, {}, {}])", half_extents.x(),
                        half_extents.y(), half_extents.z());
    }
  }
}

SdfSample Box::eval(const Vec3& p) const {
  // q_i = |p_i| - h_i: signed distance to the slab of axis i (positive outside it).
  const Vec3 sign(sign_of(p.x()), sign_of(p.y()), sign_of(p.z()));
  const Vec3 q = p.cwiseAbs() - m_half;
  SdfSample s;
  if (q.maxCoeff() <= 0.0) {
    // Inside: the nearest face wins; phi is piecewise linear, so H = 0 (ties go to the lowest axis).
    int k = 0;
    s.phi = q.maxCoeff(&k);
    s.grad[k] = sign[k];
    return s;
  }
  // Outside: the distance to the nearest face, edge or corner is the Euclidean norm of the active
  // components d = max(q, 0); with active projector P_A, grad = sign ∘ d/|d| and H = (P_A - grad gradᵀ)/|d|.
  const Vec3 d = q.cwiseMax(0.0);
  s.phi = d.norm();
  s.grad = sign.cwiseProduct(d) / s.phi;
  Mat3 active = Mat3::Zero();
  for (int i = 0; i < 3; ++i) active(i, i) = q[i] > 0.0 ? 1.0 : 0.0;
  s.hess = (active - s.grad * s.grad.transpose()) / s.phi;
  return s;
}

double Box::distance(const Vec3& p) const {
  const Vec3 q = p.cwiseAbs() - m_half;
  return q.maxCoeff() <= 0.0 ? q.maxCoeff() : q.cwiseMax(0.0).norm();
}

Capsule::Capsule(double radius, double half_length) : m_radius(radius), m_half_length(half_length) {
  if (!is_positive_finite(radius)) throw_input_error("capsule: radius must be positive and finite (got {})", radius);
  if (!std::isfinite(half_length) || half_length < 0.0) {
    throw_input_error("capsule: half_length must be non-negative and finite (got {})", half_length);
  }
}

SdfSample Capsule::eval(const Vec3& p) const {
  const double z = p.z();
  if (std::abs(z) >= m_half_length) {
    // Beyond the segment: distance to the end point, as for a sphere. On the axis the outward normal is ±z.
    const Vec3 end(0.0, 0.0, std::copysign(m_half_length, z));
    return point_distance(p - end, m_radius, Vec3(0.0, 0.0, sign_of(z)));
  }
  // Beside the segment: distance to the z axis, phi = |(x, y)| - r; H = (I - e_z e_zᵀ - n nᵀ)/|(x, y)|.
  SdfSample s;
  const Vec3 v(p.x(), p.y(), 0.0);
  const double r = v.norm();
  s.phi = r - m_radius;
  if (r == 0.0) {
    s.grad = Vec3::UnitX();  // on the axis every radial direction is a valid normal; pick one deterministically
    return s;
  }
  s.grad = v / r;
  s.hess = (Mat3(Vec3(1.0, 1.0, 0.0).asDiagonal()) - s.grad * s.grad.transpose()) / r;
  return s;
}

double Capsule::distance(const Vec3& p) const {
  const double z = std::clamp(p.z(), -m_half_length, m_half_length);
  return (p - Vec3(0.0, 0.0, z)).norm() - m_radius;
}

}  // namespace mgcloth::geometry
