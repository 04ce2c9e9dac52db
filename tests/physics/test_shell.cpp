// Subdivision Kirchhoff-Love shell (Kopaničáková 2019, §3, §5.2): derivatives, invariants, materials.
#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/limit_surface.hpp>
#include <mgcloth/physics/shell.hpp>
#include <mgcloth/physics/shell_kinematics.hpp>

#include "term_checks.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

using namespace mgcloth;
using namespace mgcloth::physics;

namespace {

/// Five quads around a point of valence 5 with an open boundary: irregular Bfr patches and boundary rules.
mesh::QuadMesh pentagon_fan() {
  mesh::QuadMesh m;
  m.x.setZero(3, 11);
  m.u.setZero(2, 11);
  for (int i = 0; i < 5; ++i) {
    const double a = 2.0 * M_PI * i / 5.0, b = a + M_PI / 5.0;
    m.u.col(1 + i) = 0.2 * Vec2(std::cos(a), std::sin(a));
    m.u.col(6 + i) = 0.28 * Vec2(std::cos(b), std::sin(b));
  }
  m.x.topRows(2) = m.u;
  for (int i = 0; i < 5; ++i) m.quads.push_back({0, 1 + i, 6 + i, 1 + (i + 1) % 5});
  return m;
}

/// A deformed state of the control points: stretched, sheared, bent and noised, then rigidly moved.
VecX deformed(const mesh::QuadMesh& m, std::uint64_t seed, double noise, double strain = 1.0) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Mat3 A = Eigen::AngleAxisd(0.4, Vec3(1, 2, 3).normalized()).toRotationMatrix() *
                 (Mat3() << 1.0 + 0.05 * strain, 0.03 * strain, 0.0, -0.02 * strain, 1.0 - 0.03 * strain, 0.0, 0.0, 0.0, 1.0)
                     .finished();
  VecX x(3 * m.num_vertices());
  for (Index i = 0; i < m.num_vertices(); ++i) {
    const Vec3 r = m.x.col(i);
    Vec3 p = r + strain * Vec3(0, 0, 0.3 * r.x() * r.x() - 0.2 * r.x() * r.y());
    p = A * p;
    for (int k = 0; k < 3; ++k) p[k] += noise * n01(rng);
    x.segment<3>(3 * i) = p;
  }
  return x;
}

ShellMaterial isotropic() {
  ShellMaterial m;
  m.young = 2.0e6;
  m.poisson = 0.3;
  m.thickness = 1e-3;
  m.density = 0.3;
  m.warp_angle_deg = 25.0;
  return m;
}

TEST(Shell, FundamentalFormDerivativesMatchFiniteDifferences) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  Vec18 z;
  for (int i = 0; i < 18; ++i) z[i] = n01(rng);
  Eigen::Matrix<double, 6, 1> s, sp, sm, lambda;
  ShellJacobian J, Jp, Jm;
  ASSERT_TRUE(shell_fundamental_forms(z, s, &J));
  for (int i = 0; i < 6; ++i) lambda[i] = n01(rng);
  Mat18 H = Mat18::Zero();
  add_fundamental_form_curvature(z, lambda, H);
  const double h = 1e-6;
  for (int k = 0; k < 18; ++k) {
    Vec18 zp = z, zm = z;
    zp[k] += h;
    zm[k] -= h;
    shell_fundamental_forms(zp, sp, &Jp);
    shell_fundamental_forms(zm, sm, &Jm);
    EXPECT_LE(((sp - sm) / (2 * h) - J.col(k)).norm(), 1e-7 * (1 + J.norm())) << "d s / d z" << k;
    const Vec18 fd = ((Jp - Jm).transpose() * lambda) / (2 * h);
    EXPECT_LE((fd - H.col(k)).norm(), 1e-6 * (1 + H.norm())) << "second derivative column " << k;
  }
  EXPECT_LE((H - H.transpose()).norm(), 1e-12 * H.norm());
}

TEST(Shell, StVKEnergyDerivativesMatchFiniteDifferences) {
  const mesh::LimitSurface surface(mesh::make_quad_rectangle(0.3, 0.2, 3, 2));
  ShellTerm term(surface, isotropic(), Vec3(0, 0, -9.81));
  term.set_inertia(0.01, deformed(surface.mesh(), 9, 0.002));
  for (std::uint64_t seed = 1; seed <= 3; ++seed) check_term(term, deformed(surface.mesh(), seed, 0.003), 1e-5);
}

