#include <mgcloth/collision/distance.hpp>

#include <Eigen/Geometry>

#include <array>
#include <cmath>

namespace mgcloth::collision {

namespace {

// One relative threshold for every degenerate case, on a squared sine: a triangle whose angle at t0 has
// sin² ≤ kDegenerateSin2 (|n|² ≤ kDegenerateSin2·|t1−t0|²·|t2−t0|²) is treated as its three edges; two segments
// with |a×b|² ≤ kDegenerateSin2·|a|²·|b|² as parallel; a segment with |b−a|² ≤ kDegenerateSin2·|p−a|² as a point.
// Near those limits the plane and line–line formulas lose accuracy like ε/sin (ε = 2.2e-16) and their Hessians grow
// like 1/sin². Falling back to the edges / endpoints costs at most kDegenerateSin2·ℓ² in squared distance (ℓ the
// shorter segment or edge: along the minimiser's valley the squared distance grows by at most ℓ²·sin² before it
// reaches the boundary of the parameter domain), so at most 1e-6·ℓ in distance, and only when the pair nearly
// touches; just above the threshold the formulas' rounding costs about 2e-10·ℓ. Additive CCD stays safe as long as
// 1e-6·ℓ is well below a tenth of its target distance (always, for cloth edges and contact thicknesses).
constexpr double kDegenerateSin2 = 1e-12;

// The smooth pieces take difference vectors y_k = x[plus_k] − x[minus_k] of the 4 stacked points; their gradient and
// Hessian with respect to y are scattered onto the 12 coordinates through that incidence.
struct Diff {
  int plus, minus;
};

template <int M>
struct Piece {
  using VecY = Eigen::Matrix<double, 3 * M, 1>;
  using MatY = Eigen::Matrix<double, 3 * M, 3 * M>;
  double f = 0;
  VecY g;
  MatY H;
};

template <int M>
double scatter(const Piece<M>& piece, const std::array<Diff, M>& map, Vec12* grad, Mat12* hess) {
  if (grad) {
    grad->setZero();
    for (int i = 0; i < M; ++i) {
      grad->segment<3>(3 * map[i].plus) += piece.g.template segment<3>(3 * i);
      grad->segment<3>(3 * map[i].minus) -= piece.g.template segment<3>(3 * i);
    }
  }
  if (hess) {
    hess->setZero();
    for (int i = 0; i < M; ++i)
      for (int j = 0; j < M; ++j) {
        const Mat3 b = piece.H.template block<3, 3>(3 * i, 3 * j);
        hess->block<3, 3>(3 * map[i].plus, 3 * map[j].plus) += b;
        hess->block<3, 3>(3 * map[i].plus, 3 * map[j].minus) -= b;
        hess->block<3, 3>(3 * map[i].minus, 3 * map[j].plus) -= b;
        hess->block<3, 3>(3 * map[i].minus, 3 * map[j].minus) += b;
      }
  }
  return piece.f;
}

Mat3 skew(const Vec3& v) {
  Mat3 s;
  s << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return s;
}

// --- Point–point: |r|². ---
Piece<1> point_point(const Vec3& r, bool derivatives) {
  Piece<1> out;
  out.f = r.squaredNorm();
  if (derivatives) {
    out.g = 2 * r;
    out.H = 2 * Mat3::Identity();
  }
  return out;
}

// --- Point–line: |r − σe|², σ = r·e/|e|², r = p − a, e = b − a; equal to |r×e|²/|e|². ---
bool line_degenerate(const Vec3& r, const Vec3& e) { return !(e.squaredNorm() > kDegenerateSin2 * r.squaredNorm()); }

double point_line_sq(const Vec3& r, const Vec3& e) {
  // The perpendicular part r − σe rather than |r|² − (r·e)²/|e|²: the latter cancels when p is near the line.
  return (r - (r.dot(e) / e.squaredNorm()) * e).squaredNorm();
}

Piece<2> point_line(const Vec3& r, const Vec3& e, bool derivatives) {
  Piece<2> out;
  const double beta = e.squaredNorm();
  const double sigma = r.dot(e) / beta;
  const Vec3 q = r - sigma * e;
  out.f = q.squaredNorm();
  if (!derivatives) return out;
  // ∂f/∂r = 2q, ∂f/∂e = −2σq (q ⟂ e makes the ∂σ terms vanish).
  out.g << 2 * q, -2 * sigma * q;
  const Mat3 P = Mat3::Identity() - e * e.transpose() / beta;
  const Mat3 Hre = -2 * (e * q.transpose() / beta + sigma * P);
  out.H.block<3, 3>(0, 0) = 2 * P;
  out.H.block<3, 3>(0, 3) = Hre;
  out.H.block<3, 3>(3, 0) = Hre.transpose();
  out.H.block<3, 3>(3, 3) = (-2 / beta) * q * q.transpose() + (2 * sigma / beta) * (q * e.transpose() + e * q.transpose()) +
                            (2 * sigma * sigma) * P;
  return out;
}

// --- Point–plane and line–line: (n·r)²/|n|² with n = e1×e2 (point–plane: r = p − t0, e1 = t1 − t0, e2 = t2 − t0;
// line–line: r = b0 − a0, e1 = a1 − a0, e2 = b1 − b0). ---
bool plane_degenerate(const Vec3& n, const Vec3& e1, const Vec3& e2) {
  return !(n.squaredNorm() > kDegenerateSin2 * e1.squaredNorm() * e2.squaredNorm());
}

// The same operations as plane() below, so that the classification's value and the typed value agree to the bit.
double plane_sq(const Vec3& r, const Vec3& n) {
  const double h = ((1 / n.norm()) * n).dot(r);
  return h * h;
}

Piece<3> plane(const Vec3& r, const Vec3& e1, const Vec3& e2, bool derivatives) {
  Piece<3> out;
  const Vec3 n = e1.cross(e2);
  const double kappa = 1 / n.norm();
  const Vec3 m = kappa * n;
  const double h = m.dot(r);  // signed distance
  out.f = h * h;
  if (!derivatives) return out;
  // With F(r, n) = (n·r)²/|n|², m = n/|n|, κ = 1/|n| and ρ = r − h·m (the in-plane part of r):
  //   F_r = 2h·m,  F_n = 2hκ·ρ,  F_rr = 2mmᵀ,  F_rn = 2κ(mρᵀ + h(I − mmᵀ)),
  //   F_nn = 2κ²(ρρᵀ − h(ρmᵀ + mρᵀ) − h²(I − mmᵀ));
  // then through n = e1×e2: ∂n/∂e1 = −[e2]×, ∂n/∂e2 = [e1]×, and the bilinear part F_n·(e1×e2) adds −[F_n]× to
  // the e1–e2 block.
  const Vec3 rho = r - h * m;
  const Vec3 Fn = 2 * h * kappa * rho;
  out.g << 2 * h * m, e2.cross(Fn), Fn.cross(e1);
  const Mat3 Pt = Mat3::Identity() - m * m.transpose();
  const Mat3 Frn = 2 * kappa * (m * rho.transpose() + h * Pt);
  const Mat3 Fnn = 2 * kappa * kappa * (rho * rho.transpose() - h * (rho * m.transpose() + m * rho.transpose()) - h * h * Pt);
  const Mat3 J1 = -skew(e2), J2 = skew(e1);
  const Mat3 FnnJ1 = Fnn * J1, FnnJ2 = Fnn * J2;
  const Mat3 Hre1 = Frn * J1, Hre2 = Frn * J2;
  const Mat3 He1e2 = J1.transpose() * FnnJ2 - skew(Fn);
  out.H.block<3, 3>(0, 0) = 2 * m * m.transpose();
  out.H.block<3, 3>(0, 3) = Hre1;
  out.H.block<3, 3>(0, 6) = Hre2;
  out.H.block<3, 3>(3, 0) = Hre1.transpose();
  out.H.block<3, 3>(6, 0) = Hre2.transpose();
  out.H.block<3, 3>(3, 3) = J1.transpose() * FnnJ1;
  out.H.block<3, 3>(6, 6) = J2.transpose() * FnnJ2;
  out.H.block<3, 3>(3, 6) = He1e2;
  out.H.block<3, 3>(6, 3) = He1e2.transpose();
  return out;
}

// --- Classification. The exact squared distance is always the value of the chosen type's formula, so that a type
// and its value never disagree. ---

// Nearest feature of segment (a, b) to p: 0 = a, 1 = b, 2 = interior.
struct Nearest {
  int feature;
  double d2;
};
Nearest point_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 r = p - a, e = b - a;
  if (line_degenerate(r, e)) {
    const double da = r.squaredNorm(), db = (p - b).squaredNorm();
    return da <= db ? Nearest{0, da} : Nearest{1, db};
  }
  const double s = r.dot(e) / e.squaredNorm();
  if (s <= 0) return {0, r.squaredNorm()};
  if (s >= 1) return {1, (p - b).squaredNorm()};
  return {2, point_line_sq(r, e)};
}

struct PointTriangleResult {
  PointTriangleType type;
  double d2;
};
// The nearest of the edges flagged `search` (the triangle's boundary; the whole triangle when it is degenerate).
PointTriangleResult nearest_on_edges(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2,
                                     const std::array<bool, 3>& search) {
  using T = PointTriangleType;
  static constexpr std::array<std::array<T, 3>, 3> kEdgeTypes{{{T::P_T0, T::P_T1, T::P_E0},
                                                                {T::P_T1, T::P_T2, T::P_E1},
                                                                {T::P_T2, T::P_T0, T::P_E2}}};
  const std::array<const Vec3*, 3> t{&t0, &t1, &t2};
  PointTriangleResult best{T::P_T0, kInf};
  for (int i = 0; i < 3; ++i) {
    if (!search[i]) continue;
    const Nearest near = point_segment(p, *t[i], *t[(i + 1) % 3]);
    if (near.d2 < best.d2) best = {kEdgeTypes[i][near.feature], near.d2};
  }
  return best;
}

PointTriangleResult classify_point_triangle(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2) {
  const Vec3 e1 = t1 - t0, e2 = t2 - t0;
  const Vec3 n = e1.cross(e2);
  if (plane_degenerate(n, e1, e2)) return nearest_on_edges(p, t0, t1, t2, {true, true, true});
  // The projection of p lies outside edge E_i when its barycentric coordinate opposite E_i is negative; the nearest
  // point is then on an edge it lies outside of, so only those edges are searched.
  const std::array<bool, 3> outside{e1.cross(p - t0).dot(n) < 0, (t2 - t1).cross(p - t1).dot(n) < 0,
                                    (t0 - t2).cross(p - t2).dot(n) < 0};
  if (!outside[0] && !outside[1] && !outside[2]) return {PointTriangleType::P_T, plane_sq(p - t0, n)};
  return nearest_on_edges(p, t0, t1, t2, outside);
}

struct EdgeEdgeResult {
  EdgeEdgeType type;
  double d2;
};
// The minimum of the convex squared distance over the boundary of the parameter square: an endpoint against the
// other segment.
EdgeEdgeResult nearest_on_boundary(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  using T = EdgeEdgeType;
  EdgeEdgeResult best{T::EA0_EB0, kInf};
  const auto consider = [&best](const Nearest& near, const std::array<T, 3>& types) {
    if (near.d2 < best.d2) best = {types[near.feature], near.d2};
  };
  consider(point_segment(a0, b0, b1), {T::EA0_EB0, T::EA0_EB1, T::EA0_EB});
  consider(point_segment(a1, b0, b1), {T::EA1_EB0, T::EA1_EB1, T::EA1_EB});
  consider(point_segment(b0, a0, a1), {T::EA0_EB0, T::EA1_EB0, T::EA_EB0});
  consider(point_segment(b1, a0, a1), {T::EA0_EB1, T::EA1_EB1, T::EA_EB1});
  return best;
}

EdgeEdgeResult classify_edge_edge(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  const Vec3 u = a1 - a0, v = b1 - b0, w = b0 - a0;
  const Vec3 n = u.cross(v);
  if (!plane_degenerate(n, u, v)) {
    // Parameters of the lines' closest points a0 + s·u and b0 + t·v; when both are inside, that is the minimum.
    const double nu = n.squaredNorm();
    const double s = w.cross(v).dot(n) / nu, t = w.cross(u).dot(n) / nu;
    if (s > 0 && s < 1 && t > 0 && t < 1) return {EdgeEdgeType::EA_EB, plane_sq(w, n)};
  }
  return nearest_on_boundary(a0, a1, b0, b1);
}

// The typed pieces on the 4 stacked points x[0..3]. A piece whose formula is degenerate by the classification's own
// threshold (zero-length edge, collapsed triangle, parallel segments), which a caller's stale type can ask for,
// falls back: a point–line to the nearer endpoint, a plane to the pair's own type (which is then never a plane).
using Points = std::array<const Vec3*, 4>;

double point_point_piece(const Points& x, int p, int q, Vec12* grad, Mat12* hess) {
  return scatter<1>(point_point(*x[p] - *x[q], grad || hess), {Diff{p, q}}, grad, hess);
}

double point_line_piece(const Points& x, int p, int a, int b, Vec12* grad, Mat12* hess) {
  const Vec3 r = *x[p] - *x[a], e = *x[b] - *x[a];
  if (line_degenerate(r, e)) {
    const bool nearer_a = r.squaredNorm() <= (*x[p] - *x[b]).squaredNorm();
    return point_point_piece(x, p, nearer_a ? a : b, grad, hess);
  }
  return scatter<2>(point_line(r, e, grad || hess), {Diff{p, a}, Diff{b, a}}, grad, hess);
}

// r = x[r.plus] − x[r.minus], e1, e2 likewise.
double plane_piece(const Points& x, Diff r, Diff e1, Diff e2, Vec12* grad, Mat12* hess) {
  const Vec3 y0 = *x[r.plus] - *x[r.minus], y1 = *x[e1.plus] - *x[e1.minus], y2 = *x[e2.plus] - *x[e2.minus];
  return scatter<3>(plane(y0, y1, y2, grad || hess), {r, e1, e2}, grad, hess);
}

}  // namespace

