#pragma once
// Element math of the triangle-cloth objective as free functions on plain arrays, shared by the CPU terms
// (physics/*.cpp) and the CUDA kernels (cuda/). Local vectors are xyz-interleaved per element vertex; local
// Hessians are row-major (they are symmetric, so the layout of an Eigen column-major matrix is the same).
#include <mgcloth/geometry/sdf_kernels.hpp>

namespace mgcloth::hd {

/// St. Venant-Kirchhoff membrane of one triangle (Wang 2018 §5; plane stress): W = A·t·(μ tr(E²) + λ/2 tr(E)²),
/// F = [x1−x0, x2−x0] Dm⁻¹, E = (FᵀF − I)/2. `dm_inv` is Dm⁻¹ row-major, `at` = material area × thickness.
/// g (9) and H (81) are filled when non-null. clamp_stress: the geometric term uses the positive part of the second
/// Piola-Kirchhoff stress S, which makes H positive semi-definite (the material term JᵀCJ always is); equal to the
/// exact Hessian where S ⪰ 0.
MGCLOTH_HOST_DEVICE inline double stvk_triangle(const double* x, const double* dm_inv, double at, double mu,
                                                double lambda, double* g, double* H, bool clamp_stress) {
  const V3 x0 = load3(x), e1 = load3(x + 3) - x0, e2 = load3(x + 6) - x0;
  // F = Σ_a x_a b_aᵀ with b_1, b_2 the rows of Dm⁻¹ and b_0 = −b_1 − b_2.
  const double b[3][2] = {{-dm_inv[0] - dm_inv[2], -dm_inv[1] - dm_inv[3]}, {dm_inv[0], dm_inv[1]}, {dm_inv[2], dm_inv[3]}};
  const V3 F0 = dm_inv[0] * e1 + dm_inv[2] * e2, F1 = dm_inv[1] * e1 + dm_inv[3] * e2;
  const double E00 = 0.5 * (dot(F0, F0) - 1.0), E01 = 0.5 * dot(F0, F1), E11 = 0.5 * (dot(F1, F1) - 1.0);
  const double trE = E00 + E11;
  const double energy = at * (mu * (E00 * E00 + 2.0 * E01 * E01 + E11 * E11) + 0.5 * lambda * trE * trE);
  if (!g && !H) return energy;
  const double S00 = 2.0 * mu * E00 + lambda * trE, S01 = 2.0 * mu * E01, S11 = 2.0 * mu * E11 + lambda * trE;
  if (g) {
    const V3 P0 = S00 * F0 + S01 * F1, P1 = S01 * F0 + S11 * F1;  // P = F S
    for (int a = 0; a < 3; ++a) store3(g + 3 * a, at * (b[a][0] * P0 + b[a][1] * P1));
  }
  if (H) {
    // ∂²W/∂x_a∂x_c = A t [(b_aᵀ S b_c) I + μ (F b_c)(F b_a)ᵀ + μ (b_a·b_c) F Fᵀ + λ (F b_a)(F b_c)ᵀ],
    // from dP = dF S + F dS with dF = δ b_cᵀ.
    double G00 = S00, G01 = S01, G11 = S11;
    if (clamp_stress) {
      // Eigenvalues l1 ≥ l2 of S; where they differ in sign, S₊ = l1 v1v1ᵀ = l1/(l1 − l2) (S − l2 I).
      const double m = 0.5 * (S00 + S11), d = 0.5 * (S00 - S11);
      const double r = std::sqrt(d * d + S01 * S01), l1 = m + r, l2 = m - r;
      if (l1 <= 0.0) {
        G00 = G01 = G11 = 0.0;
      } else if (l2 < 0.0) {
        const double s = l1 / (l1 - l2);
        G00 = s * (S00 - l2);
        G01 = s * S01;
        G11 = s * (S11 - l2);
      }
    }
    V3 Fb[3];
    for (int a = 0; a < 3; ++a) Fb[a] = b[a][0] * F0 + b[a][1] * F1;
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) {
        const double geo = b[a][0] * (G00 * b[c][0] + G01 * b[c][1]) + b[a][1] * (G01 * b[c][0] + G11 * b[c][1]);
        const double bb = b[a][0] * b[c][0] + b[a][1] * b[c][1];
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            const double FFt = comp(F0, i) * comp(F0, j) + comp(F1, i) * comp(F1, j);
            const double v = (i == j ? geo : 0.0) + mu * comp(Fb[c], i) * comp(Fb[a], j) + mu * bb * FFt +
                             lambda * comp(Fb[a], i) * comp(Fb[c], j);
            H[(3 * a + i) * 9 + 3 * c + j] = at * v;
          }
      }
  }
  return energy;
}

