#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/block_jacobi.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/linalg/hypre_amg.hpp>
#include <mgcloth/linalg/pcg.hpp>

#include <gtest/gtest.h>

#include <Eigen/Geometry>

using namespace mgcloth;
using namespace mgcloth::linalg;

namespace {
/// A cloth-like SPD system without the physics module: an n x n vertex sheet on [0, 1]² with linear plane-stress
/// elasticity (constant-strain triangles, E = 500 N/m, ν = 0.3) for x and y, a tension Laplacian (5 N/m) for z, and
/// a lumped mass/Δt² on the diagonal (0.15 kg/m², Δt = 1/30 s); every block then rotated by R (blocks R B Rᵀ), so
/// that x, y and z couple as on a tilted sheet.
BlockMatrix3 sheet_system(Index n, const Mat3& R = Mat3::Identity()) {
  const double h = 1.0 / (n - 1), young = 500.0, nu = 0.3, tension = 5.0;
  const double mu = young / (2.0 * (1.0 + nu)), lambda = young * nu / (1.0 - nu * nu);
  const double mass = 0.15 * h * h * 900.0;
  auto id = [n](Index i, Index j) { return i * n + j; };
  std::vector<Tri> tris;
  for (Index i = 0; i + 1 < n; ++i)
    for (Index j = 0; j + 1 < n; ++j) {
      tris.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      tris.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  std::vector<std::pair<Index, Index>> pairs;
  for (const Tri& t : tris)
    for (int a = 0; a < 3; ++a) pairs.emplace_back(t[a], t[(a + 1) % 3]);
  BlockMatrix3 A(n * n, pairs);
  auto position = [&](Index v) { return Vec2(h * (v / n), h * (v % n)); };
  for (const Tri& t : tris) {
    const Vec2 p0 = position(t[0]), e1 = position(t[1]) - p0, e2 = position(t[2]) - p0;
    const double area = 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());
    Eigen::Matrix<double, 2, 3> g;  // barycentric gradients
    const Mat2 Dinv = (Mat2() << e1, e2).finished().inverse();
    g.col(1) = Dinv.row(0).transpose();
    g.col(2) = Dinv.row(1).transpose();
    g.col(0) = -g.col(1) - g.col(2);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        Mat3 K = Mat3::Zero();
        for (int a = 0; a < 2; ++a)
          for (int b = 0; b < 2; ++b)
            K(a, b) = area * (mu * ((a == b ? g.col(i).dot(g.col(j)) : 0.0) + g(b, i) * g(a, j)) + lambda * g(a, i) * g(b, j));
        K(2, 2) = area * tension * g.col(i).dot(g.col(j));
        A.block(A.find(t[i], t[j])) += K;
      }
  }
  for (Index v = 0; v < A.rows(); ++v) A.block(A.diagonal(v)) += mass * Mat3::Identity();
  for (auto& B : A.blocks()) B = R * B * R.transpose();
  return A;
}

Mat3 tilt() { return Eigen::AngleAxisd(0.7, Vec3(1.0, 2.0, 0.5).normalized()).toRotationMatrix(); }

VecX random_vector(Index size, unsigned seed) {
  std::srand(seed);
  return VecX::Random(size);
}

double relative_residual(const BlockMatrix3& A, const VecX& b, const VecX& x) { return (b - A * x).norm() / b.norm(); }
}  // namespace

TEST(Pcg, EachPreconditionerSolvesToToleranceAndMatchesCholmod) {
  const BlockMatrix3 A = sheet_system(30, tilt());
  const VecX b = random_vector(3 * A.rows(), 1);
  CholmodSolver chol;
  ASSERT_TRUE(chol.factorize(A));
  VecX exact;
  chol.solve(b, exact);

  BlockJacobi jacobi(A);
  HypreAmg amg;
  amg.set_matrix(A);
  const std::vector<std::pair<std::string, Preconditioner>> preconditioners{
      {"identity", [](const VecX& r, VecX& z) { z = r; }},
      {"block-Jacobi", [&](const VecX& r, VecX& z) { jacobi.apply(r, z); }},
      {"BoomerAMG", [&](const VecX& r, VecX& z) { amg.apply(r, z); }}};
  for (const auto& [name, M] : preconditioners) {
    VecX x = VecX::Zero(b.size());
    const int iterations = pcg(A, b, x, M, 1e-8, 5000);
    EXPECT_LT(iterations, 5000) << name;
    EXPECT_LE(relative_residual(A, b, x), 1e-8) << name;
    EXPECT_LT((x - exact).norm(), 1e-6 * exact.norm()) << name;
  }
}

