#pragma once
#include <mgcloth/core/types.hpp>

#include <array>
#include <memory>
#include <string>

namespace mgcloth::geometry {

/// Signed distance phi (negative inside) with its gradient and Hessian, in the shape's local frame.
/// The Hessian is the exact second derivative where phi is smooth (zero for planes and box faces).
struct SdfSample {
  double phi = 0.0;
  Vec3 grad = Vec3::Zero();
  Mat3 hess = Mat3::Zero();
};

/// An obstacle shape; its signed distance is the shared kernel hd::sdf (physics/element_kernels.hpp) of its kind()
/// and params(), so that the CUDA backend evaluates the same function.
class Shape {
 public:
  virtual ~Shape() = default;
  SdfSample eval(const Vec3& p) const;
  /// phi alone: contact terms test every vertex each evaluation and need derivatives only for the few in contact.
  double distance(const Vec3& p) const;
  virtual std::string type() const = 0;
  /// hd::ShapeKind.
  virtual int kind() const = 0;
  /// The kind's parameters (sphere: radius; box: half extents; capsule: radius, half length).
  virtual std::array<double, 3> params() const { return {0.0, 0.0, 0.0}; }
};

/// Half-space below the plane through the origin with normal +z (the obstacle is z < 0).
class Plane final : public Shape {
 public:
  std::string type() const override { return "plane"; }
  int kind() const override { return 0; }
};

class Sphere final : public Shape {
 public:
  explicit Sphere(double radius);
  std::string type() const override { return "sphere"; }
  int kind() const override { return 1; }
  std::array<double, 3> params() const override { return {m_radius, 0.0, 0.0}; }
  double radius() const { return m_radius; }

 private:
  double m_radius;
};

/// Axis-aligned box centred at the origin with the given half extents (exact SDF, inside and outside).
class Box final : public Shape {
 public:
  explicit Box(const Vec3& half_extents);
  std::string type() const override { return "box"; }
  int kind() const override { return 2; }
  std::array<double, 3> params() const override { return {m_half.x(), m_half.y(), m_half.z()}; }

 private:
  Vec3 m_half;
};

/// Capsule: segment from (0,0,-half_length) to (0,0,+half_length) along local z, inflated by radius.
class Capsule final : public Shape {
 public:
  Capsule(double radius, double half_length);
  std::string type() const override { return "capsule"; }
  int kind() const override { return 3; }
  std::array<double, 3> params() const override { return {m_radius, m_half_length, 0.0}; }

 private:
  double m_radius, m_half_length;
};

}  // namespace mgcloth::geometry
