// Finite-difference, symmetry and PSD checks for every term of the incremental potential.
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/attachment.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/contact.hpp>
#include <mgcloth/physics/element_kernels.hpp>
#include <mgcloth/physics/inertia.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/physics/seam.hpp>

#include "term_checks.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <unsupported/Eigen/AutoDiff>
#include <array>
#include <cmath>
#include <cstring>
#include <random>

using namespace mgcloth;
using namespace mgcloth::physics;

namespace {

struct Fixture {
  mesh::TriMesh mesh;
  mesh::Topology topo;
  Material material;
};

Fixture small_cloth(bool unstructured) {
  Fixture f;
  mesh::RectangleSpec spec;
  spec.width = 0.2;
  spec.height = 0.15;
  spec.target_vertices = 40;
  spec.unstructured = unstructured;
  f.mesh = mesh::make_rectangle(spec);
  f.topo = mesh::build_topology(f.mesh);
  return f;
}

/// A random deformed state: rest positions stretched, sheared, rotated and noised, with real bending.
VecX deformed_state(const mesh::TriMesh& m, std::uint64_t seed, double noise) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Eigen::Matrix3d A = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix() *
                            (Eigen::Matrix3d() << 1.1, 0.2, 0.0, -0.1, 0.9, 0.0, 0.0, 0.0, 1.0).finished();
  VecX x(3 * m.num_vertices());
  for (Index i = 0; i < m.num_vertices(); ++i) {
    const Vec2 u = m.u.col(i);
    Vec3 p(u.x(), u.y(), 0.3 * std::sin(8.0 * u.x()) * u.y());
    p = A * p;
    for (int k = 0; k < 3; ++k) p[k] += noise * n01(rng);
    x.segment<3>(3 * i) = p;
  }
  return x;
}

}  // namespace

TEST(Terms, StVKMembrane) {
  for (bool unstructured : {false, true}) {
    auto f = small_cloth(unstructured);
    StVKMembrane term(f.mesh, f.material);
    for (std::uint64_t s = 1; s <= 3; ++s) check_term(term, deformed_state(f.mesh, s, 0.01));
  }
}

TEST(Terms, StVKIndefiniteUnderCompression) {
  // The unprojected Hessian of a compressed triangle must have a negative eigenvalue (buckling), otherwise the
  // projection would have nothing to do and the test of projection would be vacuous.
  auto f = small_cloth(false);
  StVKMembrane term(f.mesh, f.material);
  VecX x = as_stacked(f.mesh.x) * 0.9;
  std::vector<std::pair<Index, Index>> pairs;
  term.collect_pattern(pairs);
  linalg::BlockMatrix3 H(f.mesh.num_vertices(), pairs);
  term.bind(H);
  term.add_hessian(x, H, false);
  const double min_eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(H.to_sparse())).eigenvalues().minCoeff();
  EXPECT_LT(min_eig, 0.0);
}

TEST(Terms, StVKRestIsStressFree) {
  auto f = small_cloth(true);
  StVKMembrane term(f.mesh, f.material);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(1.1, Vec3(0.3, -1, 0.5).normalized()).toRotationMatrix();
  VecX x(3 * f.mesh.num_vertices());
  for (Index i = 0; i < f.mesh.num_vertices(); ++i) x.segment<3>(3 * i) = R * Vec3(f.mesh.u(0, i), f.mesh.u(1, i), 0) + Vec3(1, 2, 3);
  EXPECT_NEAR(term.value(x), 0.0, 1e-20);
  VecX g = VecX::Zero(x.size());
  term.add_gradient(x, g);
  EXPECT_LT(g.norm(), 1e-10);
}