/// Signed dihedral angle of a hinge (x0, x1 the edge, x2 and x3 the opposite vertices):
/// θ = atan2((N1 × N2)·ê, N1·N2), N1 = e × (x2 − x0), N2 = (x3 − x0) × e; zero when flat.
MGCLOTH_HOST_DEVICE inline double dihedral_angle(const double* x) {
  const V3 x0 = load3(x), e = load3(x + 3) - x0;
  const V3 n1 = cross(e, load3(x + 6) - x0), n2 = cross(load3(x + 9) - x0, e);
  return std::atan2(dot(cross(n1, n2), e) / norm(e), dot(n1, n2));
}

/// ∇θ (Bridson et al. 2003): the opposite vertices move along their triangle's normal over its height
/// (∂θ/∂x2 = −|e| N1/|N1|²), the edge vertices take the opposite, split by where x2 and x3 project onto the edge.
/// Generic in the scalar so that the tests can check dihedral_angle_hessian against its automatic differentiation.
template <class S>
MGCLOTH_HOST_DEVICE void dihedral_angle_gradient(const S* x, S* g) {
  using std::sqrt;
  S e[3], a2[3], a3[3];
  for (int i = 0; i < 3; ++i) {
    e[i] = x[3 + i] - x[i];
    a2[i] = x[6 + i] - x[i];
    a3[i] = x[9 + i] - x[i];
  }
  const auto crs = [](const S* u, const S* v, S* w) {
    w[0] = u[1] * v[2] - u[2] * v[1];
    w[1] = u[2] * v[0] - u[0] * v[2];
    w[2] = u[0] * v[1] - u[1] * v[0];
  };
  const auto dt = [](const S* u, const S* v) -> S { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; };
  S n1[3], n2[3];
  crs(e, a2, n1);
  crs(a3, e, n2);
  const S el2 = dt(e, e);
  const S el = sqrt(el2);
  const S s2 = -el / dt(n1, n1), s3 = -el / dt(n2, n2);
  const S t2 = dt(a2, e) / el2, t3 = dt(a3, e) / el2;
  for (int i = 0; i < 3; ++i) {
    const S g2 = s2 * n1[i], g3 = s3 * n2[i];
    g[i] = -(S(1) - t2) * g2 - (S(1) - t3) * g3;
    g[3 + i] = -t2 * g2 - t3 * g3;
    g[6 + i] = g2;
    g[9 + i] = g3;
  }
}

/// Whether a hinge's triangles collapsed in world space (its angle has no gradient; it contributes no force).
MGCLOTH_HOST_DEVICE inline bool hinge_degenerate(const double* x) {
  const V3 x0 = load3(x), e = load3(x + 3) - x0;
  const double el2 = dot(e, e), tiny = 1e-24 * el2 * el2;
  const V3 n1 = cross(e, load3(x + 6) - x0), n2 = cross(e, load3(x + 9) - x0);
  return dot(n1, n1) <= tiny || dot(n2, n2) <= tiny;
}

