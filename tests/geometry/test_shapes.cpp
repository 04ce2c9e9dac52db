#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/shapes.hpp>

#include <geometry/sdf_checks.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace mgcloth::geometry {
namespace {

using test::derivatives_match;
using test::random_point;

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
// Keeps finite-difference stencils (1e-6 wide) clear of the sets where phi or its Hessian is not smooth.
constexpr double kMargin = 1e-2;

/// Properties every exact signed distance has where it is smooth: |grad| = 1 and H grad = 0
/// (differentiate |grad|² = 1), plus derivatives that match finite differences.
void expect_smooth_sdf(const Shape& shape, const Vec3& p) {
  const SdfSample s = shape.eval(p);
  EXPECT_NEAR(s.grad.norm(), 1.0, 1e-14) << "at " << p.transpose();
  EXPECT_LT((s.hess * s.grad).norm(), 1e-12 * std::max(1.0, s.hess.norm())) << "at " << p.transpose();
  EXPECT_TRUE(derivatives_match([&](const Vec3& x) { return shape.eval(x); }, p));
}

struct Counts {
  int inside = 0, outside = 0;
};

Counts check_random_points(const Shape& shape, double extent, int samples,
                           const std::function<bool(const Vec3&)>& is_smooth_there) {
  std::mt19937 rng(12345);
  Counts counts;
  for (int i = 0; i < samples; ++i) {
    const Vec3 p = random_point(rng, extent);
    if (!is_smooth_there(p)) continue;
    (shape.eval(p).phi < 0 ? counts.inside : counts.outside)++;
    expect_smooth_sdf(shape, p);
  }
  return counts;
}

void expect_sample(const SdfSample& s, double phi, const Vec3& grad) {
  EXPECT_NEAR(s.phi, phi, 1e-15);
  EXPECT_TRUE(s.grad.isApprox(grad, 1e-15)) << s.grad.transpose() << " vs " << grad.transpose();
  EXPECT_TRUE(s.hess.allFinite());
}

// ---- Plane ----

TEST(Plane, IsSignedHeight) {
  const Plane plane;
  expect_sample(plane.eval(Vec3(1, 2, -3)), -3.0, Vec3::UnitZ());
  expect_sample(plane.eval(Vec3(-4, 0.5, 0.25)), 0.25, Vec3::UnitZ());
  EXPECT_TRUE(plane.eval(Vec3(1, 1, 1)).hess.isZero(0.0));
  EXPECT_EQ(plane.type(), "plane");
}

TEST(Plane, DerivativesMatchFiniteDifferences) {
  const Plane plane;
  const Counts c = check_random_points(plane, 2.0, 200, [](const Vec3&) { return true; });
  EXPECT_GT(c.inside, 50);
  EXPECT_GT(c.outside, 50);
}

// ---- Sphere ----

TEST(Sphere, ExactValues) {
  const Sphere sphere(0.5);
  EXPECT_EQ(sphere.radius(), 0.5);
  expect_sample(sphere.eval(Vec3(0, 0, 2)), 1.5, Vec3::UnitZ());
  expect_sample(sphere.eval(Vec3(-0.25, 0, 0)), -0.25, -Vec3::UnitX());
  const Vec3 on_surface = Vec3(1, -2, 3).normalized() * 0.5;
  EXPECT_NEAR(sphere.eval(on_surface).phi, 0.0, 1e-15);
  // H = (I - n nᵀ)/r: at (0, 0, 2) curvature 1/2 in x and y, none along the normal.
  EXPECT_TRUE(sphere.eval(Vec3(0, 0, 2)).hess.isApprox(Vec3(0.5, 0.5, 0.0).asDiagonal().toDenseMatrix(), 1e-15));
}

TEST(Sphere, CentreHasDeterministicUnitGradient) {
  const Sphere sphere(0.5);
  const SdfSample s = sphere.eval(Vec3::Zero());
  EXPECT_EQ(s.phi, -0.5);
  EXPECT_EQ(s.grad, Vec3::UnitZ());
  EXPECT_TRUE(s.hess.allFinite());
}

TEST(Sphere, DerivativesMatchFiniteDifferences) {
  const Sphere sphere(0.7);
  const Counts c = check_random_points(sphere, 1.0, 2000, [](const Vec3& p) { return p.norm() > 0.05; });
  EXPECT_GT(c.inside, 100);
  EXPECT_GT(c.outside, 100);
}

TEST(Sphere, RejectsBadRadius) {
  for (double r : {0.0, -1.0, kNan, std::numeric_limits<double>::infinity()}) {
    EXPECT_THROW(Sphere{r}, InputError) << r;
  }
}

// ---- Box ----

TEST(Box, ExactValuesAtFacesEdgesAndCorners) {
  const Box box(Vec3(1, 2, 3));
  EXPECT_EQ(box.type(), "box");
  expect_sample(box.eval(Vec3(2, 0, 0)), 1.0, Vec3::UnitX());                          // face
  expect_sample(box.eval(Vec3(0.5, -2.5, 1)), 0.5, -Vec3::UnitY());                    // face
  expect_sample(box.eval(Vec3(2, 3, 0)), std::sqrt(2.0), Vec3(1, 1, 0) / std::sqrt(2.0));  // edge
  expect_sample(box.eval(Vec3(-2, -3, -4)), std::sqrt(3.0), -Vec3::Ones() / std::sqrt(3.0));  // corner
  expect_sample(box.eval(Vec3(1, 2, 3)), 0.0, Vec3::UnitX());                          // corner itself
  expect_sample(box.eval(Vec3(0.5, 0, 0)), -0.5, Vec3::UnitX());                       // inside, nearest face +x
  expect_sample(box.eval(Vec3(0, 0, -2.5)), -0.5, -Vec3::UnitZ());                     // inside, nearest face -z
  expect_sample(box.eval(Vec3::Zero()), -1.0, Vec3::UnitX());                          // centre
  // Faces are flat; an edge curves only across its own two axes: H = (P_A - g gᵀ)/phi.
  EXPECT_TRUE(box.eval(Vec3(2, 0, 0)).hess.isZero(0.0));
  EXPECT_TRUE(box.eval(Vec3(0.5, 0, 0)).hess.isZero(0.0));
  Mat3 edge_hess = Mat3::Zero();
  edge_hess.topLeftCorner<2, 2>() << 0.5, -0.5, -0.5, 0.5;
  EXPECT_TRUE(box.eval(Vec3(2, 3, 0)).hess.isApprox(edge_hess / std::sqrt(2.0), 1e-15));
}

TEST(Box, DerivativesMatchFiniteDifferences) {
  const Vec3 half(0.4, 0.7, 1.1);
  const Box box(half);
  int faces = 0, edges = 0, corners = 0;
  const Counts c = check_random_points(box, 1.8, 3000, [&](const Vec3& p) {
    const Vec3 q = p.cwiseAbs() - half;
    if (q.cwiseAbs().minCoeff() < kMargin || p.cwiseAbs().minCoeff() < kMargin) return false;
    if (q.maxCoeff() < 0) {
      // Inside, phi = max q_i is smooth only away from ties between the two nearest faces.
      Vec3 sorted = q;
      std::sort(sorted.data(), sorted.data() + 3);
      return sorted[2] - sorted[1] > kMargin;
    }
    const int active = static_cast<int>((q.array() > 0).count());
    (active == 1 ? faces : active == 2 ? edges : corners)++;
    return true;
  });
  EXPECT_GT(c.inside, 50);
  EXPECT_GT(faces, 50);
  EXPECT_GT(edges, 50);
  EXPECT_GT(corners, 50);
}

TEST(Box, RejectsBadHalfExtents) {
  EXPECT_THROW(Box(Vec3(1, 0, 1)), InputError);
  EXPECT_THROW(Box(Vec3(-1, 1, 1)), InputError);
  EXPECT_THROW(Box(Vec3(1, 1, kNan)), InputError);
  EXPECT_NO_THROW(Box(Vec3(1e-3, 1, 1)));
}

// ---- Capsule ----

TEST(Capsule, ExactValuesOnSideAndCaps) {
  const Capsule capsule(0.3, 1.0);
  EXPECT_EQ(capsule.type(), "capsule");
  expect_sample(capsule.eval(Vec3(1, 0, 0.5)), 0.7, Vec3::UnitX());               // side
  expect_sample(capsule.eval(Vec3(0, -0.1, -0.9)), -0.2, -Vec3::UnitY());          // inside, near side
  expect_sample(capsule.eval(Vec3(0, 0, 2)), 0.7, Vec3::UnitZ());                 // top cap pole
  expect_sample(capsule.eval(Vec3(0, 0, -1.1)), -0.2, -Vec3::UnitZ());            // inside bottom cap
  expect_sample(capsule.eval(Vec3(1, 0, 2)), std::sqrt(2.0) - 0.3, Vec3(1, 0, 1) / std::sqrt(2.0));  // cap
  EXPECT_NEAR(capsule.eval(Vec3(0.3, 0, 0)).phi, 0.0, 1e-15);
  EXPECT_NEAR(capsule.eval(Vec3(0, 0, 1) + 0.3 * Vec3(1, -1, 1).normalized()).phi, 0.0, 1e-15);
  // The side curves around the axis only.
  EXPECT_TRUE(capsule.eval(Vec3(1, 0, 0.5)).hess.isApprox(Vec3(0, 1, 0).asDiagonal().toDenseMatrix(), 1e-15));
}

TEST(Capsule, AxisHasDeterministicUnitGradient) {
  const Capsule capsule(0.3, 1.0);
  for (const Vec3& p : {Vec3(0, 0, 0.2), Vec3(0, 0, 1), Vec3(0, 0, -1)}) {
    const SdfSample s = capsule.eval(p);
    EXPECT_EQ(s.phi, -0.3);
    EXPECT_NEAR(s.grad.norm(), 1.0, 1e-15);
    EXPECT_TRUE(s.hess.allFinite());
  }
  EXPECT_EQ(capsule.eval(Vec3(0, 0, -1)).grad, -Vec3::UnitZ());
}

TEST(Capsule, ZeroLengthIsASphere) {
  const Capsule capsule(0.4, 0.0);
  const Sphere sphere(0.4);
  std::mt19937 rng(7);
  for (int i = 0; i < 100; ++i) {
    const Vec3 p = random_point(rng, 1.0);
    const SdfSample a = capsule.eval(p), b = sphere.eval(p);
    EXPECT_NEAR(a.phi, b.phi, 1e-15);
    EXPECT_TRUE(a.grad.isApprox(b.grad, 1e-15));
    EXPECT_TRUE(a.hess.isApprox(b.hess, 1e-14));
  }
  EXPECT_EQ(capsule.eval(Vec3::Zero()).grad, sphere.eval(Vec3::Zero()).grad);
}

TEST(Capsule, DerivativesMatchFiniteDifferences) {
  const double half_length = 0.5;
  const Capsule capsule(0.3, half_length);
  int side = 0, caps = 0;
  const Counts c = check_random_points(capsule, 0.9, 3000, [&](const Vec3& p) {
    const double beyond = std::abs(p.z()) - half_length;
    if (std::abs(beyond) < kMargin) return false;  // the Hessian jumps where the side meets a cap
    const double to_segment = Vec3(p.x(), p.y(), std::max(beyond, 0.0)).norm();
    if (to_segment < 0.05) return false;
    (beyond < 0 ? side : caps)++;
    return true;
  });
  EXPECT_GT(c.inside, 100);
  EXPECT_GT(c.outside, 100);
  EXPECT_GT(side, 100);
  EXPECT_GT(caps, 100);
}

TEST(Capsule, RejectsBadParameters) {
  EXPECT_THROW(Capsule(0.0, 1.0), InputError);
  EXPECT_THROW(Capsule(-0.1, 1.0), InputError);
  EXPECT_THROW(Capsule(0.1, -0.1), InputError);
  EXPECT_THROW(Capsule(0.1, kNan), InputError);
  EXPECT_THROW(Capsule(kNan, 1.0), InputError);
  EXPECT_NO_THROW(Capsule(0.1, 0.0));
}

}  // namespace
}  // namespace mgcloth::geometry

namespace mgcloth::geometry {
namespace {

// The cheap distance() that contact terms test first must be exactly eval().phi everywhere: in and out, near
// edges and corners, on capsule caps and beside the segment, and on the axes where the gradient has fallbacks.
TEST(Shapes, DistanceEqualsEvalPhi) {
  const Plane plane;
  const Sphere sphere(0.3);
  const Box box(Vec3(0.2, 0.4, 0.1));
  const Capsule capsule(0.15, 0.35);
  const Capsule ball(0.15, 0.0);
  std::mt19937 rng(7);
  std::vector<Vec3> points{Vec3::Zero(), Vec3(0, 0, 0.35), Vec3(0, 0, -1), Vec3(0.2, 0.4, 0.1), Vec3(0.2, 0, 0)};
  for (int i = 0; i < 2000; ++i) points.push_back(random_point(rng, 1.0));
  for (const Shape* shape : std::initializer_list<const Shape*>{&plane, &sphere, &box, &capsule, &ball})
    for (const Vec3& p : points)
      EXPECT_NEAR(shape->distance(p), shape->eval(p).phi, 1e-15) << shape->type() << " at " << p.transpose();
}

}  // namespace
}  // namespace mgcloth::geometry
