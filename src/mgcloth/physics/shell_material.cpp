#include <mgcloth/core/error.hpp>
#include <mgcloth/physics/shell.hpp>
#include <mgcloth/physics/shell_material.hpp>

#include <cmath>

namespace mgcloth::physics {

void WovenResponse::evaluate(double u, double& f, double& df, double& ddf) const {
  if (mu.empty()) {
    f = u;
    df = 1.0;
    ddf = 0.0;
    return;
  }
  f = df = ddf = 0.0;
  const double base = 1.0 + u;
  // The value's (1 + u)^α − 1 is formed by expm1/log1p: the μ_ji are O(10³) and cancel to φ'(0) = 1, so
  // pow(1 + u, α) − 1 would lose every digit of αu at small strain (u = Ẽ² ~ 1e-10). One log1p serves every term,
  // and the derivatives' lower powers follow by division, so no pow is needed (it and log1p were a tenth of a
  // shell solve's time).
  const double log_base = base > 0.0 ? std::log1p(u) : 0.0;
  for (size_t i = 0; i < mu.size(); ++i) {
    const double a = alpha[i];
    if (base <= 0.0 && a != std::round(a)) {
      f = kInf;
      return;
    }
    double p0m1, p1, p2;
    if (base > 0.0) {
      p0m1 = std::expm1(a * log_base);
      p1 = (p0m1 + 1.0) / base;
      p2 = p1 / base;
    } else {
      p2 = std::pow(base, a - 2.0);
      p1 = p2 * base;
      p0m1 = p1 * base - 1.0;
    }
    f += mu[i] / a * p0m1;
    df += mu[i] * p1;
    ddf += mu[i] * (a - 1.0) * p2;
  }
}

void ShellMaterial::validate() const {
  const auto positive = [](double v, const char* name) {
    if (!(v > 0.0) || !std::isfinite(v)) throw_input_error("shell material: {} must be positive and finite (got {})", name, v);
  };
  positive(thickness, "thickness");
  positive(density, "density");
  if (!std::isfinite(warp_angle_deg)) throw_input_error("shell material: warp_angle must be finite");
  if (!(woven_energy_floor >= 0.0 && woven_energy_floor < 1.0))
    throw_input_error("shell material: energy_floor must lie in [0, 1) (got {})", woven_energy_floor);
  if (thickness_points < 2 || thickness_points > 5)
    throw_input_error("shell material: thickness_points must be 2-5 (one point has no bending) (got {})", thickness_points);
  if (model == Model::stvk) {
    positive(young, "young");
    if (!(poisson > -1.0 && poisson < 0.5))
      throw_input_error("shell material: poisson must lie in (-1, 0.5) (got {})", poisson);
    return;
  }
  for (int j = 0; j < 4; ++j) {
    if (!std::isfinite(k[j])) throw_input_error("shell material: k{} must be finite (got {})", j + 1, k[j]);
    const auto& p = phi[j];
    if (p.mu.size() != p.alpha.size())
      throw_input_error("shell material: phi{} has {} mu and {} alpha values", j + 1, p.mu.size(), p.alpha.size());
    for (size_t i = 0; i < p.mu.size(); ++i)
      if (!std::isfinite(p.mu[i]) || !std::isfinite(p.alpha[i]) || p.alpha[i] == 0.0)
        throw_input_error("shell material: phi{} term {}: mu and alpha must be finite, alpha non-zero", j + 1, i + 1);
  }
  if (!(k[0] > 0.0) || !(k[2] > 0.0) || !(k[3] > 0.0) || !(k[0] * k[2] > k[1] * k[1]))
    throw_input_error("shell material: the small-strain stiffness must be positive definite: k1, k3, k4 > 0 and "
                      "k1 k3 > k2² (got k = {}, {}, {}, {})", k[0], k[1], k[2], k[3]);
}

ShellMaterial denim_material() {
  ShellMaterial m;
  m.model = ShellMaterial::Model::woven;
  m.k = {4.79e6, 4.52e6, 9.03e6, 2.44e6};
  m.thickness = 0.66e-3;
  m.density = 0.4;
  m.integration = ShellMaterial::Integration::split;
  const auto response = [](std::vector<double> mu_rest, std::vector<double> alpha) {
    double sum = 0.0;
    for (double v : mu_rest) sum += v;
    std::vector<double> mu{1.0 - sum};
    mu.insert(mu.end(), mu_rest.begin(), mu_rest.end());
    return WovenResponse{mu, std::move(alpha)};
  };
  m.phi[0] = response({-1482.1, 276.43, 2407.67, 3416.79}, {-7.80, 10.80, 18.95, -12.89, 1.61});
  m.phi[1] = response({}, {1.0});
  m.phi[2] = response({0.658, -185.7, -45.82, 146.98}, {12.71, -12802.0, 17.91, 30.07, 24.68});
  m.phi[3] = response({0.79, 11.08}, {2.95, -2823.9, 4.29});
  return m;
}

double shell_energy_density(const ShellMaterial& m, const Vec3& e, Vec3* g, Mat3* H) {
  if (m.model == ShellMaterial::Model::stvk) {
    const double c = m.young / (2.0 * (1.0 - m.poisson * m.poisson)), nu = m.poisson;
    const double psi = c * (e[0] * e[0] + e[1] * e[1] + 2.0 * nu * e[0] * e[1] + 2.0 * (1.0 - nu) * e[2] * e[2]);
    if (g) *g = 2.0 * c * Vec3(e[0] + nu * e[1], e[1] + nu * e[0], 2.0 * (1.0 - nu) * e[2]);
    if (H) *H << 2.0 * c, 2.0 * c * nu, 0.0, 2.0 * c * nu, 2.0 * c, 0.0, 0.0, 0.0, 4.0 * c * (1.0 - nu);
    return psi;
  }
  // eq. (3.3)
  double f1, d1, dd1, f2, d2, dd2, f3, d3, dd3, f4, d4, dd4;
  m.phi[0].evaluate(e[0] * e[0], f1, d1, dd1);
  m.phi[1].evaluate(e[0] * e[1], f2, d2, dd2);
  m.phi[2].evaluate(e[1] * e[1], f3, d3, dd3);
  m.phi[3].evaluate(e[2] * e[2], f4, d4, dd4);
  const auto& k = m.k;
  double psi = 0.5 * k[0] * f1 + k[1] * f2 + 0.5 * k[2] * f3 + k[3] * f4;
  if (psi == kInf) return kInf;  // overflow of a stiffening response: an infinitely stiff state
  // Beyond the paper: the fit's responses soften while its coupling k2 φ2 stays linear, so ψ turns negative at
  // moderate opposite strains (about −2e4 J/m³ at Ẽ11 = −Ẽ22 = 0.1 for denim) and, where φ3' < 0 (Ẽ22² > 0.102),
  // falls without bound; solvers then find such states at dt = 1 s. The energy is kept at or above a fraction of
  // the small-strain (linear orthotropic) energy ½ Ẽᵀ C₀ Ẽ, which changes nothing where the fit still has that
  // much of its initial stiffness and makes the model bounded below and convex where it has not.
  const double floor_fraction = m.woven_energy_floor;
  Vec3 gfit = Vec3(k[0] * d1 * e[0] + k[1] * d2 * e[1], k[2] * d3 * e[1] + k[1] * d2 * e[0], 2.0 * k[3] * d4 * e[2]);
  Mat3 Hfit = Mat3::Zero();
  Hfit(0, 0) = k[0] * (d1 + 2.0 * e[0] * e[0] * dd1) + k[1] * dd2 * e[1] * e[1];
  Hfit(1, 1) = k[2] * (d3 + 2.0 * e[1] * e[1] * dd3) + k[1] * dd2 * e[0] * e[0];
  Hfit(0, 1) = Hfit(1, 0) = k[1] * (d2 + dd2 * e[0] * e[1]);
  Hfit(2, 2) = 2.0 * k[3] * (d4 + 2.0 * e[2] * e[2] * dd4);
  if (floor_fraction > 0.0) {
    Mat3 C0;
    C0 << k[0], k[1], 0.0, k[1], k[2], 0.0, 0.0, 0.0, 2.0 * k[3];
    const double F = 0.5 * floor_fraction * e.dot(C0 * e);
    // ψ = F h(ψ_fit / F): the fit itself where ψ_fit >= 2F, h(u) = 1 + e^(u − 2) below (C¹ at u = 2, so that
    // the solvers see no kink), which decays to the floor F where the fit turns negative or falls without bound.
    if (F > 0.0 && !(psi >= 2.0 * F)) {
      const Vec3 gF = floor_fraction * C0 * e;
      if (!std::isfinite(psi) || !gfit.allFinite() || !Hfit.allFinite()) {  // the fit fell without bound
        if (g) *g = gF;
        if (H) *H = floor_fraction * C0;
        return F;
      }
      const double u = psi / F;
      const double ex = std::exp(u - 2.0), h = 1.0 + ex, dh = ex, ddh = ex;
      if (g) *g = (h - u * dh) * gF + dh * gfit;
      if (H) {
        const Vec3 w = gfit - u * gF;
        *H = (h - u * dh) * floor_fraction * C0 + dh * Hfit + (ddh / F) * w * w.transpose();
      }
      return F * h;
    }
  }
  if (!std::isfinite(psi)) return kInf;
  if (g) *g = gfit;
  if (H) *H = Hfit;
  return psi;
}


double shell_area_density(const ShellMaterial& m, const Vec3& eps, const Vec3& kappa, Vec6* g, Mat6* H) {
  if (m.integration == ShellMaterial::Integration::split) {
    Vec3 ge;
    Mat3 He, C0;
    const double membrane = shell_energy_density(m, eps, g ? &ge : nullptr, H ? &He : nullptr);
    if (!std::isfinite(membrane)) return kInf;
    shell_energy_density(m, Vec3::Zero(), nullptr, &C0);
    const double b = m.thickness * m.thickness * m.thickness / 12.0;
    if (g) {
      g->head<3>() = m.thickness * ge;
      g->tail<3>() = b * C0 * kappa;
    }
    if (H) {
      H->setZero();
      H->topLeftCorner<3, 3>() = m.thickness * He;
      H->bottomRightCorner<3, 3>() = b * C0;
    }
    return m.thickness * membrane + 0.5 * b * kappa.dot(C0 * kappa);
  }
  std::vector<double> z, w;
  const int n = m.thickness_points;
  line_gauss_rule(n, z, w);
  double W = 0.0;
  if (g) g->setZero();
  if (H) H->setZero();
  Vec3 ge;
  Mat3 He;
  for (int i = 0; i < n; ++i) {
    const double zi = m.thickness * (z[i] - 0.5), wi = m.thickness * w[i];
    const double psi = shell_energy_density(m, eps + zi * kappa, g ? &ge : nullptr, H ? &He : nullptr);
    if (!std::isfinite(psi)) return kInf;
    W += wi * psi;
    if (g) {
      g->head<3>() += wi * ge;
      g->tail<3>() += wi * zi * ge;
    }
    if (H) {
      H->topLeftCorner<3, 3>() += wi * He;
      H->topRightCorner<3, 3>() += wi * zi * He;
      H->bottomRightCorner<3, 3>() += wi * zi * zi * He;
    }
  }
  if (H) H->bottomLeftCorner<3, 3>() = H->topRightCorner<3, 3>().transpose();
  return W;
}

}  // namespace mgcloth::physics
