#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/physics/psd.hpp>
#include <mgcloth/physics/shell.hpp>
#include <mgcloth/physics/shell_kinematics.hpp>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>

namespace mgcloth::physics {

namespace {
using StencilBlock = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 6>>;
constexpr double kDegToRad = M_PI / 180.0;
}  // namespace

void line_gauss_rule(int n, std::vector<double>& points, std::vector<double>& weights) {
  if (n < 1 || n > 5) throw_input_error("Gauss-Legendre rule of {} points; 1-5 are supported", n);
  std::vector<double> z, w;
  switch (n) {
    case 1: z = {0.0}; w = {2.0}; break;
    case 2: z = {-1.0 / std::sqrt(3.0), 1.0 / std::sqrt(3.0)}; w = {1.0, 1.0}; break;
    case 3: z = {-std::sqrt(0.6), 0.0, std::sqrt(0.6)}; w = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0}; break;
    case 4: {
      const double a = std::sqrt(3.0 / 7.0 - 2.0 / 7.0 * std::sqrt(1.2)), b = std::sqrt(3.0 / 7.0 + 2.0 / 7.0 * std::sqrt(1.2));
      const double wa = (18.0 + std::sqrt(30.0)) / 36.0, wb = (18.0 - std::sqrt(30.0)) / 36.0;
      z = {-b, -a, a, b};
      w = {wb, wa, wa, wb};
      break;
    }
    default: {
      const double a = std::sqrt(5.0 - 2.0 * std::sqrt(10.0 / 7.0)) / 3.0, b = std::sqrt(5.0 + 2.0 * std::sqrt(10.0 / 7.0)) / 3.0;
      const double wa = (322.0 + 13.0 * std::sqrt(70.0)) / 900.0, wb = (322.0 - 13.0 * std::sqrt(70.0)) / 900.0;
      z = {-b, -a, 0.0, a, b};
      w = {wb, wa, 128.0 / 225.0, wa, wb};
    }
  }
  points.clear();
  weights.clear();
  for (int i = 0; i < n; ++i) {
    points.push_back(0.5 * (z[i] + 1.0));
    weights.push_back(0.5 * w[i]);
  }
}

void square_gauss_rule(int n, std::vector<Vec2>& points, std::vector<double>& weights) {
  std::vector<double> z, w;
  line_gauss_rule(n, z, w);
  points.clear();
  weights.clear();
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      points.emplace_back(z[i], z[j]);
      weights.push_back(w[i] * w[j]);
    }
}

std::vector<ShellFaceQuadrature> shell_quadrature(const mesh::LimitSurface& surface, int n) {
  std::vector<Vec2> pts;
  std::vector<double> wts;
  square_gauss_rule(n, pts, wts);
  std::vector<ShellFaceQuadrature> out;
  out.reserve(surface.real_faces().size());
  mesh::LimitStencil st;
  for (Index f : surface.real_faces()) {
    ShellFaceQuadrature fq;
    fq.face = f;
    for (size_t g = 0; g < pts.size(); ++g) {
      surface.stencil(f, pts[g].x(), pts[g].y(), st);
      if (g == 0) fq.points = st.points;
      const Index K = st.size();
      for (int d = 0; d < 6; ++d)
        for (Index k = 0; k < K; ++k) fq.basis.push_back(st.w(k, d));
    }
    out.push_back(std::move(fq));
  }
  return out;
}

