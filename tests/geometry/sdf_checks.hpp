#pragma once
// Shared finite-difference checks for the geometry tests.
#include <mgcloth/geometry/shapes.hpp>

#include <gtest/gtest.h>

#include <functional>
#include <random>

namespace mgcloth::geometry::test {

using SdfFunction = std::function<SdfSample(const Vec3&)>;

inline constexpr double kStep = 1e-6;
inline constexpr double kRelTol = 1e-5;

/// Central differences of phi must match grad, and central differences of grad must match the Hessian,
/// within kRelTol relative to the size of the exact quantity (absolute below 1, where it may vanish).
inline ::testing::AssertionResult derivatives_match(const SdfFunction& f, const Vec3& p) {
  const SdfSample s = f(p);
  Vec3 fd_grad;
  Mat3 fd_hess;
  for (int i = 0; i < 3; ++i) {
    Vec3 plus = p, minus = p;
    plus[i] += kStep;
    minus[i] -= kStep;
    const SdfSample sp = f(plus), sm = f(minus);
    fd_grad[i] = (sp.phi - sm.phi) / (2 * kStep);
    fd_hess.col(i) = (sp.grad - sm.grad) / (2 * kStep);
  }
  const double grad_err = (fd_grad - s.grad).norm();
  const double hess_err = (fd_hess - s.hess).norm();
  if (grad_err > kRelTol * std::max(1.0, s.grad.norm()) || hess_err > kRelTol * std::max(1.0, s.hess.norm())) {
    return ::testing::AssertionFailure() << "at p = " << p.transpose() << ": grad " << s.grad.transpose()
                                         << " vs fd " << fd_grad.transpose() << " (err " << grad_err
                                         << "), hess error " << hess_err << "\nhess\n"
                                         << s.hess << "\nfd\n"
                                         << fd_hess;
  }
  if (!s.hess.isApprox(s.hess.transpose(), 1e-14)) {
    return ::testing::AssertionFailure() << "Hessian not symmetric at " << p.transpose();
  }
  return ::testing::AssertionSuccess();
}

/// Uniform point in the box [-extent, extent]^3.
inline Vec3 random_point(std::mt19937& rng, double extent) {
  std::uniform_real_distribution<double> u(-extent, extent);
  return {u(rng), u(rng), u(rng)};
}

}  // namespace mgcloth::geometry::test
