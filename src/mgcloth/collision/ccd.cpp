#include <mgcloth/collision/ccd.hpp>

#include <mgcloth/collision/distance.hpp>
#include <mgcloth/core/error.hpp>

#include <algorithm>
#include <array>
#include <cmath>

namespace mgcloth::collision {

namespace {

// Step factor after the first step (Li et al. 2021, Alg. 1): each step covers 0.9 of the distance at its start, so
// that the distance at its end is at least a tenth of it even when the primitives approach at the bound l_p; the
// margin also absorbs the rounding of the positions and of the distance.
constexpr double kStepFraction = 0.9;
// A pair that slides past itself at a distance much smaller than its motion advances by about d/l_p per iteration
// without ever getting close; after this many iterations the time reached so far is returned. It is safe (every
// step was), only conservative: the caller's step is shortened and the next call starts from nearer.
constexpr int kMaxIterations = 100'000;

using Points = std::array<Vec3, 4>;

void check_arguments(double separation, double t_max) {
  if (!(separation > 0 && separation < 1))
    throw_error("additive CCD: separation must be in (0, 1), got {}", separation);
  if (!(t_max > 0) || !std::isfinite(t_max)) throw_error("additive CCD: t_max must be positive and finite, got {}", t_max);
}

// Li et al. 2021, Alg. 1. `distance` gives the exact distance of the pair at the four points (invariant to the
// common translation that was removed from the displacements); l_p bounds the speed at which any point of one
// primitive approaches any point of the other, so that a step dt from a configuration at distance d keeps the pair
// apart while l_p·dt < d. As in Alg. 1 the time returned is the last one reached *before* the step that brought the
// distance below s·d0, so the distance there is still at least s·d0: the first step, (1 − s)·d0/l_p, cannot go below
// it, and every later time was checked.
template <class Distance>
double additive_ccd(const Points& x, const Points& dx, double l_p, double separation, double t_max, Distance distance) {
  const double d0 = distance(x);
  if (!(d0 > 0)) return 0;  // touching already: no motion is known to be safe
  if (!(l_p > 0)) return t_max;
  const double target = separation * d0;
  Points xt;
  double t = 0;
  double step = (1 - separation) * d0 / l_p;
  for (int it = 0; it < kMaxIterations; ++it) {
    const double t_next = step < t_max - t ? t + step : t_max;
    for (int i = 0; i < 4; ++i) xt[i] = x[i] + t_next * dx[i];
    const double d = distance(xt);
    if (t > 0 && d <= target) return t;
    if (t_next == t_max) return t_max;
    t = t_next;
    step = kStepFraction * d / l_p;
  }
  return t;
}

Points without_mean(const Points& dx) {
  const Vec3 mean = 0.25 * (dx[0] + dx[1] + dx[2] + dx[3]);
  Points out;
  for (int i = 0; i < 4; ++i) out[i] = dx[i] - mean;
  return out;
}

}  // namespace

double point_triangle_ccd(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2, const Vec3& dp,
                          const Vec3& dt0, const Vec3& dt1, const Vec3& dt2, double separation, double t_max) {
  check_arguments(separation, t_max);
  const Points x{p, t0, t1, t2};
  const Points dx = without_mean({dp, dt0, dt1, dt2});
  // A point of the triangle moves by a convex combination of its vertices' displacements.
  const double l_p = dx[0].norm() + std::max({dx[1].norm(), dx[2].norm(), dx[3].norm()});
  return additive_ccd(x, dx, l_p, separation, t_max, [](const Points& y) {
    return std::sqrt(point_triangle_distance_sq(y[0], y[1], y[2], y[3]));
  });
}

double edge_edge_ccd(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, const Vec3& da0, const Vec3& da1,
                     const Vec3& db0, const Vec3& db1, double separation, double t_max) {
  check_arguments(separation, t_max);
  const Points x{a0, a1, b0, b1};
  const Points dx = without_mean({da0, da1, db0, db1});
  const double l_p = std::max(dx[0].norm(), dx[1].norm()) + std::max(dx[2].norm(), dx[3].norm());
  return additive_ccd(x, dx, l_p, separation, t_max, [](const Points& y) {
    return std::sqrt(edge_edge_distance_sq(y[0], y[1], y[2], y[3]));
  });
}

}  // namespace mgcloth::collision
