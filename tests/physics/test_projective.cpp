// The Projective Dynamics form: exact energies and gradients (finite differences), and the constant, symmetric,
// positive semi-definite PD matrix in place of the Hessian.
#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/projective.hpp>

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <random>

using namespace mgcloth;
using namespace mgcloth::physics;

namespace {

mesh::TriMesh small_cloth(bool unstructured) {
  mesh::RectangleSpec spec;
  spec.width = 0.2;
  spec.height = 0.15;
  spec.target_vertices = 40;
  spec.unstructured = unstructured;
  return mesh::make_rectangle(spec);
}

/// Positions x_i = A (u_i, 0) + c: every triangle has F = A's first two columns.
VecX linear_state(const mesh::TriMesh& m, const Mat3& A, const Vec3& c = Vec3::Zero()) {
  VecX x(3 * m.num_vertices());
  for (Index i = 0; i < m.num_vertices(); ++i) x.segment<3>(3 * i) = A * Vec3(m.u(0, i), m.u(1, i), 0.0) + c;
  return x;
}

/// A random deformed state: stretched, sheared, rotated, bent and noised, so that singular values are distinct,
/// away from the strain limits' kinks, and no triangle is collapsed.
VecX deformed_state(const mesh::TriMesh& m, std::uint64_t seed, double noise) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Mat3 A = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix() *
                 (Mat3() << 1.15, 0.2, 0.0, -0.1, 0.85, 0.0, 0.0, 0.0, 1.0).finished();
  VecX x(3 * m.num_vertices());
  for (Index i = 0; i < m.num_vertices(); ++i) {
    const Vec2 u = m.u.col(i);
    Vec3 p = A * Vec3(u.x(), u.y(), 0.3 * std::sin(8.0 * u.x()) * u.y());
    for (int k = 0; k < 3; ++k) p[k] += noise * n01(rng);
    x.segment<3>(3 * i) = p;
  }
  return x;
}

/// Binds a term to its own pattern and assembles its matrix at x.
Eigen::MatrixXd assemble(const Term& term, const VecX& x, bool project_psd = false) {
  std::vector<std::pair<Index, Index>> pairs;
  term.collect_pattern(pairs);
  linalg::BlockMatrix3 H(static_cast<Index>(x.size() / 3), pairs);
  const_cast<Term&>(term).bind(H);
  H.set_zero();
  term.add_hessian(x, H, project_psd);
  return Eigen::MatrixXd(H.to_sparse());
}

/// Central differences of the value against the gradient, along random directions and along single coordinates.
void check_gradient(const Term& term, const VecX& x, double rel_tol = 1e-6) {
  VecX g = VecX::Zero(x.size());
  term.add_gradient(x, g);
  const double h = 1e-6;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (int trial = 0; trial < 8; ++trial) {
    VecX d = VecX::Zero(x.size());
    if (trial < 5) {
      for (Index i = 0; i < d.size(); ++i) d[i] = n01(rng);
      d /= d.norm();
    } else {
      d[std::uniform_int_distribution<Index>(0, static_cast<Index>(x.size()) - 1)(rng)] = 1.0;
    }
    const double fd = (term.value(x + h * d) - term.value(x - h * d)) / (2 * h);
    const double an = g.dot(d);
    EXPECT_NEAR(fd, an, rel_tol * (std::abs(an) + g.norm()) + 1e-14) << term.name() << " gradient, trial " << trial;
  }
}

void expect_symmetric_psd(const Eigen::MatrixXd& L, const std::string& what) {
  EXPECT_LE((L - L.transpose()).norm(), 1e-14 * (1.0 + L.norm())) << what << " symmetry";
  const double min_eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(L).eigenvalues().minCoeff();
  EXPECT_GE(min_eig, -1e-12 * L.norm()) << what << " not PSD";
}

std::vector<geometry::Obstacle> sphere_at(const Vec3& c, double r) {
  geometry::Obstacle s;
  s.shape = std::make_shared<geometry::Sphere>(r);
  s.motion = std::make_shared<geometry::ConstantVelocityMotion>(geometry::Pose{Eigen::Quaterniond::Identity(), c},
                                                               Vec3::Zero(), Vec3::Zero());
  return {s};
}