ShellTerm::ShellTerm(const mesh::LimitSurface& surface, const ShellMaterial& material, const Vec3& gravity, int gauss)
    : m_material(material), m_gravity(gravity), m_num_points(surface.mesh().num_vertices()), m_gauss(gauss) {
  m_material.validate();
  m_faces = shell_quadrature(surface, gauss);
  std::vector<Vec2> pts;
  std::vector<double> wts;
  square_gauss_rule(gauss, pts, wts);
  const Mat3X& rest = surface.mesh().x;
  const Mat2X& u = surface.mesh().u;
  const double theta = m_material.warp_angle_deg * kDegToRad;
  const Vec2 warp(std::cos(theta), std::sin(theta));
  const Index nq = static_cast<Index>(pts.size());
  m_ref.resize(m_faces.size() * nq);
  for (size_t e = 0; e < m_faces.size(); ++e) {
    const auto& F = m_faces[e];
    const Index K = F.size();
    Mat3X q(3, K);
    Mat2X uq(2, K);
    for (Index k = 0; k < K; ++k) {
      q.col(k) = rest.col(F.points[k]);
      uq.col(k) = u.col(F.points[k]);
    }
    for (Index g = 0; g < nq; ++g) {
      const StencilBlock D(F.basis.data() + static_cast<size_t>(g) * K * 6, K, 6);
      const Eigen::Matrix<double, 3, 6> Z = q * D;
      const Vec3 a1 = Z.col(1), a2 = Z.col(2);
      const Vec3 m = a1.cross(a2);
      const double jac = m.norm();
      if (!(jac > 1e-14 * (a1.squaredNorm() + a2.squaredNorm())))
        throw_input_error("quad {}: the reference limit surface is degenerate at a Gauss point (zero area element)", F.face);
      const Vec3 n = m / jac;
      Reference& r = m_ref[e * nq + g];
      r.dA = wts[g] * jac;
      r.abar = Vec3(a1.dot(a1), a2.dot(a2), a1.dot(a2));
      r.bbar = Vec3(Z.col(3).dot(n), Z.col(5).dot(n), Z.col(4).dot(n));
      // Material frame: the warp direction mapped from material space onto the reference tangent plane, weft
      // perpendicular to it in that plane (eq. 3.3, O = [o1, o2, o3]).
      Mat2 Ju;
      Ju.col(0) = uq * D.col(1);
      Ju.col(1) = uq * D.col(2);
      if (!(std::abs(Ju.determinant()) > 1e-14 * Ju.squaredNorm()))
        throw_input_error("quad {}: the material coordinates are degenerate (zero material area at a Gauss point)", F.face);
      const Vec2 w = Ju.lu().solve(warp);
      const Vec3 o1 = (w.x() * a1 + w.y() * a2).normalized();
      const Vec3 o2 = n.cross(o1);
      Mat2 A;
      A << r.abar[0], r.abar[2], r.abar[2], r.abar[1];
      const Mat2 Ai = A.inverse();
      const Vec3 c1 = Ai(0, 0) * a1 + Ai(0, 1) * a2, c2 = Ai(1, 0) * a1 + Ai(1, 1) * a2;  // contravariant ā^α
      const double C00 = o1.dot(c1), C01 = o1.dot(c2), C10 = o2.dot(c1), C11 = o2.dot(c2);
      r.T << C00 * C00, C01 * C01, 2.0 * C00 * C01,  //
          C10 * C10, C11 * C11, 2.0 * C10 * C11,      //
          C00 * C10, C01 * C11, C00 * C11 + C01 * C10;
      m_area += r.dA;
    }
  }
  Index kmax = 0;
  for (const auto& F : m_faces) kmax = std::max(kmax, F.size());
  std::vector<Index> flat(m_faces.size() * kmax);
  for (size_t e = 0; e < m_faces.size(); ++e)
    for (Index k = 0; k < kmax; ++k) flat[e * kmax + k] = m_faces[e].points[std::min(k, m_faces[e].size() - 1)];
  m_colors = color_elements(flat, static_cast<int>(kmax), m_num_points);
  m_prediction = VecX::Zero(3 * m_num_points);
}

void ShellTerm::set_inertia(double h, const VecX& y) {
  if (h > 0.0) {
    if (y.size() != 3 * m_num_points) throw_error("ShellTerm::set_inertia: prediction has {} entries, expected {}", y.size(), 3 * m_num_points);
    m_inertia_coeff = m_material.density / (h * h);
    m_prediction = y;
  } else {
    m_inertia_coeff = 0.0;
  }
}