/// ∇²θ (row-major 12×12) by differentiating dihedral_angle_gradient's closed form by hand. With e = x1 − x0,
/// a2 = x2 − x0, a3 = x3 − x0 the gradient reads g2 = −|e| n1/|n1|², g3 = −|e| n2/|n2|², g1 = −t2 g2 − t3 g3,
/// g0 = −g1 − g2 − g3; its partials in (e, a2, a3) follow from ∂(n/|n|²) = (I − 2n̂n̂ᵀ)/|n|² ∂n,
/// ∂n1 = −[a2]×∂e + [e]×∂a2, ∂n2 = [a3]×∂e − [e]×∂a3, ∂t2 = ((a2 − 2t2 e)·∂e + e·∂a2)/|e|², and map to the
/// vertices by ∂/∂x0 = −(∂/∂e + ∂/∂a2 + ∂/∂a3). Symmetric to round-off. Not for a degenerate hinge.
MGCLOTH_HOST_DEVICE inline void dihedral_angle_hessian(const double* x, double* H) {
  const V3 x0 = load3(x), e = load3(x + 3) - x0, a2 = load3(x + 6) - x0, a3 = load3(x + 9) - x0;
  const V3 n1 = cross(e, a2), n2 = cross(a3, e);
  const double el2 = dot(e, e), el = std::sqrt(el2), q1 = dot(n1, n1), q2 = dot(n2, n2);
  const V3 eh = (1.0 / el) * e;
  const V3 g2 = (-el / q1) * n1, g3 = (-el / q2) * n2;
  const double t2 = dot(a2, e) / el2, t3 = dot(a3, e) / el2;
  // D[r][w] = ∂g_r/∂w (row-major 3×3) for r = 0..3 and w = e, a2, a3.
  double D[4][3][9];
  // Column j of (I − 2n̂n̂ᵀ)(c × u_j) scaled by s, added to M.
  const auto add_reflected_cross = [](double* M, const V3& n, double q, const V3& c, double s) {
    const V3 u[3] = {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}};
    for (int j = 0; j < 3; ++j) {
      const V3 w = cross(c, u[j]);
      const V3 pw = w - (2.0 * dot(n, w) / q) * n;
      for (int i = 0; i < 3; ++i) M[3 * i + j] += s * comp(pw, i);
    }
  };
  const auto outer_add = [](double* M, const V3& a, const V3& b, double s) {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) M[3 * i + j] += s * comp(a, i) * comp(b, j);
  };
  for (int r = 0; r < 4; ++r)
    for (int w = 0; w < 3; ++w)
      for (int k = 0; k < 9; ++k) D[r][w][k] = 0.0;
  outer_add(D[2][0], n1, eh, -1.0 / q1);
  add_reflected_cross(D[2][0], n1, q1, a2, el / q1);
  add_reflected_cross(D[2][1], n1, q1, e, -el / q1);
  outer_add(D[3][0], n2, eh, -1.0 / q2);
  add_reflected_cross(D[3][0], n2, q2, a3, -el / q2);
  add_reflected_cross(D[3][2], n2, q2, e, el / q2);
  // g1 = −t2 g2 − t3 g3.
  const V3 dt2_de = (1.0 / el2) * (a2 - 2.0 * t2 * e), dt3_de = (1.0 / el2) * (a3 - 2.0 * t3 * e);
  const V3 dt_da = (1.0 / el2) * e;
  for (int k = 0; k < 9; ++k) {
    D[1][0][k] = -t2 * D[2][0][k] - t3 * D[3][0][k];
    D[1][1][k] = -t2 * D[2][1][k];
    D[1][2][k] = -t3 * D[3][2][k];
  }
  outer_add(D[1][0], g2, dt2_de, -1.0);
  outer_add(D[1][0], g3, dt3_de, -1.0);
  outer_add(D[1][1], g2, dt_da, -1.0);
  outer_add(D[1][2], g3, dt_da, -1.0);
  for (int w = 0; w < 3; ++w)
    for (int k = 0; k < 9; ++k) D[0][w][k] = -D[1][w][k] - D[2][w][k] - D[3][w][k];
  for (int r = 0; r < 4; ++r)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const int k = 3 * i + j;
        double* row = H + (3 * r + i) * 12 + j;
        row[0] = -(D[r][0][k] + D[r][1][k] + D[r][2][k]);
        row[3] = D[r][0][k];
        row[6] = D[r][1][k];
        row[9] = D[r][2][k];
      }
}