Material limited(double lo, double hi) {
  Material m;
  m.pd_strain_min = lo;
  m.pd_strain_max = hi;
  return m;
}

}  // namespace

TEST(Projective, StrainProjectionIsIdempotentAndKeepsTheConstraintSet) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (auto [lo, hi] : {std::pair{1.0, 1.0}, std::pair{0.9, 1.1}, std::pair{0.0, 2.0}}) {
    for (int trial = 0; trial < 20; ++trial) {
      Mat32 F;
      for (int k = 0; k < 6; ++k) F(k % 3, k / 3) = n01(rng);
      const Mat32 P = project_strain(F, lo, hi);
      EXPECT_LE((project_strain(P, lo, hi) - P).norm(), 1e-13);
      const Vec2 sigma = Eigen::JacobiSVD<Mat32>(P).singularValues();
      EXPECT_GE(sigma.minCoeff(), lo - 1e-13);
      EXPECT_LE(sigma.maxCoeff(), hi + 1e-13);
      // P(F) is the closest point of the set: no other member (F's own SVD with other clamped values) is closer.
      const Eigen::JacobiSVD<Mat32> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
      const Mat32 other = svd.matrixU().leftCols<2>() * Vec2(hi, lo).asDiagonal() * svd.matrixV().transpose();
      EXPECT_LE((F - P).norm(), (F - other).norm() + 1e-13);
    }
  }
  // A rotation (orthonormal columns) is its own projection under the ARAP limits; so is F = 0 under [0, 2].
  const Mat32 R = Eigen::AngleAxisd(0.4, Vec3(1, -1, 2).normalized()).toRotationMatrix().leftCols<2>();
  EXPECT_LE((project_strain(R, 1.0, 1.0) - R).norm(), 1e-14);
  EXPECT_TRUE(project_strain(Mat32::Zero(), 0.0, 2.0).isZero());
  EXPECT_TRUE(project_strain(Mat32::Zero(), 1.0, 1.0).allFinite());
}

TEST(Projective, StrainMembraneGradientMatchesFiniteDifferences) {
  for (bool unstructured : {false, true})
    for (auto [lo, hi] : {std::pair{1.0, 1.0}, std::pair{0.95, 1.05}}) {
      const auto m = small_cloth(unstructured);
      PDStrainMembrane term(m, limited(lo, hi));
      for (std::uint64_t s = 1; s <= 3; ++s) {
        const VecX x = deformed_state(m, s, 0.005);
        check_gradient(term, x);
        EXPECT_GT(term.value(x), 0.0);
      }
    }
}

TEST(Projective, StrainMembraneRestAndStretchedEnergies) {
  const auto m = small_cloth(true);
  const Material mat;
  PDStrainMembrane arap(m, mat);
  EXPECT_DOUBLE_EQ(arap.weight(), 2.0 * mat.mu() * mat.thickness);
  // Rest state rotated and moved: every F is a rotation, so the energy and the gradient vanish.
  const Mat3 R = Eigen::AngleAxisd(1.1, Vec3(0.3, -1, 0.5).normalized()).toRotationMatrix();
  const VecX rest = linear_state(m, R, Vec3(1, 2, 3));
  EXPECT_NEAR(arap.value(rest), 0.0, 1e-20);
  VecX g = VecX::Zero(rest.size());
  arap.add_gradient(rest, g);
  EXPECT_LT(g.norm(), 1e-12);
  // Uniform stretch F = R diag(s1, s2): E = wA/2 Σ (σ − clamp(σ))², for the ARAP and for strain-limited sets.
  const double s1 = 1.2, s2 = 0.93, A = m.total_material_area(), w = arap.weight();
  const VecX stretched = linear_state(m, R * Vec3(s1, s2, 1.0).asDiagonal());
  const double expected = 0.5 * w * A * ((s1 - 1) * (s1 - 1) + (s2 - 1) * (s2 - 1));
  EXPECT_NEAR(arap.value(stretched), expected, 1e-12 * expected);
  PDStrainMembrane limits(m, limited(0.95, 1.1));
  const double expected_limited = 0.5 * w * A * ((s1 - 1.1) * (s1 - 1.1) + (s2 - 0.95) * (s2 - 0.95));
  EXPECT_NEAR(limits.value(stretched), expected_limited, 1e-12 * expected_limited);
  PDStrainMembrane loose(m, limited(0.9, 1.3));
  EXPECT_NEAR(loose.value(stretched), 0.0, 1e-20);
}