void ShellTerm::set_parts(bool elastic, bool inertia, bool gravity) {
  m_elastic = elastic;
  m_inertia = inertia;
  m_gravity_on = gravity;
}

double ShellTerm::element(Index e, const VecX& x, VecX* g, MatX* H) const {
  const auto& F = m_faces[e];
  const Index K = F.size();
  const Index nq = m_gauss * m_gauss;
  Mat3X q(3, K), y(3, K);
  for (Index k = 0; k < K; ++k) {
    q.col(k) = x.segment<3>(3 * F.points[k]);
    y.col(k) = m_prediction.segment<3>(3 * F.points[k]);
  }
  if (g) g->setZero(3 * K);
  if (H) H->setZero(3 * K, 3 * K);
  const bool inertia = m_inertia && m_inertia_coeff > 0.0;
  const Vec3 gravity = m_gravity_on ? Vec3(m_gravity_scale * m_material.density * m_gravity) : Vec3::Zero();
  double energy = 0.0;
  Eigen::Matrix<double, 6, 1> s, Ws, gW;
  Mat6 HW, L = Mat6::Zero(), Wss;
  ShellJacobian J;
  Eigen::Matrix<double, Eigen::Dynamic, 18> R;
  for (Index gp = 0; gp < nq; ++gp) {
    const Reference& r = m_ref[static_cast<size_t>(e) * nq + gp];
    const StencilBlock D(F.basis.data() + static_cast<size_t>(gp) * K * 6, K, 6);
    Eigen::Matrix<double, 3, 6> Z = q * D;
    const Vec18 z = Eigen::Map<const Vec18>(Z.data());
    Vec18 gz = Vec18::Zero();
    Mat18 Hz = Mat18::Zero();
    if (m_elastic) {
      if (!shell_fundamental_forms(z, s, g || H ? &J : nullptr)) return kInf;
      const Vec3 eps = 0.5 * (s.head<3>() - r.abar), kappa = r.bbar - s.tail<3>();
      const double W = shell_area_density(m_material, r.T * eps, r.T * kappa, g || H ? &gW : nullptr, H ? &HW : nullptr);
      if (!std::isfinite(W)) return kInf;
      energy += r.dA * W;
      if (g || H) {
        // s -> (ε, κ) -> frame: ε = (a − ā)/2, κ = b̄ − b, then T.
        L.topLeftCorner<3, 3>() = 0.5 * r.T;
        L.bottomRightCorner<3, 3>() = -r.T;
        Ws = L.transpose() * gW;
        gz += r.dA * J.transpose() * Ws;
        if (H) {
          Wss = L.transpose() * HW * L;
          Hz += r.dA * J.transpose() * Wss * J;
          add_fundamental_form_curvature(z, r.dA * Ws, Hz);
        }
      }
    }
    if (inertia) {
      const Vec3 d = Z.col(0) - y * D.col(0);
      energy += 0.5 * m_inertia_coeff * r.dA * d.squaredNorm();
      gz.head<3>() += m_inertia_coeff * r.dA * d;
      Hz.topLeftCorner<3, 3>() += m_inertia_coeff * r.dA * Mat3::Identity();
    }
    if (m_gravity_on) {
      energy -= r.dA * gravity.dot(Z.col(0));
      gz.head<3>() -= r.dA * gravity;
    }
    if (g) {
      Eigen::Map<Mat3X> gl(g->data(), 3, K);
      gl.noalias() += Eigen::Map<const Eigen::Matrix<double, 3, 6>>(gz.data()) * D.transpose();
    }
    if (H) {
      // H += Bᵀ Hz B with B = ∂z/∂q (z_{3j+c} = Σ_a D(a,j) q_{c,a}): first R = Bᵀ Hz by 3x18 row blocks, then the
      // upper block triangle of R B (Hz is symmetric), mirrored once after the last Gauss point. Fixed-size 3x3
      // arithmetic: the dynamic products this replaces spent most of their time in small-matrix overhead.
      R.resize(3 * K, 18);
      for (Index a = 0; a < K; ++a) {
        Eigen::Matrix<double, 3, 18> Ra = D(a, 0) * Hz.topRows<3>();
        for (int j = 1; j < 6; ++j)
          if (D(a, j) != 0.0) Ra.noalias() += D(a, j) * Hz.middleRows<3>(3 * j);
        R.middleRows<3>(3 * a) = Ra;
      }
      for (Index a = 0; a < K; ++a)
        for (int l = 0; l < 6; ++l) {
          const Mat3 Ral = R.block<3, 3>(3 * a, 3 * l);
          for (Index b = a; b < K; ++b)
            if (D(b, l) != 0.0) H->block<3, 3>(3 * a, 3 * b).noalias() += D(b, l) * Ral;
        }
    }
  }
  if (H)
    for (Index a = 0; a < K; ++a)
      for (Index b = a + 1; b < K; ++b) H->block<3, 3>(3 * b, 3 * a) = H->block<3, 3>(3 * a, 3 * b).transpose();
  return energy;
}


