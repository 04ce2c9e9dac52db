#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/shapes.hpp>
#include <mgcloth/geometry/sdf_kernels.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth::geometry {
namespace {

bool is_positive_finite(double v) { return std::isfinite(v) && v > 0.0; }

}  // namespace

SdfSample Shape::eval(const Vec3& p) const {
  const auto prm = params();
  hd::V3 grad;
  SdfSample s;
  s.phi = hd::sdf(kind(), prm.data(), {p.x(), p.y(), p.z()}, grad, s.hess.data());
  s.hess.transposeInPlace();  // row-major from the shared kernel (symmetric anyway)
  s.grad = Vec3(grad.x, grad.y, grad.z);
  return s;
}

double Shape::distance(const Vec3& p) const { return hd::sdf_distance(kind(), params().data(), {p.x(), p.y(), p.z()}); }

Sphere::Sphere(double radius) : m_radius(radius) {
  if (!is_positive_finite(radius)) throw_input_error("sphere: radius must be positive and finite (got {})", radius);
}

Box::Box(const Vec3& half_extents) : m_half(half_extents) {
  for (int i = 0; i < 3; ++i) {
    if (!is_positive_finite(half_extents[i])) {
      throw_input_error("box: half extents must be positive and finite (got [{}, {}, {}])", half_extents.x(),
                        half_extents.y(), half_extents.z());
    }
  }
}

Capsule::Capsule(double radius, double half_length) : m_radius(radius), m_half_length(half_length) {
  if (!is_positive_finite(radius)) throw_input_error("capsule: radius must be positive and finite (got {})", radius);
  if (!std::isfinite(half_length) || half_length < 0.0) {
    throw_input_error("capsule: half_length must be non-negative and finite (got {})", half_length);
  }
}

}  // namespace mgcloth::geometry