TEST(Projective, StrainMembraneMatchesStVKShearAtSmallStrain) {
  // Pure shear ε = [[0, γ], [γ, 0]]: StVK gives A t μ tr(ε²) = 2 A t μ γ² to leading order, and so does w = 2μt.
  const auto m = small_cloth(true);
  const Material mat;
  PDStrainMembrane pd(m, mat);
  StVKMembrane stvk(m, mat);
  const double gamma = 1e-4;
  const Mat3 F = (Mat3() << 1, gamma, 0, gamma, 1, 0, 0, 0, 1).finished();
  const VecX x = linear_state(m, F);
  const double expected = 2.0 * m.total_material_area() * mat.thickness * mat.mu() * gamma * gamma;
  EXPECT_NEAR(pd.value(x) / expected, 1.0, 1e-3);
  EXPECT_NEAR(stvk.value(x) / expected, 1.0, 1e-3);
}

TEST(Projective, StrainMembraneDegenerateTriangleIsFinite) {
  const auto m = small_cloth(false);
  PDStrainMembrane term(m, Material{});
  VecX x = VecX::Zero(3 * m.num_vertices());  // every triangle collapsed to a point
  VecX g = VecX::Zero(x.size());
  term.add_gradient(x, g);
  EXPECT_TRUE(std::isfinite(term.value(x)));
  EXPECT_TRUE(g.allFinite());
  x = linear_state(m, Vec3(1.0, 0.0, 1.0).asDiagonal());  // collapsed onto a line
  g.setZero();
  term.add_gradient(x, g);
  EXPECT_TRUE(std::isfinite(term.value(x)));
  EXPECT_TRUE(g.allFinite());
  EXPECT_THROW(PDStrainMembrane(m, limited(1.1, 1.2)), InputError);
  EXPECT_THROW(PDStrainMembrane(m, limited(0.9, 0.95)), InputError);
}

TEST(Projective, StrainMatrixIsTheConstantGradientOperatorProduct) {
  // For a linear displacement field v_i = M u_i every triangle has F(v) = M, so vᵀ L v = w A |M|²_F when
  // L = Σ_t w A_t GᵀG ⊗ I₃.
  const auto m = small_cloth(true);
  PDStrainMembrane term(m, Material{});
  const Eigen::MatrixXd L = assemble(term, deformed_state(m, 1, 0.005));
  const Mat3 M = (Mat3() << 0.3, -1.2, 0, 0.7, 0.1, 0, 2.0, -0.4, 0).finished();
  const VecX v = linear_state(m, M);
  const double expected = term.weight() * m.total_material_area() * M.leftCols<2>().squaredNorm();
  EXPECT_NEAR(v.dot(L * v), expected, 1e-12 * expected);
}

TEST(Projective, MatrixIsSymmetricPsdAndIndependentOfTheState) {
  const auto m = small_cloth(true);
  const auto topo = mesh::build_topology(m);
  const Index n = m.num_vertices();
  Objective obj(n);
  obj.add(std::make_unique<PDStrainMembrane>(m, limited(0.95, 1.05)));
  obj.add(std::make_unique<QuadraticBending>(m, topo, Material{}));
  ContactParams params;
  params.thickness = 0.01;
  auto& contact = obj.add(std::make_unique<PDObstacleContact>(VecX::Constant(n, 1e-3), sphere_at(Vec3(0.1, 0.07, -0.1), 0.12), params, 0.01));
  obj.finalize();
  contact.set_active(as_stacked(m.x));
  ASSERT_GT(contact.num_active(), 0);
  ASSERT_LT(contact.num_active(), n);
  linalg::BlockMatrix3 H1, H2, H3;
  obj.hessian(deformed_state(m, 1, 0.01), H1, false);
  obj.hessian(deformed_state(m, 2, 0.03) * 1.3, H2, false);
  const Eigen::MatrixXd L1(H1.to_sparse()), L2(H2.to_sparse());
  EXPECT_EQ((L1 - L2).norm(), 0.0);
  expect_symmetric_psd(L1, "PD matrix");
  // The PD terms ignore projection; QuadraticBending's projection changes its PSD blocks only by round-off.
  obj.hessian(deformed_state(m, 3, 0.02), H3, true);
  EXPECT_LE((Eigen::MatrixXd(H3.to_sparse()) - L1).norm(), 1e-13 * L1.norm());
  for (const auto& t : obj.terms()) {
    const VecX x = deformed_state(m, 4, 0.01);
    expect_symmetric_psd(assemble(*t, x), t->name());
  }
}