TEST(Shell, WovenEnergyDerivativesMatchFiniteDifferences) {
  const mesh::LimitSurface surface(mesh::make_quad_rectangle(0.3, 0.2, 3, 2));
  ShellTerm term(surface, denim_material(), Vec3(0, 0, -9.81));
  term.set_inertia(1.0, deformed(surface.mesh(), 9, 0.002));
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const VecX x = deformed(surface.mesh(), seed, 2e-5, 0.02);  // within the fit's stable range (< 1% strain)
    ASSERT_TRUE(std::isfinite(term.value(x)));
    check_term(term, x, 1e-4);
  }
}

TEST(Shell, ExtraordinaryAndBoundaryPatchDerivativesMatchFiniteDifferences) {
  const mesh::LimitSurface surface(pentagon_fan());
  EXPECT_FALSE(surface.is_regular(0));
  for (const ShellMaterial& m : {isotropic(), denim_material()}) {
    ShellTerm term(surface, m, Vec3(0, 0, -9.81));
    const VecX x = deformed(surface.mesh(), 4, 2e-5, 0.02);
    ASSERT_TRUE(std::isfinite(term.value(x)));
    check_term(term, x, 1e-4);
  }
}

// A rigid motion of the reference surface leaves every strain and curvature change zero.
TEST(Shell, RigidMotionHasZeroElasticEnergy) {
  for (const mesh::QuadMesh& m : {mesh::make_quad_rectangle(0.3, 0.2, 3, 2), pentagon_fan()}) {
    mesh::QuadMesh curved = m;
    for (Index i = 0; i < curved.num_vertices(); ++i) curved.x(2, i) = 0.4 * curved.x(0, i) * curved.x(0, i) + 0.1 * curved.x(1, i);
    const mesh::LimitSurface surface(curved);
    for (const ShellMaterial& mat : {isotropic(), denim_material()}) {
      ShellTerm term(surface, mat, Vec3::Zero());
      term.set_parts(true, false, false);
      const Mat3 R = Eigen::AngleAxisd(1.1, Vec3(0.3, -1, 0.5).normalized()).toRotationMatrix();
      VecX x(3 * curved.num_vertices());
      for (Index i = 0; i < curved.num_vertices(); ++i) x.segment<3>(3 * i) = R * curved.x.col(i) + Vec3(1, -2, 0.5);
      VecX stretched = x;
      stretched *= 1.002;
      const double e_stretch = term.value(stretched);
      EXPECT_GT(e_stretch, 0.0);
      EXPECT_LE(std::abs(term.value(x)), 1e-12 * e_stretch);
      VecX g = VecX::Zero(x.size());
      term.add_gradient(x, g);
      VecX gs = VecX::Zero(x.size());
      term.add_gradient(stretched, gs);
      EXPECT_LE(g.norm(), 1e-8 * gs.norm());
    }
  }
}

// The limit surface of a flat grid with one ghost ring is exactly the real region: area, mass and the consistent
// mass matrix reproduce ρ A; gravity sums to m g.
TEST(Shell, MassAndGravityIntegrateToTheRealRegion) {
  const mesh::LimitSurface surface(mesh::make_quad_rectangle(1.0, 0.5, 4, 2));
  ShellMaterial mat = isotropic();
  ShellTerm term(surface, mat, Vec3(0, 0, -9.81));
  EXPECT_NEAR(term.area(), 0.5, 1e-13);
  const Index n = term.num_points();
  VecX ones = VecX::Zero(3 * n);
  for (Index i = 0; i < n; ++i) ones[3 * i] = 1.0;
  EXPECT_NEAR(ones.dot(term.mass_times(ones)), mat.density * 0.5, 1e-13);
  term.set_parts(false, false, true);
  VecX g = VecX::Zero(3 * n);
  term.add_gradient(as_stacked(surface.mesh().x), g);
  Vec3 total = Vec3::Zero();
  for (Index i = 0; i < n; ++i) total += g.segment<3>(3 * i);
  EXPECT_NEAR(total.z(), 9.81 * mat.density * 0.5, 1e-12);
  EXPECT_NEAR(total.head<2>().norm(), 0.0, 1e-14);
}