PointTriangleType point_triangle_type(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2) {
  return classify_point_triangle(p, t0, t1, t2).type;
}

EdgeEdgeType edge_edge_type(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  return classify_edge_edge(a0, a1, b0, b1).type;
}

double point_triangle_distance_sq(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2) {
  return classify_point_triangle(p, t0, t1, t2).d2;
}

double edge_edge_distance_sq(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  return classify_edge_edge(a0, a1, b0, b1).d2;
}

double point_triangle_distance_sq(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2, PointTriangleType type,
                                  Vec12* grad, Mat12* hess) {
  using T = PointTriangleType;
  const Points x{&p, &t0, &t1, &t2};
  switch (type) {
    case T::P_T0: return point_point_piece(x, 0, 1, grad, hess);
    case T::P_T1: return point_point_piece(x, 0, 2, grad, hess);
    case T::P_T2: return point_point_piece(x, 0, 3, grad, hess);
    case T::P_E0: return point_line_piece(x, 0, 1, 2, grad, hess);
    case T::P_E1: return point_line_piece(x, 0, 2, 3, grad, hess);
    case T::P_E2: return point_line_piece(x, 0, 3, 1, grad, hess);
    case T::P_T: break;
  }
  if (plane_degenerate((t1 - t0).cross(t2 - t0), t1 - t0, t2 - t0)) {
    const PointTriangleType own = nearest_on_edges(p, t0, t1, t2, {true, true, true}).type;
    return point_triangle_distance_sq(p, t0, t1, t2, own, grad, hess);
  }
  return plane_piece(x, {0, 1}, {2, 1}, {3, 1}, grad, hess);
}

