#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/trust_region_qp.hpp>

#include <Eigen/Dense>
#include "block_fixtures.hpp"

#include <gtest/gtest.h>

#include <random>

using namespace mgcloth;
using namespace mgcloth::linalg;

namespace {

/// A random symmetric block matrix on a ring-with-chords graph, shifted by `shift`·I: with shift = 0 it is SPD
/// (diagonally heavy), with a shift inside its spectrum it is indefinite.
BlockMatrix3 random_symmetric(Index n, std::uint64_t seed, double shift) {
  return random_ring_matrix(n, seed, 5, 14.0 - shift);
}

Eigen::VectorXd eigenvalues(const BlockMatrix3& A) {
  const Eigen::MatrixXd D = Eigen::MatrixXd(A.to_sparse());
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(D).eigenvalues();
}

VecX random_vector(Index n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> nd;
  VecX v(n);
  for (Index i = 0; i < n; ++i) v[i] = nd(rng);
  return v;
}

double model_decrease(const BlockMatrix3& H, const VecX& g, const VecX& s) { return -(g.dot(s) + 0.5 * s.dot(H * s)); }

struct Case {
  BlockMatrix3 H;
  VecX g;
  bool spd;
};

std::vector<Case> cases() {
  std::vector<Case> out;
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    out.push_back({random_symmetric(20, seed, 0.0), random_vector(60, 100 + seed), true});
    out.push_back({random_symmetric(20, seed, 14.0), random_vector(60, 200 + seed), false});
  }
  return out;
}

const std::vector<double> kRadii = {1e-4, 1e-2, 0.1, 0.5, 1.0, 3.0, 10.0, 1e3};

}  // namespace

TEST(TrustRegionQp, TestMatricesAreSpdOrIndefiniteAsIntended) {
  for (const auto& c : cases()) {
    const auto ev = eigenvalues(c.H);
    if (c.spd) EXPECT_GT(ev.minCoeff(), 0.0);
    else {
      EXPECT_LT(ev.minCoeff(), 0.0);
      EXPECT_GT(ev.maxCoeff(), 0.0);
    }
  }
}

TEST(TrustRegionQp, StepsStayInsideTheRadiusAndReportTheirModelDecrease) {
  for (const auto& c : cases()) {
    Dogleg dogleg;
    dogleg.prepare(c.H, c.g);
    for (double delta : kRadii) {
      for (const auto& r : {steihaug_cg(c.H, c.g, delta, 0, 1e-12), steihaug_cg(c.H, c.g, delta, 3, 1e-12),
                            dogleg.step(delta), cauchy_point(c.H, c.g, delta)}) {
        EXPECT_LE(r.s.norm(), delta * (1.0 + 1e-12)) << "spd " << c.spd << " delta " << delta;
        EXPECT_NEAR(r.model_decrease, model_decrease(c.H, c.g, r.s), 1e-10 * std::max(1.0, std::abs(r.model_decrease)));
        EXPECT_GT(r.model_decrease, 0.0);
      }
    }
  }
}

TEST(TrustRegionQp, LargeRadiusOnSpdGivesTheNewtonStep) {
  for (const auto& c : cases()) {
    if (!c.spd) continue;
    const Eigen::MatrixXd D = Eigen::MatrixXd(c.H.to_sparse());
    const VecX newton = D.ldlt().solve(-c.g);
    const auto cg = steihaug_cg(c.H, c.g, 1e6, 0, 1e-13);
    EXPECT_EQ(cg.reason, QpStop::Converged);
    EXPECT_LE((cg.s - newton).norm(), 1e-9 * newton.norm());
    Dogleg dogleg;
    dogleg.prepare(c.H, c.g);
    EXPECT_EQ(dogleg.shift(), 0.0);
    const auto dl = dogleg.step(1e6);
    EXPECT_EQ(dl.reason, QpStop::Converged);
    EXPECT_LE((dl.s - newton).norm(), 1e-10 * newton.norm());
    EXPECT_NEAR(dogleg.newton_norm(), newton.norm(), 1e-10 * newton.norm());
    // The model's minimum value is −½ gᵀH⁻¹g.
    EXPECT_NEAR(dl.model_decrease, -0.5 * c.g.dot(newton), 1e-10 * std::abs(c.g.dot(newton)));
  }
}

