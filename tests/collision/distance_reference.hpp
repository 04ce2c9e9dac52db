#pragma once
// Brute-force references for the contact distances, independent of the classification in distance.cpp: dense
// sampling of the primitives, a projected Gauss-Seidel descent from the best sample, and a golden-section search on
// the partial minimum over one parameter (convex, so the search converges however ill-conditioned the pair: nearly
// parallel segments, sliver triangles, where Gauss-Seidel crawls along the valley). Each is an upper bound (a
// point of the primitives); the reference is their minimum.
#include <mgcloth/core/types.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

namespace mgcloth::collision::testing {

/// min over x ∈ [0, 1] of a convex function.
template <class F>
double golden_section_min(F f, int iterations = 120) {
  const double r = (std::sqrt(5.0) - 1) / 2;
  double lo = 0, hi = 1, x1 = hi - r * (hi - lo), x2 = lo + r * (hi - lo), f1 = f(x1), f2 = f(x2);
  for (int i = 0; i < iterations; ++i) {
    if (f1 <= f2) {
      hi = x2, x2 = x1, f2 = f1, x1 = hi - r * (hi - lo), f1 = f(x1);
    } else {
      lo = x1, x1 = x2, f1 = f2, x2 = lo + r * (hi - lo), f2 = f(x2);
    }
  }
  return std::min({f1, f2, f(0.0), f(1.0)});
}

/// min over t ∈ [0, tmax] of |c − t·v|².
inline double clamped_line_sq(const Vec3& c, const Vec3& v, double tmax) {
  const double vv = v.squaredNorm();
  const double t = vv > 0 ? std::clamp(c.dot(v) / vv, 0.0, tmax) : 0.0;
  return (c - t * v).squaredNorm();
}

/// min over the triangle of |p − q|².
inline double reference_point_triangle_sq(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2, int grid = 32,
                                          int sweeps = 200) {
  const std::array<Vec3, 3> t{t0, t1, t2};
  std::array<double, 3> best_l{1, 0, 0};
  double best = kInf;
  for (int i = 0; i <= grid; ++i)
    for (int j = 0; i + j <= grid; ++j) {
      const std::array<double, 3> l{double(i) / grid, double(j) / grid, double(grid - i - j) / grid};
      const double d = (p - (l[0] * t0 + l[1] * t1 + l[2] * t2)).squaredNorm();
      if (d < best) best = d, best_l = l;
    }
  // Projected Gauss-Seidel on the simplex: move weight between two vertices at a time, each move an exact 1D
  // minimisation clamped to the simplex.
  std::array<double, 3> l = best_l;
  for (int sweep = 0; sweep < sweeps; ++sweep)
    for (int k = 0; k < 3; ++k) {
      const int i = k, j = (k + 1) % 3;
      const Vec3 q = l[0] * t0 + l[1] * t1 + l[2] * t2;
      const Vec3 dir = t[i] - t[j];
      const double dd = dir.squaredNorm();
      if (dd == 0) continue;
      const double mu = std::clamp((p - q).dot(dir) / dd, -l[i], l[j]);
      l[i] += mu;
      l[j] -= mu;
    }
  best = std::min(best, (p - (l[0] * t0 + l[1] * t1 + l[2] * t2)).squaredNorm());
  // q = t0 + α(t1 − t0) + β(t2 − t0), β ∈ [0, 1 − α]: the minimum over β is convex in α; both orders.
  for (int k = 0; k < 3; ++k) {
    const Vec3& o = t[k];
    const Vec3 e1 = t[(k + 1) % 3] - o, e2 = t[(k + 2) % 3] - o;
    best = std::min(best, golden_section_min([&](double a) { return clamped_line_sq(p - o - a * e1, e2, 1 - a); }));
  }
  return best;
}

/// min over s, t ∈ [0, 1] of |a0 + s(a1 − a0) − b0 − t(b1 − b0)|².
inline double reference_edge_edge_sq(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, int grid = 40,
                                     int sweeps = 200) {
  const Vec3 u = a1 - a0, v = b1 - b0;
  const auto f = [&](double s, double t) { return (a0 + s * u - b0 - t * v).squaredNorm(); };
  double best = kInf, s = 0, t = 0;
  for (int i = 0; i <= grid; ++i)
    for (int j = 0; j <= grid; ++j) {
      const double si = double(i) / grid, tj = double(j) / grid, d = f(si, tj);
      if (d < best) best = d, s = si, t = tj;
    }
  // Projected Gauss-Seidel on the box.
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    if (u.squaredNorm() > 0) s = std::clamp((b0 + t * v - a0).dot(u) / u.squaredNorm(), 0.0, 1.0);
    if (v.squaredNorm() > 0) t = std::clamp((a0 + s * u - b0).dot(v) / v.squaredNorm(), 0.0, 1.0);
  }
  best = std::min(best, f(s, t));
  best = std::min(best, golden_section_min([&](double si) { return clamped_line_sq(a0 + si * u - b0, v, 1); }));
  best = std::min(best, golden_section_min([&](double tj) { return clamped_line_sq(b0 + tj * v - a0, u, 1); }));
  return best;
}

inline Vec3 random_vec(std::mt19937_64& rng, double scale = 1.0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return scale * Vec3(u(rng), u(rng), u(rng));
}

}  // namespace mgcloth::collision::testing