TEST(Pcg, StartsFromTheGivenGuessAndRejectsIndefiniteMatrices) {
  BlockMatrix3 A = sheet_system(8);
  const VecX b = random_vector(3 * A.rows(), 2);
  CholmodSolver chol;
  ASSERT_TRUE(chol.factorize(A));
  VecX x;
  chol.solve(b, x);
  EXPECT_EQ(pcg(A, b, x, [](const VecX& r, VecX& z) { z = r; }, 1e-8, 100), 0);
  for (auto& B : A.blocks()) B = -B;
  VecX y = VecX::Zero(b.size());
  EXPECT_THROW(pcg(A, b, y, [](const VecX& r, VecX& z) { z = r; }, 1e-8, 100), SolveError);
}

TEST(HypreAmg, NeedsFarFewerIterationsThanPlainCGOnPlaneElasticity) {
  const BlockMatrix3 A = sheet_system(32);
  const VecX b = random_vector(3 * A.rows(), 3);
  HypreAmg amg;
  amg.set_matrix(A);
  EXPECT_GE(amg.setup_seconds(), 0.0);
  VecX x_amg = VecX::Zero(b.size()), x_cg = VecX::Zero(b.size());
  const int it_amg = pcg(A, b, x_amg, [&](const VecX& r, VecX& z) { amg.apply(r, z); }, 1e-8, 500);
  const int it_cg = pcg(A, b, x_cg, [](const VecX& r, VecX& z) { z = r; }, 1e-8, 5000);
  EXPECT_LE(relative_residual(A, b, x_amg), 1e-8);
  EXPECT_LT(it_amg, 40);
  EXPECT_LT(10 * it_amg, it_cg) << "BoomerAMG-PCG " << it_amg << ", CG " << it_cg;
}

TEST(HypreAmg, TakesNewValuesForTheSamePattern) {
  BlockMatrix3 A = sheet_system(12, tilt());
  const VecX b = random_vector(3 * A.rows(), 4);
  HypreAmg amg;
  amg.set_matrix(A);
  for (auto& B : A.blocks()) B *= 2.0;
  amg.set_matrix(A);
  CholmodSolver chol;
  ASSERT_TRUE(chol.factorize(A));
  VecX exact, x = VecX::Zero(b.size());
  chol.solve(b, exact);
  pcg(A, b, x, [&](const VecX& r, VecX& z) { amg.apply(r, z); }, 1e-10, 200);
  EXPECT_LT((x - exact).norm(), 1e-8 * exact.norm());
}

TEST(Preconditioners, AreSymmetricAndPositive) {
  const BlockMatrix3 A = sheet_system(20, tilt());
  const VecX r1 = random_vector(3 * A.rows(), 5), r2 = random_vector(3 * A.rows(), 6);
  auto expect_spd = [&](const std::string& name, const Preconditioner& M) {
    VecX z1, z2;
    M(r1, z1);
    M(r2, z2);
    EXPECT_NEAR(r2.dot(z1), r1.dot(z2), 1e-8 * std::abs(r1.dot(z2))) << name;
    EXPECT_GT(r1.dot(z1), 0.0) << name;
    EXPECT_GT(r2.dot(z2), 0.0) << name;
  };
  BlockJacobi jacobi(A);
  expect_spd("block-Jacobi", [&](const VecX& r, VecX& z) { jacobi.apply(r, z); });
  using S = HypreAmgParams::Smoother;
  for (const S smoother : {S::ForwardBackwardGS, S::SymmetricGS, S::L1SymmetricGS, S::L1Jacobi}) {
    for (const int nodal : {0, 2}) {
      HypreAmgParams params;
      params.smoother = smoother;
      params.nodal = nodal;
      HypreAmg amg(params);
      amg.set_matrix(A);
      expect_spd(fmt::format("BoomerAMG smoother {} nodal {}", static_cast<int>(smoother), nodal),
                 [&](const VecX& r, VecX& z) { amg.apply(r, z); });
    }
  }
}

TEST(Preconditioners, RejectSingularDiagonalBlocks) {
  BlockMatrix3 A = sheet_system(6);
  A.block(A.diagonal(7)).setZero();
  try {
    BlockJacobi jacobi(A);
    FAIL() << "no exception";
  } catch (const SolveError& e) {
    EXPECT_NE(std::string(e.what()).find("row 7"), std::string::npos) << e.what();
  }
  A = sheet_system(6);
  A.block(A.diagonal(3))(1, 1) = -1.0;  // indefinite block
  EXPECT_THROW(BlockJacobi{A}, SolveError);
  HypreAmg amg;
  EXPECT_THROW(amg.set_matrix(A), SolveError);
  VecX z;
  EXPECT_THROW(amg.apply(VecX::Ones(3 * A.rows()), z), Error);  // no successful setup yet
}

TEST(HypreAmg, RejectsBadParameters) {
  HypreAmgParams params;
  params.strong_threshold = 1.5;
  EXPECT_THROW(HypreAmg{params}, InputError);
  params = {};
  params.nodal = 5;
  EXPECT_THROW(HypreAmg{params}, InputError);
}