TEST(Terms, StVKUniaxialStretchMatchesContinuum) {
  // Uniform stretch by s along u: E = (s²−1)/2, W = A t (μ E² + λ/2 E²) exactly for any triangulation.
  auto f = small_cloth(true);
  StVKMembrane term(f.mesh, f.material);
  const double s = 1.1, e = 0.5 * (s * s - 1.0);
  VecX x(3 * f.mesh.num_vertices());
  for (Index i = 0; i < f.mesh.num_vertices(); ++i) x.segment<3>(3 * i) = Vec3(s * f.mesh.u(0, i), f.mesh.u(1, i), 0);
  const double expected = f.mesh.total_material_area() * f.material.thickness *
                          (f.material.mu() * e * e + 0.5 * f.material.lambda_plane_stress() * e * e);
  EXPECT_NEAR(term.value(x), expected, 1e-10 * expected);
}

TEST(Terms, MassSpringMembrane) {
  auto f = small_cloth(true);
  MassSpringMembrane term(f.mesh, f.topo, f.material);
  for (std::uint64_t s = 1; s <= 3; ++s) check_term(term, deformed_state(f.mesh, s, 0.01));
}

TEST(Terms, HingeBending) {
  for (bool unstructured : {false, true}) {
    auto f = small_cloth(unstructured);
    HingeBending term(f.mesh, f.topo, f.material);
    for (std::uint64_t s = 1; s <= 3; ++s) check_term(term, deformed_state(f.mesh, s, 0.01), 1e-5);
  }
}

TEST(Terms, DihedralAngleKnownValues) {
  // Flat hinge: zero; folding the wing x2 up by 90 degrees about the edge gives |θ| = π/2.
  Vec12 x;
  x << 0, 0, 0, 1, 0, 0, 0.5, 1, 0, 0.5, -1, 0;
  EXPECT_NEAR(dihedral_angle(x), 0.0, 1e-15);
  x.segment<3>(6) = Vec3(0.5, 0, 1);
  EXPECT_NEAR(std::abs(dihedral_angle(x)), M_PI / 2, 1e-12);
}

// The hand-derived ∇²θ against two references it shares no code with: forward-mode automatic differentiation of the
// gradient, and central differences of it, on hinges folded from nearly flat to nearly shut, with skewed wings.
TEST(Terms, DihedralAngleHessianMatchesAutoDiffAndDifferences) {
  using AD = Eigen::AutoDiffScalar<Vec12>;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int checked = 0;
  for (double fold : {0.01, 0.5, 1.5, 2.5, 3.0}) {
    for (int trial = 0; trial < 4; ++trial) {
      // Edge along x, wing x2 in the xy-plane, wing x3 rotated by `fold`, all perturbed and moved off the origin.
      Vec12 x;
      x << 0, 0, 0, 1.3, 0, 0, 0.4, 0.9, 0, 0.7, -0.8 * std::cos(fold), 0.8 * std::sin(fold);
      for (int i = 0; i < 12; ++i) x[i] += 0.15 * u(rng) + (i % 3 == 2 ? 0.3 : -0.2);
      const Mat12 H = dihedral_angle_hessian(x);
      std::array<AD, 12> xa, ga;
      for (int i = 0; i < 12; ++i) xa[i] = AD(x[i], 12, i);
      hd::dihedral_angle_gradient(xa.data(), ga.data());
      Mat12 Had;
      for (int i = 0; i < 12; ++i) Had.row(i) = ga[i].derivatives().transpose();
      EXPECT_LE((H - Had).norm(), 1e-11 * Had.norm()) << "fold " << fold;
      const double h = 1e-6;
      Mat12 Hfd;
      for (int j = 0; j < 12; ++j) {
        Vec12 xp = x, xm = x, gp, gm;
        xp[j] += h;
        xm[j] -= h;
        hd::dihedral_angle_gradient(xp.data(), gp.data());
        hd::dihedral_angle_gradient(xm.data(), gm.data());
        Hfd.col(j) = (gp - gm) / (2 * h);
      }
      EXPECT_LE((H - Hfd).norm(), 1e-6 * Hfd.norm()) << "fold " << fold;
      // θ is invariant under translation: each row's blocks sum to zero.
      for (int i = 0; i < 12; ++i)
        for (int c = 0; c < 3; ++c)
          EXPECT_NEAR(H(i, c) + H(i, 3 + c) + H(i, 6 + c) + H(i, 9 + c), 0.0, 1e-10 * H.norm());
      ++checked;
    }
  }
  EXPECT_EQ(checked, 20);
}

