#pragma once
#include <mgcloth/core/types.hpp>

#include <Eigen/Core>

namespace mgcloth::collision {

using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;

/// Which features of a point–triangle pair are nearest: a triangle vertex, an edge (E0 = t0t1, E1 = t1t2,
/// E2 = t2t0) or the interior. The squared distance is a smooth function of the four points while the type stays.
enum class PointTriangleType { P_T0, P_T1, P_T2, P_E0, P_E1, P_E2, P_T };

/// The nearest features of two segments a = (a0, a1), b = (b0, b1): endpoint–endpoint, endpoint–segment or
/// segment–segment (the lines' closest points interior to both). Parallel segments never give EA_EB.
enum class EdgeEdgeType { EA0_EB0, EA0_EB1, EA1_EB0, EA1_EB1, EA_EB0, EA_EB1, EA0_EB, EA1_EB, EA_EB };

PointTriangleType point_triangle_type(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2);
EdgeEdgeType edge_edge_type(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1);

/// Exact squared distance between a point and a (possibly degenerate) triangle. It is the value of the type's
/// formula; a triangle whose angle at t0 has sin² ≤ 1e-12 counts as its three edges, two segments whose sin² ≤ 1e-12
/// as parallel and a segment shorter than 1e-6 of the point's distance to its first end as a point; each costs at
/// most 1e-12 of the squared lengths involved and keeps the plane, line–line and point–line formulas away from their
/// ill-conditioned limits.
double point_triangle_distance_sq(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2);
/// Exact squared distance between two (possibly degenerate or parallel) segments.
double edge_edge_distance_sq(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1);

/// Gradient and Hessian of the squared distance of the given type with respect to (p, t0, t1, t2) stacked, for the
/// type held fixed (so the Hessian is that of the smooth piece: point–point, point–line or point–plane). Either
/// output may be null. Returns the squared distance of that type. A type whose formula is degenerate by the thresholds
/// above (a stale type: zero-area triangle, zero-length edge, parallel segments) falls back to the pair's own type
/// (point–line: the nearer endpoint), so the result is always finite.
double point_triangle_distance_sq(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2, PointTriangleType type,
                                  Vec12* grad, Mat12* hess);
/// The same for two segments with respect to (a0, a1, b0, b1) stacked (point–point, point–line or line–line).
double edge_edge_distance_sq(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, EdgeEdgeType type,
                             Vec12* grad, Mat12* hess);

}  // namespace mgcloth::collision
