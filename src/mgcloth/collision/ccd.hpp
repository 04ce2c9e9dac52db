#pragma once
#include <mgcloth/core/types.hpp>

namespace mgcloth::collision {

/// Additive continuous collision detection (Li, Kaufman & Jiang 2021, "Codimensional Incremental Potential
/// Contact", Alg. 1): the points move linearly, x_i(t) = x_i + t·d_i. Returns a time t ∈ (0, t_max] such that the
/// pair's distance stays above zero on [0, t] and, where it returns less than t_max, has come down to about
/// `separation` times its distance at t = 0 (0 < separation < 1); t_max when the pair does not get that close
/// before t_max. Conservative: it may stop early, never late. The pair must be apart at t = 0.
/// Precisely: the distance at the returned t is at least separation·d0 (Alg. 1 returns the time reached before the
/// step that went below it) and, where t < t_max, less than 10·separation·d0 (each step covers 0.9 of the distance
/// at its start); a pair that touches at t = 0 gets 0; separation outside (0, 1) or t_max ≤ 0 throws Error.
double point_triangle_ccd(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2, const Vec3& dp,
                          const Vec3& dt0, const Vec3& dt1, const Vec3& dt2, double separation, double t_max);
double edge_edge_ccd(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, const Vec3& da0, const Vec3& da1,
                     const Vec3& db0, const Vec3& db1, double separation, double t_max);

}  // namespace mgcloth::collision