TEST(Shell, LimitStencilsArePartitionsOfUnityAndReproduceLinearFields) {
  for (const mesh::QuadMesh& m : {mesh::make_quad_rectangle(1.0, 0.5, 4, 2), pentagon_fan()}) {
    const mesh::LimitSurface surface(m);
    mesh::LimitStencil st;
    for (Index f : surface.real_faces())
      for (double s : {0.0, 0.3, 1.0})
        for (double t : {0.0, 0.7}) {
          surface.stencil(f, s, t, st);
          EXPECT_NEAR(st.w.col(0).sum(), 1.0, 1e-12);
          for (int d = 1; d < 6; ++d) EXPECT_NEAR(st.w.col(d).sum(), 0.0, 1e-10);
          if (m.num_vertices() != 11) {
            // Uniform grid: the limit map is the affine grid map, so x = (u, v, 0) and x,st = 0.
            const Vec3 x = st.apply(surface.mesh().x, 0);
            EXPECT_NEAR((x.head<2>() - st.apply(surface.mesh().u, 0)).norm(), 0.0, 1e-13);
            EXPECT_NEAR(st.apply(surface.mesh().x, 4).norm(), 0.0, 1e-12);
          }
        }
  }
}

// Identity responses and the plane-stress constants make the woven model St. Venant-Kirchhoff exactly.
TEST(ShellMaterial, WovenWithLinearResponsesIsStVK) {
  ShellMaterial s = isotropic();
  ShellMaterial w = s;
  w.model = ShellMaterial::Model::woven;
  const double c = s.young / (1.0 - s.poisson * s.poisson);
  w.k = {c, s.poisson * c, c, s.young / (1.0 + s.poisson)};
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01(0.0, 0.05);
  for (int trial = 0; trial < 10; ++trial) {
    const Vec3 e(n01(rng), n01(rng), n01(rng));
    Vec3 gs, gw;
    Mat3 Hs, Hw;
    const double ps = shell_energy_density(s, e, &gs, &Hs), pw = shell_energy_density(w, e, &gw, &Hw);
    EXPECT_NEAR(ps, pw, 1e-12 * ps);
    EXPECT_LE((gs - gw).norm(), 1e-12 * gs.norm());
    EXPECT_LE((Hs - Hw).norm(), 1e-12 * Hs.norm());
  }
}

// Denim at small strain: ψ → k1/2 Ẽ11² + k2 Ẽ11 Ẽ22 + k3/2 Ẽ22² + k4 Ẽ12², the relative deviation shrinking like
// the strain squared (the responses' second-order terms are in u = Ẽ²).
TEST(ShellMaterial, DenimIsLinearOrthotropicAtSmallStrain) {
  const ShellMaterial d = denim_material();
  const Vec3 dir(1.0, -0.6, 0.4);
  double previous = 0.0;
  for (double scale : {1e-3, 1e-4, 1e-5}) {
    const Vec3 e = scale * dir;
    const double linear = 0.5 * d.k[0] * e[0] * e[0] + d.k[1] * e[0] * e[1] + 0.5 * d.k[2] * e[1] * e[1] + d.k[3] * e[2] * e[2];
    const double rel = std::abs(shell_energy_density(d, e, nullptr, nullptr) - linear) / linear;
    if (previous > 0.0) {
      EXPECT_NEAR(previous / rel, 100.0, 5.0) << "at strain " << scale;
    }
    previous = rel;
    if (scale <= 1e-5) {
      EXPECT_LT(rel, 1e-6);
    }
  }
  Vec3 g;
  Mat3 H;
  shell_energy_density(d, Vec3::Zero(), &g, &H);
  EXPECT_NEAR(H(0, 0), d.k[0], 1e-6 * d.k[0]);
  EXPECT_NEAR(H(0, 1), d.k[1], 1e-6 * d.k[0]);
  EXPECT_NEAR(H(1, 1), d.k[2], 1e-6 * d.k[0]);
  EXPECT_NEAR(H(2, 2), 2.0 * d.k[3], 1e-6 * d.k[0]);
}