TEST(Projective, ContactGradientMatchesFiniteDifferences) {
  auto m = small_cloth(false);
  const Index n = m.num_vertices();
  ContactParams params;
  params.thickness = 0.02;
  auto obstacles = sphere_at(Vec3(0.1, 0.07, 0.02), 0.1);
  auto box = sphere_at(Vec3(0.02, 0.02, -0.03), 0.05);
  box[0].shape = std::make_shared<geometry::Box>(Vec3(0.05, 0.05, 0.05));
  obstacles.push_back(box[0]);
  PDObstacleContact contact(VecX::LinSpaced(n, 1e-3, 2e-3), obstacles, params, 0.005);
  VecX x = as_stacked(m.x);
  x.array() += 0.001;  // off the kink at φ = d
  contact.set_active(x);
  check_gradient(contact, x);
  EXPECT_GT(contact.value(x), 0.0);
}

TEST(Projective, ContactActiveSetFixesTheMatrixForTheStep) {
  // Three vertices above a sphere of radius 1: deep in the layer, just outside it (inside the margin), far away.
  const double d = 0.01, margin = 0.02;
  ContactParams params;
  params.thickness = d;
  params.stiffness = 1e4;
  const VecX area = VecX::Constant(3, 0.5);
  Objective obj(3);
  auto& c = obj.add(std::make_unique<PDObstacleContact>(area, sphere_at(Vec3::Zero(), 1.0), params, margin));
  obj.finalize();
  EXPECT_EQ(pd_matrix_version(obj), 0u);
  const double w = 1e4 * 0.5;
  VecX y(9);
  y << 0, 0, 1.004, 0, 1.02, 0, 2.0, 0, 0;
  c.set_active(y);
  EXPECT_TRUE(c.active(0, 0));
  EXPECT_TRUE(c.active(1, 0));
  EXPECT_FALSE(c.active(2, 0));
  EXPECT_EQ(c.num_active(), 2);
  EXPECT_EQ(pd_matrix_version(obj), 1u);
  c.set_active(y);  // same set: no new version, a solver keeps its factorization
  EXPECT_EQ(c.active_set_version(), 1u);

  // At y: vertex 0 feels the layer (energy w/2 gap², gradient −w gap n), vertex 1 none; both add w I to the matrix.
  const double gap = d - 0.004;
  EXPECT_NEAR(c.value(y), 0.5 * w * gap * gap, 1e-15);
  VecX g;
  obj.gradient(y, g);
  EXPECT_NEAR(g[2], -w * gap, 1e-12);
  EXPECT_TRUE(g.tail<6>().isZero());
  linalg::BlockMatrix3 H;
  obj.hessian(y, H);
  const Eigen::MatrixXd L(H.to_sparse());
  Eigen::MatrixXd expected = Eigen::MatrixXd::Zero(9, 9);
  expected.topLeftCorner<6, 6>() = w * Eigen::MatrixXd::Identity(6, 6);
  EXPECT_EQ((L - expected).norm(), 0.0);
  EXPECT_DOUBLE_EQ(c.normal_force(0, gap), w * gap);

  // The inactive vertex entering the layer during the step: exact energy and force, no matrix contribution.
  VecX x = y;
  x.segment<3>(6) = Vec3(1.005, 0, 0);
  obj.gradient(x, g);
  EXPECT_NEAR(g[6], -w * (d - 0.005), 1e-12);
  obj.hessian(x, H);
  EXPECT_EQ((Eigen::MatrixXd(H.to_sparse()) - expected).norm(), 0.0);

  // A new prediction that changes the set bumps the version.
  c.set_active(x);
  EXPECT_TRUE(c.active(2, 0));
  EXPECT_EQ(pd_matrix_version(obj), 2u);
  EXPECT_THROW(PDObstacleContact(area, sphere_at(Vec3::Zero(), 1.0), params, -1.0), InputError);
}