double ShellTerm::value(const VecX& x) const {
  return parallel_sum(num_elements(), [&](Index e) { return element(e, x, nullptr, nullptr); });
}

void ShellTerm::add_gradient(const VecX& x, VecX& g) const {
  physics::for_each_colored(m_colors, [&](Index e) {
    VecX ge;
    element(e, x, &ge, nullptr);
    const auto& P = m_faces[e].points;
    for (size_t a = 0; a < P.size(); ++a) g.segment<3>(3 * P[a]) += ge.segment<3>(3 * a);
  });
}

void ShellTerm::add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool project) const {
  physics::for_each_colored(m_colors, [&](Index e) {
    VecX ge;
    MatX He;
    element(e, x, &ge, &He);
    if (project) project_psd(He);
    const Index K = m_faces[e].size();
    const Index* slots = &m_slots[m_slot_offsets[e]];
    for (Index a = 0; a < K; ++a)
      for (Index b = 0; b < K; ++b) H.block(slots[a * K + b]) += He.block<3, 3>(3 * a, 3 * b);
  });
}

void ShellTerm::collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const {
  for (const auto& F : m_faces)
    for (Index a : F.points)
      for (Index b : F.points)
        if (a <= b) pairs.emplace_back(a, b);
}

void ShellTerm::bind(const linalg::BlockMatrix3& pattern) {
  m_slot_offsets.assign(1, 0);
  m_slots.clear();
  for (const auto& F : m_faces) {
    for (Index a : F.points)
      for (Index b : F.points) m_slots.push_back(pattern.find(a, b));
    m_slot_offsets.push_back(static_cast<Index>(m_slots.size()));
  }
}

VecX ShellTerm::mass_times(const VecX& v) const {
  VecX out = VecX::Zero(v.size());
  const Index nq = m_gauss * m_gauss;
  for (size_t e = 0; e < m_faces.size(); ++e) {
    const auto& F = m_faces[e];
    const Index K = F.size();
    for (Index gp = 0; gp < nq; ++gp) {
      const StencilBlock D(F.basis.data() + static_cast<size_t>(gp) * K * 6, K, 6);
      Vec3 vq = Vec3::Zero();
      for (Index k = 0; k < K; ++k) vq += D(k, 0) * v.segment<3>(3 * F.points[k]);
      const double c = m_material.density * m_ref[e * nq + gp].dA;
      for (Index k = 0; k < K; ++k) out.segment<3>(3 * F.points[k]) += c * D(k, 0) * vq;
    }
  }
  return out;
}

}  // namespace mgcloth::physics