TEST(Terms, QuadraticBending) {
  auto f = small_cloth(true);
  QuadraticBending term(f.mesh, f.topo, f.material);
  for (std::uint64_t s = 1; s <= 2; ++s) check_term(term, deformed_state(f.mesh, s, 0.01));
  // Any planar configuration has zero bending energy (the cotangent weights reproduce linear functions).
  VecX flat(3 * f.mesh.num_vertices());
  for (Index i = 0; i < f.mesh.num_vertices(); ++i) flat.segment<3>(3 * i) = Vec3(f.mesh.u(0, i), 2.0 * f.mesh.u(1, i), 0.5);
  EXPECT_NEAR(term.value(flat), 0.0, 1e-18);
}

TEST(Terms, BendingModelsAgreeOnCylinder) {
  // Wrap a quasi-uniform sheet on a cylinder of curvature κ: both models should give about k_b/2 κ² A
  // (exactly on regular grids; the Delaunay meshes' edge-direction mix puts them about 15% above).
  mesh::RectangleSpec spec;
  spec.target_vertices = 3000;
  spec.unstructured = true;
  spec.width = 0.5;
  spec.height = 0.5;
  auto m = mesh::make_rectangle(spec);
  auto topo = mesh::build_topology(m);
  Material mat;
  HingeBending hinge(m, topo, mat);
  QuadraticBending quad(m, topo, mat);
  const double kappa = 2.0;
  VecX x(3 * m.num_vertices());
  for (Index i = 0; i < m.num_vertices(); ++i) {
    const double a = kappa * m.u(0, i);
    x.segment<3>(3 * i) = Vec3(std::sin(a) / kappa, m.u(1, i), (1 - std::cos(a)) / kappa);
  }
  const double continuum = 0.5 * mat.bending_stiffness * kappa * kappa * m.total_material_area();
  EXPECT_NEAR(hinge.value(x) / continuum, 1.1, 0.1);
  EXPECT_NEAR(quad.value(x) / continuum, 1.1, 0.1);
  EXPECT_NEAR(hinge.value(x) / quad.value(x), 1.0, 0.05);
}

TEST(Terms, InertiaGravityAttachment) {
  auto f = small_cloth(false);
  const Index n = f.mesh.num_vertices();
  VecX mass = VecX::LinSpaced(n, 0.01, 0.02);
  const VecX x = deformed_state(f.mesh, 3, 0.01);
  InertiaTerm inertia(mass);
  inertia.set_prediction(deformed_state(f.mesh, 4, 0.02), 1.0 / 30.0);
  check_term(inertia, x);
  GravityTerm gravity(mass, Vec3(0, 0, -9.81));
  check_term(gravity, x);
  AttachmentTerm pins({0, 3, 3}, {1e3, 2e3, 5e2}, n);
  pins.set_targets({Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(0, 1, 0)});
  check_term(pins, x);
}

TEST(Terms, SeamSprings) {
  auto f = small_cloth(true);
  const Index n = f.mesh.num_vertices();
  const VecX x = deformed_state(f.mesh, 5, 0.01);
  SeamTerm seam({{0, 5, 9}, {2, 7}}, 3e3, n);
  EXPECT_EQ(seam.num_elements(), 3);
  check_term(seam, x);
  // Closed seams cost nothing; an open one pulls its two sides together.
  VecX y = x;
  for (Index v : {5, 9}) y.segment<3>(3 * v) = y.segment<3>(0);
  y.segment<3>(21) = y.segment<3>(6);
  EXPECT_NEAR(seam.value(y), 0.0, 1e-20);
  VecX g = VecX::Zero(3 * n);
  seam.add_gradient(x, g);
  EXPECT_NEAR(g.segment<3>(6).dot(x.segment<3>(6) - x.segment<3>(21)), 3e3 * (x.segment<3>(6) - x.segment<3>(21)).squaredNorm(), 1e-9);
  EXPECT_THROW(SeamTerm({{1, 1}}, 1.0, n), mgcloth::InputError);
  EXPECT_THROW(SeamTerm({{0, 1}}, -1.0, n), mgcloth::InputError);
}