double edge_edge_distance_sq(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, EdgeEdgeType type,
                             Vec12* grad, Mat12* hess) {
  using T = EdgeEdgeType;
  const Points x{&a0, &a1, &b0, &b1};
  switch (type) {
    case T::EA0_EB0: return point_point_piece(x, 0, 2, grad, hess);
    case T::EA0_EB1: return point_point_piece(x, 0, 3, grad, hess);
    case T::EA1_EB0: return point_point_piece(x, 1, 2, grad, hess);
    case T::EA1_EB1: return point_point_piece(x, 1, 3, grad, hess);
    case T::EA_EB0: return point_line_piece(x, 2, 0, 1, grad, hess);
    case T::EA_EB1: return point_line_piece(x, 3, 0, 1, grad, hess);
    case T::EA0_EB: return point_line_piece(x, 0, 2, 3, grad, hess);
    case T::EA1_EB: return point_line_piece(x, 1, 2, 3, grad, hess);
    case T::EA_EB: break;
  }
  const Vec3 u = a1 - a0, v = b1 - b0;
  if (plane_degenerate(u.cross(v), u, v)) {
    const EdgeEdgeType own = nearest_on_boundary(a0, a1, b0, b1).type;
    return edge_edge_distance_sq(a0, a1, b0, b1, own, grad, hess);
  }
  return plane_piece(x, {2, 0}, {1, 0}, {3, 2}, grad, hess);
}

}  // namespace mgcloth::collision
