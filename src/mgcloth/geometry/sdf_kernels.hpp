#pragma once
// Signed distances of the obstacle shapes as free functions on plain data, shared by geometry::Shape on the CPU and
// the CUDA kernels (cuda/).
#include <mgcloth/core/host_device.hpp>

namespace mgcloth::hd {

/// Signed distance of the obstacle shapes in their local frame: φ and ∇φ, and ∇²φ when hess is non-null.
enum ShapeKind : int { kPlane = 0, kSphere = 1, kBox = 2, kCapsule = 3 };

namespace detail {
// sign(0) = +1 so that points on a symmetry plane still get a unit gradient.
MGCLOTH_HOST_DEVICE inline double sign_of(double v) { return v < 0.0 ? -1.0 : 1.0; }
/// φ = |v| − radius with H = (I − n nᵀ)/|v|; at v = 0 the gradient is `fallback`.
MGCLOTH_HOST_DEVICE inline double point_distance(const V3& v, double radius, const V3& fallback, V3& grad, double* hess) {
  const double r = norm(v);
  if (hess)
    for (int i = 0; i < 9; ++i) hess[i] = 0.0;
  if (r == 0.0) {
    grad = fallback;
    return -radius;
  }
  grad = (1.0 / r) * v;
  if (hess)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) hess[3 * i + j] = ((i == j ? 1.0 : 0.0) - comp(grad, i) * comp(grad, j)) / r;
  return r - radius;
}
}  // namespace detail

/// φ alone (the cheap test before sdf()). `p`: shape parameters (sphere: radius; box: half extents; capsule:
/// radius, half length).
MGCLOTH_HOST_DEVICE inline double sdf_distance(int kind, const double* p, const V3& q) {
  switch (kind) {
    case kPlane: return q.z;
    case kSphere: return norm(q) - p[0];
    case kBox: {
      const V3 d{std::fabs(q.x) - p[0], std::fabs(q.y) - p[1], std::fabs(q.z) - p[2]};
      const double m = std::fmax(d.x, std::fmax(d.y, d.z));
      if (m <= 0.0) return m;
      const V3 o{std::fmax(d.x, 0.0), std::fmax(d.y, 0.0), std::fmax(d.z, 0.0)};
      return norm(o);
    }
    default: {
      const double z = std::fmin(std::fmax(q.z, -p[1]), p[1]);
      return norm(V3{q.x, q.y, q.z - z}) - p[0];
    }
  }
}

/// φ, ∇φ and (hess non-null) ∇²φ, row-major; the Hessian is the exact second derivative where φ is smooth.
MGCLOTH_HOST_DEVICE inline double sdf(int kind, const double* p, const V3& q, V3& grad, double* hess) {
  if (hess)
    for (int i = 0; i < 9; ++i) hess[i] = 0.0;
  switch (kind) {
    case kPlane: grad = {0.0, 0.0, 1.0}; return q.z;
    case kSphere: return detail::point_distance(q, p[0], V3{0.0, 0.0, 1.0}, grad, hess);
    case kBox: {
      // q_i = |p_i| − h_i: signed distance to the slab of axis i (positive outside it).
      const double sg[3] = {detail::sign_of(q.x), detail::sign_of(q.y), detail::sign_of(q.z)};
      const double d[3] = {std::fabs(q.x) - p[0], std::fabs(q.y) - p[1], std::fabs(q.z) - p[2]};
      int k = 0;
      for (int i = 1; i < 3; ++i)
        if (d[i] > d[k]) k = i;
      if (d[k] <= 0.0) {
        // Inside: the nearest face wins; φ is piecewise linear, so H = 0 (ties go to the lowest axis).
        double gv[3] = {0.0, 0.0, 0.0};
        gv[k] = sg[k];
        grad = {gv[0], gv[1], gv[2]};
        return d[k];
      }
      // Outside: the norm of the active components; ∇φ = sign ∘ d₊/|d₊|, H = (P_A − ∇φ∇φᵀ)/|d₊|.
      const double o[3] = {std::fmax(d[0], 0.0), std::fmax(d[1], 0.0), std::fmax(d[2], 0.0)};
      const double phi = std::sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
      const double gv[3] = {sg[0] * o[0] / phi, sg[1] * o[1] / phi, sg[2] * o[2] / phi};
      grad = {gv[0], gv[1], gv[2]};
      if (hess)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) hess[3 * i + j] = ((i == j && d[i] > 0.0 ? 1.0 : 0.0) - gv[i] * gv[j]) / phi;
      return phi;
    }
    default: {
      const double half = p[1];
      if (std::fabs(q.z) >= half) {
        // Beyond the segment: the distance to the end point, as for a sphere; on the axis the normal is ±z.
        const V3 end{0.0, 0.0, std::copysign(half, q.z)};
        return detail::point_distance(q - end, p[0], V3{0.0, 0.0, detail::sign_of(q.z)}, grad, hess);
      }
      // Beside the segment: the distance to the z axis, H = (I − e_z e_zᵀ − n nᵀ)/|(x, y)|.
      const V3 v{q.x, q.y, 0.0};
      const double r = norm(v);
      if (r == 0.0) {
        grad = {1.0, 0.0, 0.0};  // on the axis every radial direction is a normal; pick one deterministically
        return -p[0];
      }
      grad = (1.0 / r) * v;
      if (hess)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            hess[3 * i + j] = ((i == j && i < 2 ? 1.0 : 0.0) - comp(grad, i) * comp(grad, j)) / r;
      return r - p[0];
    }
  }
}