TEST(Terms, ObstacleContact) {
  auto f = small_cloth(false);
  const Index n = f.mesh.num_vertices();
  std::vector<geometry::Obstacle> obstacles;
  geometry::Obstacle sphere;
  sphere.shape = std::make_shared<geometry::Sphere>(0.1);
  sphere.motion = std::make_shared<geometry::ConstantVelocityMotion>(geometry::Pose{Eigen::Quaterniond::Identity(), Vec3(0.1, 0.07, 0.02)}, Vec3::Zero(), Vec3::Zero());
  obstacles.push_back(sphere);
  geometry::Obstacle box;
  box.shape = std::make_shared<geometry::Box>(Vec3(0.05, 0.05, 0.05));
  box.motion = std::make_shared<geometry::ConstantVelocityMotion>(geometry::Pose{Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Vec3::UnitZ())), Vec3(0.02, 0.02, -0.03)}, Vec3::Zero(), Vec3::Zero());
  obstacles.push_back(box);
  ContactParams params;
  params.thickness = 0.02;
  ObstacleContact contact(VecX::Constant(n, 1e-3), obstacles, params);
  VecX x = as_stacked(f.mesh.x);
  x.array() += 0.001;  // keep vertices off the penalty's C¹ kink at φ = d
  check_term(contact, x, 1e-5);
  EXPECT_GT(contact.value(x), 0.0);
}

TEST(Terms, ContactPsdHessianIsTheProjectionOfTheExactOne) {
  // One convex obstacle per vertex: ∇φ is an eigenvector of ∇²φ with eigenvalue 0, so the closed form
  // 2(k/d)(d − φ)∇φ∇φᵀ must equal the eigenvalue-clamped exact Hessian (for a sphere, a capsule and a rotated box).
  std::vector<std::shared_ptr<const geometry::Shape>> shapes{std::make_shared<geometry::Sphere>(0.1),
                                                             std::make_shared<geometry::Capsule>(0.05, 0.1),
                                                             std::make_shared<geometry::Box>(Vec3(0.05, 0.08, 0.04))};
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-0.12, 0.12);
  int in_contact = 0;
  for (const auto& shape : shapes) {
    geometry::Obstacle o;
    o.shape = shape;
    o.motion = std::make_shared<geometry::ConstantVelocityMotion>(
        geometry::Pose{Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Vec3(1, 1, 0).normalized())), Vec3(0.01, 0.0, 0.0)},
        Vec3::Zero(), Vec3::Zero());
    ContactParams params;
    params.thickness = 0.05;
    const Index n = 200;
    ObstacleContact contact(VecX::Constant(n, 1e-3), {o}, params);
    for (Index i = 0; i < n; ++i) {
      Eigen::Matrix<double, 3, 1> xe(u(rng), u(rng), u(rng)), g;
      Eigen::Matrix3d H, Hpsd;
      contact.element(i, xe, &g, &H);
      if (H.isZero(0.0)) continue;
      ++in_contact;
      project_psd(H);
      contact.element_psd_hessian(i, xe, Hpsd);
      EXPECT_LE((Hpsd - H).norm(), 1e-9 * std::max(1.0, H.norm())) << shape->type() << " vertex " << i;
    }
  }
  EXPECT_GT(in_contact, 100);
}