// The denim fit as published (energy floor 0) is positive at small strain, negative at moderate opposite strains
// (the linear coupling k2 outgrows the softened φ1, φ3) and unbounded below where φ3 turns over (Ẽ22² > 0.102).
// With the default floor F (a tenth of the small-strain energy) it is the fit wherever the fit is above 2F, and
// a C¹ blend that never goes below F elsewhere.
TEST(ShellMaterial, DenimFitPathologiesAndTheEnergyFloor) {
  ShellMaterial published = denim_material();
  published.woven_energy_floor = 0.0;
  EXPECT_LT(shell_energy_density(published, Vec3(0.1, -0.1, 0.0), nullptr, nullptr), -1e4);
  EXPECT_LT(shell_energy_density(published, Vec3(0.0, 0.6, 0.0), nullptr, nullptr), -1e8);
  const ShellMaterial d = denim_material();
  Mat3 C0;
  C0 << d.k[0], d.k[1], 0.0, d.k[1], d.k[2], 0.0, 0.0, 0.0, 2.0 * d.k[3];  // ∂²ψ/∂Ẽ² at 0 (φ_j'(0) = 1)
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  int fit = 0, floored = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const double scale = trial % 4 == 0 ? 0.003 : 0.3;
    const Vec3 e(scale * uni(rng), scale * uni(rng), scale * uni(rng));
    const double lin = 0.5 * e.dot(C0 * e);
    const double psi = shell_energy_density(d, e, nullptr, nullptr);
    const double raw = shell_energy_density(published, e, nullptr, nullptr);
    EXPECT_GE(psi, 0.1 * lin * (1 - 1e-12)) << e.transpose();
    if (raw >= 0.2 * lin) {
      EXPECT_EQ(psi, raw);
      ++fit;
    } else {
      EXPECT_LE(psi, 0.2 * lin * (1 + 1e-12));  // F (1 + e^(u-2)) between the floor and the junction
      ++floored;
    }
    if (scale < 0.01) {
      EXPECT_EQ(psi, raw) << "small strains keep the published fit: " << e.transpose();
    }
  }
  EXPECT_GT(fit, 1000);
  EXPECT_GT(floored, 50);
  // The blend's derivatives, by central differences, at states below the junction.
  for (const Vec3& e : {Vec3(0.1, -0.1, 0.02), Vec3(0.05, -0.08, 0.0), Vec3(0.0, 0.6, 0.1)}) {
    Vec3 g;
    Mat3 H;
    shell_energy_density(d, e, &g, &H);
    const double h = 1e-7;
    for (int i = 0; i < 3; ++i) {
      Vec3 ep = e, em = e, gp, gm;
      ep[i] += h;
      em[i] -= h;
      const double fd = (shell_energy_density(d, ep, &gp, nullptr) - shell_energy_density(d, em, &gm, nullptr)) / (2 * h);
      EXPECT_NEAR(fd, g[i], 1e-5 * (g.norm() + 1.0)) << e.transpose() << " component " << i;
      EXPECT_LE(((gp - gm) / (2 * h) - H.col(i)).norm(), 1e-4 * (H.norm() + 1.0)) << e.transpose() << " column " << i;
    }
  }
}

TEST(ShellMaterial, ThroughThicknessIntegrationOfStVKSplitsMembraneAndBending) {
  const ShellMaterial m = isotropic();
  const Vec3 eps(1e-3, -2e-4, 3e-4), kappa(2.0, 0.5, -0.7);
  const double W = shell_area_density(m, eps, kappa, nullptr, nullptr);
  const double t = m.thickness;
  const double expected = t * shell_energy_density(m, eps, nullptr, nullptr) +
                          t * t * t / 12.0 * shell_energy_density(m, kappa, nullptr, nullptr);
  EXPECT_NEAR(W, expected, 1e-12 * expected);
}

TEST(ShellMaterial, BadParametersAreInputErrors) {
  ShellMaterial m = isotropic();
  m.thickness = -1.0;
  EXPECT_THROW(m.validate(), InputError);
  m = isotropic();
  m.poisson = 0.5;
  EXPECT_THROW(m.validate(), InputError);
  m = denim_material();
  m.phi[0].alpha[1] = 0.0;
  EXPECT_THROW(m.validate(), InputError);
  m = denim_material();
  m.k[1] = 1e8;
  EXPECT_THROW(m.validate(), InputError);
  m = denim_material();
  m.woven_energy_floor = 1.0;
  EXPECT_THROW(m.validate(), InputError);
  m = isotropic();
  m.young = std::nan("");
  EXPECT_THROW(m.validate(), InputError);
}

}  // namespace