TEST(TrustRegionQp, DecreaseIsAtLeastTheCauchyDecrease) {
  // SDC with κ = 1 against the Cauchy point (Kopaničáková 2019, §4.1).
  for (const auto& c : cases()) {
    Dogleg dogleg;
    dogleg.prepare(c.H, c.g);
    for (double delta : kRadii) {
      const double cauchy = cauchy_point(c.H, c.g, delta).model_decrease;
      const double slack = 1e-12 * std::abs(cauchy);
      EXPECT_GE(steihaug_cg(c.H, c.g, delta, 0, 1e-12).model_decrease, cauchy - slack) << delta;
      EXPECT_GE(steihaug_cg(c.H, c.g, delta, 2, 1e-12).model_decrease, cauchy - slack) << delta;
      EXPECT_GE(dogleg.step(delta).model_decrease, cauchy - slack) << "spd " << c.spd << " delta " << delta;
    }
  }
}

TEST(TrustRegionQp, OneCgIterationIsTheCauchyPoint) {
  for (const auto& c : cases())
    for (double delta : kRadii) {
      const auto cg = steihaug_cg(c.H, c.g, delta, 1, 1e-12);
      const auto cp = cauchy_point(c.H, c.g, delta);
      EXPECT_EQ(cg.iterations, 1);
      EXPECT_LE((cg.s - cp.s).norm(), 1e-12 * cp.s.norm()) << delta;
    }
}

TEST(TrustRegionQp, CgBoundaryExitLiesOnTheCgPath) {
  // On an SPD model the CG iterates z_j grow in norm (Nocedal-Wright Thm. 7.3); a radius between |z_2| and |z_3|
  // must give the point of the segment z_2 → z_3 on the sphere.
  for (const auto& c : cases()) {
    if (!c.spd) continue;
    const VecX z2 = steihaug_cg(c.H, c.g, 1e9, 2, 0.0).s, z3 = steihaug_cg(c.H, c.g, 1e9, 3, 0.0).s;
    ASSERT_LT(z2.norm(), z3.norm());
    const double delta = 0.5 * (z2.norm() + z3.norm());
    const auto r = steihaug_cg(c.H, c.g, delta, 0, 1e-12);
    EXPECT_EQ(r.reason, QpStop::Boundary);
    EXPECT_EQ(r.iterations, 3);
    EXPECT_NEAR(r.s.norm(), delta, 1e-12 * delta);
    const VecX d = (z3 - z2).normalized();
    const VecX off = (r.s - z2) - (r.s - z2).dot(d) * d;
    EXPECT_LE(off.norm(), 1e-10 * delta);
  }
}

TEST(TrustRegionQp, IntermediateRadiusPutsTheDoglegOnTheBoundary) {
  const auto c = cases().front();
  ASSERT_TRUE(c.spd);
  Dogleg dogleg;
  dogleg.prepare(c.H, c.g);
  const double gHg = c.g.dot(c.H * c.g);
  const double cauchy_norm = c.g.squaredNorm() / gHg * c.g.norm();
  ASSERT_LT(cauchy_norm, dogleg.newton_norm());
  const double delta = 0.5 * (cauchy_norm + dogleg.newton_norm());
  const auto r = dogleg.step(delta);
  EXPECT_EQ(r.reason, QpStop::Boundary);
  EXPECT_NEAR(r.s.norm(), delta, 1e-12 * delta);
  // Strictly better than the Cauchy point: the segment towards p_B decreases an SPD model (Nocedal-Wright Lemma 4.2).
  EXPECT_GT(r.model_decrease, cauchy_point(c.H, c.g, delta).model_decrease);
}