TEST(Terms, ProjectionLeavesNoVertexInside) {
  std::vector<geometry::Obstacle> obstacles(1);
  obstacles[0].shape = std::make_shared<geometry::Sphere>(0.5);
  obstacles[0].motion = std::make_shared<geometry::ConstantVelocityMotion>(geometry::Pose{}, Vec3::Zero(), Vec3::Zero());
  VecX x(9);
  x << 0.1, 0.0, 0.0, 0.0, 0.0, 2.0, 0.3, -0.2, 0.1;
  VecX pushed;
  EXPECT_EQ(project_out_of_obstacles(x, {obstacles[0].data(0.0)}, &pushed), 2);
  for (int i = 0; i < 3; ++i) EXPECT_GE(x.segment<3>(3 * i).norm(), 0.5 - 1e-12);
  EXPECT_NEAR(x[5], 2.0, 0.0);
  EXPECT_NEAR(pushed[0], 0.4, 1e-12);
}

TEST(Terms, FrictionFilterRemovesInwardVelocityAndObeysCoulomb) {
  const hd::V3 n{0.0, 0.0, 1.0}, v_obs{1.0, 0.0, 0.0};
  // Sliding: relative tangential speed 2 loses μ·Δv_n = 0.5·1; the inward normal velocity is removed.
  double v[3] = {3.0, 0.0, -0.4};
  hd::filter_velocity(v, v_obs, n, 1.0, 0.5);
  EXPECT_NEAR(v[0], 1.0 + 1.5, 1e-15);
  EXPECT_NEAR(v[1], 0.0, 1e-15);
  EXPECT_NEAR(v[2], 0.0, 1e-15);
  // Sticking: μ·Δv_n above the slip speed leaves the vertex moving with the surface; outward velocity is kept.
  double w[3] = {1.2, -0.1, 0.3};
  hd::filter_velocity(w, v_obs, n, 2.0, 0.5);
  EXPECT_NEAR(w[0], 1.0, 1e-15);
  EXPECT_NEAR(w[1], 0.0, 1e-15);
  EXPECT_NEAR(w[2], 0.3, 1e-15);
  // Frictionless: the tangential velocity passes unchanged.
  double u[3] = {3.0, 2.0, -1.0};
  hd::filter_velocity(u, v_obs, n, 5.0, 0.0);
  EXPECT_NEAR(u[0], 3.0, 1e-15);
  EXPECT_NEAR(u[1], 2.0, 1e-15);
  EXPECT_NEAR(u[2], 0.0, 1e-15);
  // The surface velocity of a spinning, moving body: v + ω × (x − c).
  geometry::Obstacle o;
  o.shape = std::make_shared<geometry::Sphere>(0.5);
  o.motion = std::make_shared<geometry::ConstantVelocityMotion>(geometry::Pose{Eigen::Quaterniond::Identity(), Vec3(1, 0, 0)},
                                                                Vec3(0.1, 0.2, 0.3), Vec3(0.0, 0.0, 2.0));
  const double t = 0.5;
  const hd::V3 pv = hd::point_velocity(o.data(t), hd::V3{1.6, 0.0, 0.0});
  const Vec3 expected = o.motion->point_velocity(t, Vec3(1.6, 0.0, 0.0));
  EXPECT_NEAR(pv.x, expected.x(), 1e-14);
  EXPECT_NEAR(pv.y, expected.y(), 1e-14);
  EXPECT_NEAR(pv.z, expected.z(), 1e-14);
}

TEST(Objective, SumsTermsAndAssemblesInParallelDeterministically) {
  auto f = small_cloth(true);
  Objective obj(f.mesh.num_vertices());
  obj.add(std::make_unique<StVKMembrane>(f.mesh, f.material));
  obj.add(std::make_unique<HingeBending>(f.mesh, f.topo, f.material));
  obj.finalize();
  const VecX x = deformed_state(f.mesh, 9, 0.01);
  double sum = 0.0;
  for (const auto& [name, v] : obj.term_values(x)) sum += v;
  EXPECT_DOUBLE_EQ(obj.value(x), sum);
  linalg::BlockMatrix3 H1, H2;
  obj.hessian(x, H1);
  obj.hessian(x, H2);
  for (Index k = 0; k < H1.num_blocks(); ++k) EXPECT_TRUE((H1.block(k).array() == H2.block(k).array()).all());
}