/// An obstacle placed at a pose: shape kind and parameters, rotation R (row-major) and translation t, so that
/// the local point is Rᵀ(x − t).
struct ObstacleData {
  int kind = kPlane;
  double param[3] = {0.0, 0.0, 0.0};
  double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  double t[3] = {0.0, 0.0, 0.0};
  double friction = 0.0;
  /// Linear velocity of the body's origin t and angular velocity (world frame), at the pose's time: the velocity
  /// of the surface that friction measures slip against.
  double v[3] = {0.0, 0.0, 0.0};
  double w[3] = {0.0, 0.0, 0.0};
};

MGCLOTH_HOST_DEVICE inline V3 to_local(const ObstacleData& o, const V3& x) {
  const V3 d = x - load3(o.t);
  return {o.R[0] * d.x + o.R[3] * d.y + o.R[6] * d.z, o.R[1] * d.x + o.R[4] * d.y + o.R[7] * d.z,
          o.R[2] * d.x + o.R[5] * d.y + o.R[8] * d.z};
}
MGCLOTH_HOST_DEVICE inline V3 rotate(const ObstacleData& o, const V3& v) {
  return {o.R[0] * v.x + o.R[1] * v.y + o.R[2] * v.z, o.R[3] * v.x + o.R[4] * v.y + o.R[5] * v.z,
          o.R[6] * v.x + o.R[7] * v.y + o.R[8] * v.z};
}

/// Moves a point inside the obstacle (φ < 0) onto its surface along ∇φ; returns the distance moved (0: outside).
MGCLOTH_HOST_DEVICE inline double project_out(const ObstacleData& o, double* x) {
  const V3 q = to_local(o, load3(x));
  if (sdf_distance(o.kind, o.param, q) >= 0.0) return 0.0;
  V3 gl;
  const double phi = sdf(o.kind, o.param, q, gl, nullptr);
  if (phi >= 0.0) return 0.0;
  store3(x, load3(x) - phi * rotate(o, gl));
  return -phi;
}

/// Moves vertex x out of every obstacle it lies inside; a vertex may touch several, so a few passes settle it
/// where their surfaces meet. Returns the total distance moved (0: it was outside all of them).
MGCLOTH_HOST_DEVICE inline double project_vertex(const ObstacleData* obstacles, int count, double* x) {
  double pushed = 0.0;
  for (int pass = 0; pass < 4; ++pass) {
    bool inside = false;
    for (int o = 0; o < count; ++o) {
      const double moved = project_out(obstacles[o], x);
      if (moved > 0.0) {
        inside = true;
        pushed += moved;
      }
    }
    if (!inside) break;
  }
  return pushed;
}

/// Velocity of the body's material point at world position x: v + w × (x − t).
MGCLOTH_HOST_DEVICE inline V3 point_velocity(const ObstacleData& o, const V3& x) {
  return load3(o.v) + cross(load3(o.w), x - load3(o.t));
}

/// Depth gap = d − φ of x in the contact layer of thickness d (≤ 0: outside it), and the world normal ∇φ there.
MGCLOTH_HOST_DEVICE inline double contact_gap(const ObstacleData& o, const double* x, double d, V3& normal) {
  const V3 q = to_local(o, load3(x));
  if (d - sdf_distance(o.kind, o.param, q) <= 0.0) return 0.0;
  V3 gl;
  const double gap = d - sdf(o.kind, o.param, q, gl, nullptr);
  if (gap <= 0.0) return 0.0;
  normal = rotate(o, gl);
  return gap;
}

/// Coulomb friction by velocity filtering (Bridson et al. 2002 §7.2) of vertex velocity v against a surface with
/// normal n moving at v_obs: the normal part of the relative velocity loses any component into the obstacle, the
/// tangential part shrinks by μ·Δv_n (the normal velocity change the contact produced this step) and is clamped
/// at zero (static friction).
MGCLOTH_HOST_DEVICE inline void filter_velocity(double* v, const V3& v_obs, const V3& n, double dvn, double mu) {
  const V3 rel = load3(v) - v_obs;
  const double vn_raw = dot(rel, n);
  const double vn = vn_raw < 0.0 ? 0.0 : vn_raw;
  V3 vt = rel - vn_raw * n;
  const double vt_norm = norm(vt);
  if (mu > 0.0 && vt_norm > 0.0) {
    const double keep = 1.0 - mu * dvn / vt_norm;
    vt = (keep > 0.0 ? keep : 0.0) * vt;
  }
  store3(v, v_obs + vn * n + vt);
}

}  // namespace mgcloth::hd
