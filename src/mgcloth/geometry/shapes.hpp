#pragma once
#include <mgcloth/core/types.hpp>

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

class Shape {
 public:
  virtual ~Shape() = default;
  virtual SdfSample eval(const Vec3& p) const = 0;
  /// phi alone: contact terms test every vertex each evaluation and need derivatives only for the few in contact.
  virtual double distance(const Vec3& p) const { return eval(p).phi; }
  virtual std::string type() const = 0;
};

/// Half-space below the plane through the origin with normal +z (the obstacle is z < 0).
class Plane final : public Shape {
 public:
  SdfSample eval(const Vec3& p) const override;
  double distance(const Vec3& p) const override;
  std::string type() const override { return "plane"; }
};

class Sphere final : public Shape {
 public:
  explicit Sphere(double radius);
  SdfSample eval(const Vec3& p) const override;
  double distance(const Vec3& p) const override;
  std::string type() const override { return "sphere"; }
  double radius() const { return m_radius; }

 private:
  double m_radius;
};

/// Axis-aligned box centred at the origin with the given half extents (exact SDF, inside and outside).
class Box final : public Shape {
 public:
  explicit Box(const Vec3& half_extents);
  SdfSample eval(const Vec3& p) const override;
  double distance(const Vec3& p) const override;
  std::string type() const override { return "box"; }

 private:
  Vec3 m_half;
};

/// Capsule: segment from (0,0,-half_length) to (0,0,+half_length) along local z, inflated by radius.
class Capsule final : public Shape {
 public:
  Capsule(double radius, double half_length);
  SdfSample eval(const Vec3& p) const override;
  double distance(const Vec3& p) const override;
  std::string type() const override { return "capsule"; }

 private:
  double m_radius, m_half_length;
};

}  // namespace mgcloth::geometry