// The fused value-and-gradient pass must be the separate passes to the bit (solvers mix them), on any thread count.
TEST(Objective, FusedValueAndGradientAreTheSeparatePassesBitForBit) {
  auto f = small_cloth(true);
  const Index n = f.mesh.num_vertices();
  const VecX mass = VecX::LinSpaced(n, 0.01, 0.02);
  Objective obj(n);
  obj.add(std::make_unique<StVKMembrane>(f.mesh, f.material));
  obj.add(std::make_unique<HingeBending>(f.mesh, f.topo, f.material));
  obj.add(std::make_unique<IsometricBending>(f.mesh, f.topo, f.material));
  obj.add(std::make_unique<QuadraticBending>(f.mesh, f.topo, f.material));
  obj.add(std::make_unique<InertiaTerm>(mass)).set_prediction(deformed_state(f.mesh, 4, 0.02), 1.0 / 30.0);
  obj.add(std::make_unique<GravityTerm>(mass, Vec3(0, 0, -9.81)));
  obj.add(std::make_unique<SeamTerm>(std::vector<std::vector<Index>>{{0, 5, 9}, {2, 7}}, 3e3, n));
  std::vector<geometry::Obstacle> obstacles(1);
  obstacles[0].shape = std::make_shared<geometry::Sphere>(0.1);
  obstacles[0].motion = std::make_shared<geometry::ConstantVelocityMotion>(
      geometry::Pose{Eigen::Quaterniond::Identity(), Vec3(0.1, 0.07, 0.02)}, Vec3::Zero(), Vec3::Zero());
  ContactParams params;
  params.thickness = 0.02;
  obj.add(std::make_unique<ObstacleContact>(VecX::Constant(n, 1e-3), obstacles, params));
  obj.finalize();
  const int threads = num_threads();
  for (int t : {1, 2}) {
    set_num_threads(t);
    for (std::uint64_t seed : {3, 8}) {
      const VecX x = deformed_state(f.mesh, seed, 0.01);
      VecX g1, g2;
      obj.gradient(x, g1);
      const double e1 = obj.value(x);
      const double e2 = obj.value_and_gradient(x, g2);
      EXPECT_EQ(std::memcmp(&e1, &e2, sizeof e1), 0) << e1 << " " << e2;
      ASSERT_EQ(g1.size(), g2.size());
      EXPECT_EQ(std::memcmp(g1.data(), g2.data(), sizeof(double) * static_cast<size_t>(g1.size())), 0);
    }
  }
  set_num_threads(threads);
}