/// Hinge bending c θ² (discrete shells, flat rest state) with gradient and the Gauss-Newton Hessian 2c ∇θ∇θᵀ
/// (positive semi-definite; the exact Hessian adds 2cθ∇²θ). g (12), H_psd (144) when non-null.
MGCLOTH_HOST_DEVICE inline double hinge_bending_psd(const double* x, double c, double* g, double* H_psd) {
  const double theta = dihedral_angle(x);
  if (g || H_psd) {
    double dtheta[12];
    if (hinge_degenerate(x)) {
      for (int i = 0; i < 12; ++i) dtheta[i] = 0.0;
    } else {
      dihedral_angle_gradient(x, dtheta);
    }
    if (g)
      for (int i = 0; i < 12; ++i) g[i] = 2.0 * c * theta * dtheta[i];
    if (H_psd)
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) H_psd[12 * i + j] = 2.0 * c * dtheta[i] * dtheta[j];
  }
  return c * theta * theta;
}

/// Quadratic bending (Bergou et al. 2006): c |Σ_i K_i x_i|², constant PSD Hessian 2c K_i K_j I.
MGCLOTH_HOST_DEVICE inline double quadratic_bending(const double* x, const double* K, double c, double* g, double* H) {
  V3 s{0.0, 0.0, 0.0};
  for (int i = 0; i < 4; ++i) s = s + K[i] * load3(x + 3 * i);
  if (g)
    for (int i = 0; i < 4; ++i) store3(g + 3 * i, 2.0 * c * K[i] * s);
  if (H)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) H[(3 * i + a) * 12 + 3 * j + b] = a == b ? 2.0 * c * K[i] * K[j] : 0.0;
  return c * dot(s, s);
}

/// A spring to a point: k/2 |x − y|² (inertia with k = m/h² and y the prediction; pins with y the target).
MGCLOTH_HOST_DEVICE inline double point_spring(const double* x, const double* y, double k, double* g, double* H) {
  const V3 d = load3(x) - load3(y);
  if (g) store3(g, k * d);
  if (H) set_scaled_identity(H, k);
  return 0.5 * k * dot(d, d);
}

/// The cubic penalty's normal force k (d − φ)²/d at depth gap = d − φ (what friction weighs, §4.5).
MGCLOTH_HOST_DEVICE inline double contact_normal_force(double k, double gap, double d) { return k * gap * gap / d; }

/// Cubic obstacle penalty of one vertex against one obstacle, k/(3d) (d − φ)³ where φ < d (Wang 2018 §4.5). Adds
/// to g and H_psd (when non-null) the gradient −(k/d)(d − φ)² ∇φ and the PSD Hessian 2(k/d)(d − φ) ∇φ∇φᵀ: the
/// exact Hessian's other part, −(k/d)(d − φ)² ∇²φ, is negative semi-definite on our convex shapes, and ∇φ is an
/// eigenvector of ∇²φ with eigenvalue 0 (|∇φ| = 1), so dropping it is exactly the projection to PSD.
MGCLOTH_HOST_DEVICE inline double contact_psd(const ObstacleData& o, const double* x, double k, double d, double* g,
                                              double* H_psd) {
  V3 n;
  const double gap = contact_gap(o, x, d, n);
  if (gap <= 0.0) return 0.0;
  if (g) {
    const double s = contact_normal_force(k, gap, d);
    g[0] -= s * n.x;
    g[1] -= s * n.y;
    g[2] -= s * n.z;
  }
  if (H_psd) {
    const double s = 2.0 * (k / d) * gap;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) H_psd[3 * i + j] += s * comp(n, i) * comp(n, j);
  }
  return k * gap * gap * gap / (3.0 * d);
}

}  // namespace mgcloth::hd