TEST(TrustRegionQp, IndefiniteHessianShiftsTheFactorizationAndStillDecreases) {
  for (const auto& c : cases()) {
    if (c.spd) continue;
    const double lambda_min = eigenvalues(c.H).minCoeff();
    Dogleg dogleg;
    dogleg.prepare(c.H, c.g);
    EXPECT_EQ(dogleg.fallbacks(), 1);
    // λ runs 1e-8·max|diag H| × 10^k, k = 0, 1, …: the first of them that makes H + λI positive definite.
    double scale = 0.0;
    for (Index i = 0; i < c.H.rows(); ++i)
      scale = std::max(scale, c.H.block(c.H.diagonal(i)).diagonal().cwiseAbs().maxCoeff());
    int k = 0;
    while (1e-8 * scale * std::pow(10.0, k) <= -lambda_min) ++k;
    EXPECT_NEAR(dogleg.shift(), 1e-8 * scale * std::pow(10.0, k), 1e-9 * dogleg.shift());
    EXPECT_EQ(dogleg.factorizations(), k + 2);  // the unshifted try, then k + 1 shifts
    for (double delta : kRadii) {
      const auto r = dogleg.step(delta);
      EXPECT_GT(r.model_decrease, 0.0) << delta;
      EXPECT_LE(r.s.norm(), delta * (1.0 + 1e-12));
    }
    // The indefinite model is unbounded below: ST-CG with room to move meets negative curvature.
    EXPECT_EQ(steihaug_cg(c.H, c.g, 1e3, 0, 1e-12).reason, QpStop::NegativeCurvature);
  }
}

TEST(TrustRegionQp, StepsAfterOnePrepareDoNotRefactor) {
  for (const auto& c : cases()) {
    Dogleg dogleg;
    dogleg.prepare(c.H, c.g);
    const int after_prepare = dogleg.factorizations();
    EXPECT_GE(after_prepare, 1);
    double previous = kInf;
    for (double delta : {100.0, 10.0, 1.0, 0.3, 0.1, 0.01}) {
      const auto r = dogleg.step(delta);
      EXPECT_LE(r.model_decrease, previous + 1e-12);  // a smaller ball cannot decrease the model more
      previous = r.model_decrease;
    }
    EXPECT_EQ(dogleg.factorizations(), after_prepare);
    // A new point with the same pattern refactors but reuses the symbolic analysis.
    dogleg.prepare(c.H, 2.0 * c.g);
    EXPECT_GT(dogleg.factorizations(), after_prepare);
    EXPECT_EQ(dogleg.analyses(), 1);
  }
}

TEST(TrustRegionQp, ShiftedFactorizationOfASpdMatrixNeedsNoShift) {
  CholmodSolver chol;
  const auto spd = factorize_shifted(chol, random_symmetric(20, 9, 0.0));
  EXPECT_EQ(spd.shift, 0.0);
  EXPECT_EQ(spd.attempts, 1);
  const auto indefinite = factorize_shifted(chol, random_symmetric(20, 9, 14.0));
  EXPECT_GT(indefinite.shift, 0.0);
  EXPECT_GT(indefinite.attempts, 1);
  BlockMatrix3 bad = random_symmetric(4, 9, 0.0);
  bad.block(bad.diagonal(0))(0, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(factorize_shifted(chol, bad), SolveError);
}

TEST(TrustRegionQp, ZeroGradientGivesAZeroStep) {
  const auto c = cases().front();
  const VecX zero = VecX::Zero(c.g.size());
  EXPECT_EQ(steihaug_cg(c.H, zero, 1.0, 0, 1e-10).s.norm(), 0.0);
  Dogleg dogleg;
  dogleg.prepare(c.H, zero);
  EXPECT_EQ(dogleg.step(1.0).s.norm(), 0.0);
  EXPECT_EQ(dogleg.step(1.0).model_decrease, 0.0);
}