// The round-off floor of the gradient (Kopaničáková 2019 §7.2's limiting accuracy). Gravity's gradient does not
// depend on x: no floor at all. A pin of power-of-two stiffness k, with targets within a factor of two of the
// positions, changes its gradient by exactly k·(x' − x) (Sterbenz: x − t is exact; ×2^m is exact), so over random
// one-ulp moves (each coordinate with probability ⅔) the change's norm is k·√(⅔ Σ ulp(x_i)²) up to sampling noise.
TEST(Objective, GradientRoundoffIsZeroForConstantGradientsAndKUlpsForPins) {
  const Index n = 2000;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> pos(0.6, 1.9), rel(0.7, 1.3);
  VecX x(3 * n);
  std::vector<Vec3> targets(n);
  for (Index i = 0; i < 3 * n; ++i) x[i] = pos(rng);
  for (Index v = 0; v < n; ++v)
    for (int c = 0; c < 3; ++c) targets[v][c] = x[3 * v + c] * rel(rng);
  const double k = std::ldexp(1.0, 30);
  std::vector<Index> vertices(n);
  for (Index v = 0; v < n; ++v) vertices[v] = v;
  Objective obj(n);
  obj.add(std::make_unique<GravityTerm>(VecX::Constant(n, 0.01), Vec3(0, 0, -9.81)));
  obj.add(std::make_unique<AttachmentTerm>(vertices, std::vector<double>(n, k), n)).set_targets(targets);
  obj.finalize();
  const auto rows = gradient_roundoff(obj, x, 9);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0].term, "gravity");
  EXPECT_EQ(rows[0].change_max, 0.0);
  EXPECT_EQ(rows[1].term, "attachment");
  double ulp2 = 0.0;
  for (Index i = 0; i < x.size(); ++i) ulp2 += std::pow(std::nextafter(x[i], 2.0 * x[i]) - x[i], 2);
  const double expected = k * std::sqrt(2.0 / 3.0 * ulp2);
  EXPECT_NEAR(rows[1].change_median, expected, 0.05 * expected);
  EXPECT_GE(rows[1].change_max, rows[1].change_median);
  VecX g;
  obj.gradient(x, g);
  EXPECT_EQ(rows[2].term, "total");
  EXPECT_DOUBLE_EQ(rows[2].grad_norm, g.norm());
  // The floor is a property of x: a stiffer pin at the same x has a proportionally higher one.
  Objective stiff(n);
  stiff.add(std::make_unique<AttachmentTerm>(vertices, std::vector<double>(n, 4.0 * k), n)).set_targets(targets);
  stiff.finalize();
  EXPECT_DOUBLE_EQ(gradient_roundoff(stiff, x, 9)[0].change_median, 4.0 * rows[1].change_median);
  EXPECT_THROW(gradient_roundoff(obj, x, 0), mgcloth::Error);
  EXPECT_THROW(gradient_roundoff(obj, x.head(3), 1), mgcloth::Error);
}

// The assembly coloring: every element exactly once; no two chunks of one color share a vertex (the race-free
// guarantee of the parallel scatter); chunked on a coherent mesh, with few colors.
TEST(ElementColoring, ChunksOfOneColorShareNoVertexAndCoverEveryElement) {
  for (bool unstructured : {false, true}) {
    mesh::RectangleSpec spec;
    spec.target_vertices = 3000;
    spec.unstructured = unstructured;
    const auto m = mesh::make_rectangle(spec);
    const auto topo = mesh::build_topology(m);
    const Material mat;
    const HingeBending hinge(m, topo, mat);
    std::vector<Index> flat;
    for (const auto& el : hinge.elements()) flat.insert(flat.end(), el.begin(), el.end());
    for (Index chunk : {Index{0}, Index{1}, Index{7}, Index{64}}) {
      const ElementColors c = color_elements(flat, 4, m.num_vertices(), chunk);
      if (chunk > 0) {
        EXPECT_EQ(c.chunk_size, chunk);
      }
      std::vector<int> seen(hinge.num_elements(), 0);
      for (Index e : c.elements) ++seen[e];
      EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](int s) { return s == 1; })) << "chunk " << chunk;
      ASSERT_EQ(c.chunk_offsets.back(), static_cast<Index>(c.elements.size()));
      for (Index col = 0; col < c.num_colors(); ++col) {
        std::vector<Index> owner(m.num_vertices(), -1);  // the chunk of this color that touched the vertex
        for (Index k = c.color_offsets[col]; k < c.color_offsets[col + 1]; ++k)
          for (Index i = c.chunk_offsets[k]; i < c.chunk_offsets[k + 1]; ++i)
            for (int a = 0; a < 4; ++a) {
              Index& o = owner[flat[4 * c.elements[i] + a]];
              EXPECT_TRUE(o == -1 || o == k) << "color " << col << ": chunks " << o << " and " << k << " share a vertex";
              o = k;
            }
      }
    }
    EXPECT_EQ(hinge.colors().chunk_size, 64) << (unstructured ? "unstructured" : "regular") << " mesh";
    EXPECT_LE(hinge.colors().num_colors(), 16);
  }
}
