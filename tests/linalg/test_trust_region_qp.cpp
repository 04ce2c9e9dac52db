#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/exact_trust_region.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>
#include <mgcloth/linalg/patch_smoother.hpp>
#include <mgcloth/linalg/trust_region_qp.hpp>

#include <Eigen/Dense>
#include <unsupported/Eigen/KroneckerProduct>
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

/// m ⊗ I₃ as a BlockMatrix3 on the nonzero pattern of the symmetric scalar matrix m.
BlockMatrix3 scalar_blocks(const Eigen::MatrixXd& m) {
  const Index n = m.rows();
  std::vector<std::pair<Index, Index>> pairs;
  for (Index i = 0; i < n; ++i)
    for (Index j = i + 1; j < n; ++j)
      if (m(i, j) != 0.0) pairs.emplace_back(i, j);
  BlockMatrix3 A(n, pairs);
  for (Index i = 0; i < n; ++i)
    for (Index k = A.row_offsets()[i]; k < A.row_offsets()[i + 1]; ++k)
      A.block(k) = m(i, A.col_indices()[k]) * Mat3::Identity();
  return A;
}

/// A dense symmetric matrix as a BlockMatrix3 with every block stored.
BlockMatrix3 dense_blocks(const Eigen::MatrixXd& D) {
  const Index n = D.rows() / 3;
  std::vector<std::pair<Index, Index>> pairs;
  for (Index i = 0; i < n; ++i)
    for (Index j = i + 1; j < n; ++j) pairs.emplace_back(i, j);
  BlockMatrix3 A(n, pairs);
  for (Index i = 0; i < n; ++i)
    for (Index k = A.row_offsets()[i]; k < A.row_offsets()[i + 1]; ++k)
      A.block(k) = D.block<3, 3>(3 * i, 3 * A.col_indices()[k]);
  return A;
}

/// A Galerkin-like metric M = PᵀP ⊗ I₃ (the shape of IᵀI in Kopaničáková 2019, eq. 4.9) for a random scalar
/// "prolongation" P from n coarse to 2n fine points: fine point i is coarse point i, fine point n + i a convex
/// combination of coarse points i, i + 1 and i + 3, and each fine row carries a weight in [0.3, 3], so that M is
/// SPD, sparse, and far from a multiple of I (condition numbers 10-100 for the seeds used here).
Eigen::MatrixXd random_metric_scalars(Index n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> w(0.0, 1.0), row_weight(0.1, 3.0);
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(2 * n, n);
  for (Index i = 0; i < n; ++i) {
    P(i, i) = row_weight(rng);
    const double a = w(rng), b = w(rng), c = w(rng), scale = row_weight(rng) / (a + b + c);
    P(n + i, i) += scale * a;
    P(n + i, (i + 1) % n) += scale * b;
    P(n + i, (i + 3) % n) += scale * c;
  }
  const Eigen::MatrixXd m = P.transpose() * P;
  return 0.5 * (m + m.transpose());
}

NormMetric random_metric(Index n, std::uint64_t seed) { return NormMetric(scalar_blocks(random_metric_scalars(n, seed))); }

NormMetric identity_metric(Index n) { return NormMetric(scalar_blocks(Eigen::MatrixXd::Identity(n, n))); }

Eigen::MatrixXd dense(const BlockMatrix3& A) { return Eigen::MatrixXd(A.to_sparse()); }

double metric_norm(const Eigen::MatrixXd& M, const VecX& s) { return std::sqrt(s.dot(M * s)); }

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

// The decade ladder overshoots the smallest shift that factorizes by up to 10×; b geometric bisections bring it
// within 10^(2^-b) of that shift, and the solver is left holding the factor of the shift returned.
TEST(TrustRegionQp, ShiftBisectionsNarrowTheShiftToTheSmallestThatFactorizes) {
  const BlockMatrix3 H = random_symmetric(20, 9, 14.0);
  const double needed = -eigenvalues(H).minCoeff();
  ASSERT_GT(needed, 0.0);
  CholmodSolver ladder, narrowed;
  const auto f0 = factorize_shifted(ladder, H);
  const auto f4 = factorize_shifted(narrowed, H, 40, 0.0, 4);
  EXPECT_GT(f0.shift, needed);
  EXPECT_LE(f0.shift, 10.0 * needed);
  EXPECT_GT(f4.shift, needed);
  EXPECT_LE(f4.shift, std::pow(10.0, 1.0 / 16.0) * needed * (1.0 + 1e-9));
  EXPECT_LE(f4.shift, f0.shift);
  EXPECT_LE(f4.attempts, f0.attempts + 5);
  const VecX b = random_vector(60, 4);
  VecX x;
  narrowed.solve(b, x);
  VecX Hx;
  H.multiply(x, Hx);
  EXPECT_LT((Hx + f4.shift * x - b).norm(), 1e-8 * b.norm() * (1.0 + x.norm()));
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

// ---- Trust regions in a level-dependent norm ‖s‖_M (Kopaničáková 2019, eqs. 4.8-4.9) ----

TEST(TrustRegionQpMetric, NormMetricMultipliesSolvesAndMeasuresInM) {
  const Eigen::MatrixXd m = random_metric_scalars(20, 7);
  const NormMetric metric(scalar_blocks(m));
  EXPECT_EQ(metric.rows(), 20);
  const Eigen::MatrixXd M = dense(metric.matrix());
  EXPECT_LE((M - Eigen::kroneckerProduct(m, Eigen::Matrix3d::Identity())).norm(), 1e-14 * M.norm());
  const VecX a = random_vector(60, 1), b = random_vector(60, 2);
  VecX out;
  metric.multiply(a, out);
  EXPECT_LE((out - M * a).norm(), 1e-13 * (M * a).norm());
  metric.solve(a, out);
  EXPECT_LE((M * out - a).norm(), 1e-12 * a.norm());
  EXPECT_NEAR(metric.dot(a, b), a.dot(M * b), 1e-12 * a.norm() * (M * b).norm());
  EXPECT_NEAR(metric.norm(a), std::sqrt(a.dot(M * a)), 1e-13 * std::sqrt(a.dot(M * a)));
}

TEST(TrustRegionQpMetric, NormMetricRejectsWhatIsNotSpd) {
  Eigen::MatrixXd m = random_metric_scalars(6, 3);
  m(2, 2) = -1.0;
  EXPECT_THROW(NormMetric{scalar_blocks(m)}, Error);
  m = random_metric_scalars(6, 3);
  m(0, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(NormMetric{scalar_blocks(m)}, Error);
  BlockMatrix3 asymmetric = scalar_blocks(random_metric_scalars(6, 3));
  asymmetric.block(asymmetric.find(0, 1)) *= 1.5;
  EXPECT_THROW(NormMetric{asymmetric}, Error);
  // A metric over other points than the vectors' is a caller's bug, not a step.
  const auto c = cases().front();
  const NormMetric small = identity_metric(6);
  EXPECT_THROW(cauchy_point(c.H, c.g, 1.0, &small), Error);
  EXPECT_THROW(steihaug_cg(c.H, c.g, 1.0, 0, 1e-10, &small), Error);
  Dogleg dogleg;
  EXPECT_THROW(dogleg.prepare(c.H, c.g, &small), Error);
}

TEST(TrustRegionQpMetric, IdentityMetricReproducesTheEuclideanSteps) {
  const NormMetric identity = identity_metric(20);
  for (const auto& c : cases()) {
    Dogleg plain, metric;
    plain.prepare(c.H, c.g);
    metric.prepare(c.H, c.g, &identity);
    EXPECT_NEAR(metric.newton_norm(), plain.newton_norm(), 1e-14 * plain.newton_norm());
    EXPECT_EQ(metric.shift(), plain.shift());
    for (double delta : kRadii) {
      const auto expect_same = [&](const QpResult& a, const QpResult& b, const char* what) {
        EXPECT_EQ(a.reason, b.reason) << what << " spd " << c.spd << " delta " << delta;
        EXPECT_EQ(a.iterations, b.iterations) << what << " spd " << c.spd << " delta " << delta;
        EXPECT_LE((a.s - b.s).norm(), 1e-12 * b.s.norm()) << what << " spd " << c.spd << " delta " << delta;
        EXPECT_NEAR(a.model_decrease, b.model_decrease, 1e-12 * b.model_decrease) << what;
        EXPECT_NEAR(a.norm, b.norm, 1e-12 * b.norm) << what;
        EXPECT_NEAR(b.norm, b.s.norm(), 1e-14 * b.norm) << what;
      };
      expect_same(cauchy_point(c.H, c.g, delta, &identity), cauchy_point(c.H, c.g, delta), "cauchy");
      for (int iters : {0, 1, 3})
        expect_same(steihaug_cg(c.H, c.g, delta, iters, 1e-12, &identity), steihaug_cg(c.H, c.g, delta, iters, 1e-12),
                    "cg");
      expect_same(metric.step(delta), plain.step(delta), "dogleg");
    }
  }
}

TEST(TrustRegionQpMetric, StepsStayInsideTheMetricBall) {
  for (std::uint64_t seed : {11, 12}) {
    const NormMetric metric = random_metric(20, seed);
    const Eigen::MatrixXd M = dense(metric.matrix());
    bool not_l2 = false;
    for (const auto& c : cases()) {
      Dogleg dogleg;
      dogleg.prepare(c.H, c.g, &metric);
      for (double delta : kRadii) {
        for (const auto& r : {steihaug_cg(c.H, c.g, delta, 0, 1e-12, &metric),
                              steihaug_cg(c.H, c.g, delta, 3, 1e-12, &metric), dogleg.step(delta),
                              cauchy_point(c.H, c.g, delta, &metric)}) {
          const double norm = metric_norm(M, r.s);
          EXPECT_LE(norm, delta * (1.0 + 1e-10)) << "spd " << c.spd << " delta " << delta;
          EXPECT_NEAR(r.norm, norm, 1e-12 * norm);
          EXPECT_NEAR(r.model_decrease, model_decrease(c.H, c.g, r.s), 1e-10 * std::max(1.0, r.model_decrease));
          EXPECT_GT(r.model_decrease, 0.0);
          not_l2 = not_l2 || std::abs(r.s.norm() / norm - 1.0) > 0.1;
        }
      }
    }
    // The constraint is not the ℓ2 one in disguise: ‖s‖₂ and ‖s‖_M differ by more than 10% for some steps.
    EXPECT_TRUE(not_l2);
  }
}

TEST(TrustRegionQpMetric, NewtonPointInsideTheMetricBallIsTheStepAndOutsideTheStepIsOnTheSphere) {
  const NormMetric metric = random_metric(20, 21);
  const Eigen::MatrixXd M = dense(metric.matrix());
  for (const auto& c : cases()) {
    if (!c.spd) continue;
    const VecX newton = dense(c.H).ldlt().solve(-c.g);
    const double newton_norm = metric_norm(M, newton);
    Dogleg dogleg;
    dogleg.prepare(c.H, c.g, &metric);
    EXPECT_EQ(dogleg.shift(), 0.0);
    EXPECT_NEAR(dogleg.newton_norm(), newton_norm, 1e-12 * newton_norm);
    for (double factor : {1.0 + 1e-6, 2.0, 1e3}) {
      const double delta = factor * newton_norm;
      const auto cg = steihaug_cg(c.H, c.g, delta, 0, 1e-13, &metric);
      EXPECT_EQ(cg.reason, QpStop::Converged) << factor;
      EXPECT_LE((cg.s - newton).norm(), 1e-9 * newton.norm()) << factor;
      const auto dl = dogleg.step(delta);
      EXPECT_EQ(dl.reason, QpStop::Converged) << factor;
      EXPECT_LE((dl.s - newton).norm(), 1e-10 * newton.norm()) << factor;
      EXPECT_NEAR(dl.model_decrease, -0.5 * c.g.dot(newton), 1e-10 * std::abs(c.g.dot(newton)));
    }
    for (double factor : {1e-4, 0.1, 0.5, 0.9, 1.0 - 1e-6}) {
      const double delta = factor * newton_norm;
      for (const auto& r : {steihaug_cg(c.H, c.g, delta, 0, 1e-13, &metric), dogleg.step(delta)}) {
        EXPECT_EQ(r.reason, QpStop::Boundary) << factor;
        EXPECT_NEAR(metric_norm(M, r.s), delta, 1e-12 * delta) << factor;
      }
    }
  }
  // An indefinite model has no minimizer: with room to move, CG meets negative curvature and stops on the sphere.
  for (const auto& c : cases()) {
    if (c.spd) continue;
    for (double delta : {1.0, 10.0, 1e3}) {
      const auto r = steihaug_cg(c.H, c.g, delta, 0, 1e-12, &metric);
      EXPECT_NE(r.reason, QpStop::Converged) << delta;
      EXPECT_NEAR(metric_norm(M, r.s), delta, 1e-12 * delta) << delta;
    }
    EXPECT_EQ(steihaug_cg(c.H, c.g, 1e3, 0, 1e-12, &metric).reason, QpStop::NegativeCurvature);
  }
}

TEST(TrustRegionQpMetric, PreconditionedCgIteratesGrowInTheMetricNorm) {
  // Conn-Gould-Toint Thm. 7.5.1: with preconditioner M the iterates z_j grow in ‖·‖_M, so a radius between
  // ‖z_2‖_M and ‖z_3‖_M gives the point of the segment z_2 → z_3 on the M-sphere after three iterations.
  const NormMetric metric = random_metric(20, 31);
  const Eigen::MatrixXd M = dense(metric.matrix());
  for (const auto& c : cases()) {
    if (!c.spd) continue;
    double previous = 0.0;
    for (int j = 1; j <= 15; ++j) {
      const double norm = metric_norm(M, steihaug_cg(c.H, c.g, 1e9, j, 0.0, &metric).s);
      EXPECT_GT(norm, previous) << j;
      previous = norm;
    }
    const VecX z2 = steihaug_cg(c.H, c.g, 1e9, 2, 0.0, &metric).s, z3 = steihaug_cg(c.H, c.g, 1e9, 3, 0.0, &metric).s;
    const double delta = 0.5 * (metric_norm(M, z2) + metric_norm(M, z3));
    const auto r = steihaug_cg(c.H, c.g, delta, 0, 1e-12, &metric);
    EXPECT_EQ(r.reason, QpStop::Boundary);
    EXPECT_EQ(r.iterations, 3);
    EXPECT_NEAR(metric_norm(M, r.s), delta, 1e-12 * delta);
    const VecX d = (z3 - z2).normalized();
    const VecX off = (r.s - z2) - (r.s - z2).dot(d) * d;
    EXPECT_LE(off.norm(), 1e-10 * r.s.norm());
  }
}

TEST(TrustRegionQpMetric, OneCgIterationIsTheMetricCauchyPoint) {
  const NormMetric metric = random_metric(20, 41);
  const Eigen::MatrixXd M = dense(metric.matrix());
  for (const auto& c : cases())
    for (double delta : kRadii) {
      const auto cp = cauchy_point(c.H, c.g, delta, &metric);
      // Along −M⁻¹g: the minimizer of the model, or the point on the M-sphere.
      const VecX y = M.ldlt().solve(c.g);
      EXPECT_LE((cp.s - cp.s.dot(y) / y.squaredNorm() * y).norm(), 1e-12 * cp.s.norm());
      EXPECT_LT(cp.s.dot(y), 0.0);
      const double t_min = c.g.dot(y) / y.dot(c.H * y), t_ball = delta / metric_norm(M, y);
      const double t = (y.dot(c.H * y) > 0.0) ? std::min(t_min, t_ball) : t_ball;
      EXPECT_LE((cp.s + t * y).norm(), 1e-12 * cp.s.norm()) << delta;
      const auto cg = steihaug_cg(c.H, c.g, delta, 1, 1e-12, &metric);
      EXPECT_EQ(cg.iterations, 1);
      EXPECT_LE((cg.s - cp.s).norm(), 1e-12 * cp.s.norm()) << delta;
    }
}

TEST(TrustRegionQpMetric, MetricSolversAreTheEuclideanOnesAfterAChangeOfVariables) {
  // With M = RᵀR and ŝ = Rs, min m(s) s.t. ‖s‖_M ≤ Δ is min ĝᵀŝ + ½ŝᵀĤŝ s.t. ‖ŝ‖₂ ≤ Δ for Ĥ = R⁻ᵀHR⁻¹, ĝ = R⁻ᵀg.
  // The M-steepest descent −M⁻¹g maps to −ĝ, M-preconditioned CG to plain CG and the Newton point to itself, so
  // the Cauchy point, every truncated CG iterate and (for SPD H, where no shift enters) the dogleg point must all
  // map onto the ℓ2 solvers' results on (Ĥ, ĝ). CG runs with rel_tol = 0, so only iteration limits, the boundary
  // and negative curvature end it, tests that are invariant under the change of variables (‖r‖₂ is not).
  const NormMetric metric = random_metric(20, 51);
  const Eigen::MatrixXd M = dense(metric.matrix());
  const Eigen::LLT<Eigen::MatrixXd> llt(M);
  ASSERT_EQ(llt.info(), Eigen::Success);
  const Eigen::MatrixXd L = llt.matrixL();  // M = LLᵀ, R = Lᵀ
  const auto from_hat = [&](const VecX& s_hat) -> VecX { return L.transpose().triangularView<Eigen::Upper>().solve(s_hat); };
  for (const auto& c : cases()) {
    const Eigen::MatrixXd LinvH = L.triangularView<Eigen::Lower>().solve(dense(c.H));
    Eigen::MatrixXd H_hat = L.triangularView<Eigen::Lower>().solve(LinvH.transpose());
    H_hat = 0.5 * (H_hat + H_hat.transpose()).eval();
    const BlockMatrix3 Hh = dense_blocks(H_hat);
    const VecX g_hat = L.triangularView<Eigen::Lower>().solve(c.g);
    const auto expect_same = [&](const QpResult& with_metric, const QpResult& hat, double tol, const std::string& what) {
      EXPECT_EQ(with_metric.reason, hat.reason) << what;
      EXPECT_EQ(with_metric.iterations, hat.iterations) << what;
      const VecX s = from_hat(hat.s);
      EXPECT_LE((with_metric.s - s).norm(), tol * s.norm()) << what;
      EXPECT_NEAR(with_metric.model_decrease, hat.model_decrease, tol * hat.model_decrease) << what;
      EXPECT_NEAR(with_metric.norm, hat.norm, tol * hat.norm) << what;
    };
    Dogleg dogleg, dogleg_hat;
    dogleg.prepare(c.H, c.g, &metric);
    dogleg_hat.prepare(Hh, g_hat);
    if (c.spd) {
      EXPECT_NEAR(dogleg.newton_norm(), dogleg_hat.newton_norm(), 1e-12 * dogleg_hat.newton_norm());
    }
    for (double delta : kRadii) {
      const std::string at = fmt::format(" spd {} delta {}", c.spd, delta);
      expect_same(cauchy_point(c.H, c.g, delta, &metric), cauchy_point(Hh, g_hat, delta), 1e-12, "cauchy" + at);
      for (int iters : {1, 2, 3, 5, 8})
        expect_same(steihaug_cg(c.H, c.g, delta, iters, 0.0, &metric), steihaug_cg(Hh, g_hat, delta, iters, 0.0),
                    1e-12, fmt::format("cg {} iterations{}", iters, at));
      if (c.spd) expect_same(dogleg.step(delta), dogleg_hat.step(delta), 1e-12, "dogleg" + at);
    }
  }
}

TEST(TrustRegionQpMetric, DecreaseIsAtLeastTheMetricCauchyDecrease) {
  // SDC with κ = 1 against the Cauchy point of the level's norm, on SPD and indefinite models alike.
  const NormMetric metric = random_metric(20, 61);
  for (const auto& c : cases()) {
    Dogleg dogleg;
    dogleg.prepare(c.H, c.g, &metric);
    for (double delta : kRadii) {
      const double cauchy = cauchy_point(c.H, c.g, delta, &metric).model_decrease;
      const double slack = 1e-12 * std::abs(cauchy);
      EXPECT_GT(cauchy, 0.0);
      for (int iters : {0, 2, 5})
        EXPECT_GE(steihaug_cg(c.H, c.g, delta, iters, 1e-12, &metric).model_decrease, cauchy - slack)
            << "spd " << c.spd << " delta " << delta << " iterations " << iters;
      EXPECT_GE(dogleg.step(delta).model_decrease, cauchy - slack) << "spd " << c.spd << " delta " << delta;
    }
  }
}

TEST(TrustRegionQpMetric, MetricDoglegStepsDoNotRefactorAndBeatTheCauchyPointOnTheSphere) {
  const NormMetric metric = random_metric(20, 71);
  const Eigen::MatrixXd M = dense(metric.matrix());
  for (const auto& c : cases()) {
    Dogleg dogleg;
    dogleg.prepare(c.H, c.g, &metric);
    const int after_prepare = dogleg.factorizations();
    double previous = kInf;
    for (double delta : {100.0, 10.0, 1.0, 0.3, 0.1, 0.01}) {
      const auto r = dogleg.step(delta);
      EXPECT_LE(r.model_decrease, previous + 1e-12);
      previous = r.model_decrease;
    }
    EXPECT_EQ(dogleg.factorizations(), after_prepare);
    if (!c.spd) continue;
    // A radius between the M-Cauchy point and the Newton point puts the dogleg on the second leg.
    const VecX y = M.ldlt().solve(c.g);
    const double cauchy_norm = c.g.dot(y) / y.dot(c.H * y) * metric_norm(M, y);
    ASSERT_LT(cauchy_norm, dogleg.newton_norm());
    const double delta = 0.5 * (cauchy_norm + dogleg.newton_norm());
    const auto r = dogleg.step(delta);
    EXPECT_EQ(r.reason, QpStop::Boundary);
    EXPECT_NEAR(metric_norm(M, r.s), delta, 1e-12 * delta);
    EXPECT_GT(r.model_decrease, cauchy_point(c.H, c.g, delta, &metric).model_decrease);
  }
}

TEST(TrustRegionQpMetric, ZeroGradientGivesAZeroStep) {
  const auto c = cases().front();
  const NormMetric metric = random_metric(20, 81);
  const VecX zero = VecX::Zero(c.g.size());
  EXPECT_EQ(cauchy_point(c.H, zero, 1.0, &metric).s.norm(), 0.0);
  EXPECT_EQ(steihaug_cg(c.H, zero, 1.0, 0, 1e-10, &metric).s.norm(), 0.0);
  Dogleg dogleg;
  dogleg.prepare(c.H, zero, &metric);
  EXPECT_EQ(dogleg.step(1.0).s.norm(), 0.0);
  EXPECT_EQ(dogleg.step(1.0).model_decrease, 0.0);
}

// The Gauss-Seidel smoothing step: inside the ball, at least the Cauchy decrease (SDC) on SPD and indefinite H,
// and, on an SPD H with a large radius and many sweeps, the Newton step (symmetric GS converges for SPD matrices).
TEST(TrustRegionQpGaussSeidel, StaysInsideTheBallAndBeatsTheCauchyPoint) {
  for (const auto& c : cases()) {
    MultiColorGaussSeidel gs(c.H);
    gs.set_matrix(c.H);
    for (double delta : kRadii)
      for (int sweeps : {1, 3}) {
        const QpResult r = gauss_seidel_step(c.H, c.g, delta, sweeps, gs);
        EXPECT_LE(r.s.norm(), delta * (1.0 + 1e-10));
        EXPECT_NEAR(r.model_decrease, model_decrease(c.H, c.g, r.s), 1e-10 * std::abs(r.model_decrease));
        const double cauchy = cauchy_point(c.H, c.g, delta).model_decrease;
        EXPECT_GE(r.model_decrease, cauchy - 1e-12 * std::abs(cauchy)) << "spd " << c.spd << " delta " << delta;
      }
    if (!c.spd) continue;
    const QpResult newton = gauss_seidel_step(c.H, c.g, 1e6, 400, gs);
    const VecX exact = Eigen::MatrixXd(c.H.to_sparse()).ldlt().solve(-c.g);
    EXPECT_LT((newton.s - exact).norm(), 1e-8 * exact.norm());
  }
}

// Overlapping Schwarz: one patch holding every point solves exactly in one sweep; overlapping point pairs converge
// on SPD matrices; the patch step keeps the ball and SDC on indefinite ones too.
TEST(TrustRegionQpSchwarz, PatchSmootherSolvesConvergesAndItsStepBeatsTheCauchyPoint) {
  for (const auto& c : cases()) {
    const Index n = c.H.rows();
    std::vector<Index> all(static_cast<size_t>(n));
    for (Index i = 0; i < n; ++i) all[static_cast<size_t>(i)] = i;
    PatchSmoother whole({all});
    whole.set_matrix(c.H);
    std::vector<std::vector<Index>> pairs;
    for (Index i = 0; i < n; ++i) pairs.push_back({i, (i + 1) % n});
    PatchSmoother overlapping(pairs);
    overlapping.set_matrix(c.H);
    if (c.spd) {
      const VecX exact = Eigen::MatrixXd(c.H.to_sparse()).ldlt().solve(-c.g);
      VecX x = VecX::Zero(c.g.size());
      whole.symmetric_sweeps(-c.g, x, 1);
      EXPECT_LT((x - exact).norm(), 1e-10 * exact.norm());
      VecX y = VecX::Zero(c.g.size());
      overlapping.symmetric_sweeps(-c.g, y, 200);
      EXPECT_LT((y - exact).norm(), 1e-6 * exact.norm());
    }
    for (double delta : kRadii) {
      const QpResult r = patch_step(c.H, c.g, delta, 1, overlapping);
      EXPECT_LE(r.s.norm(), delta * (1.0 + 1e-10));
      EXPECT_NEAR(r.model_decrease, model_decrease(c.H, c.g, r.s), 1e-10 * std::abs(r.model_decrease));
      const double cauchy = cauchy_point(c.H, c.g, delta).model_decrease;
      EXPECT_GE(r.model_decrease, cauchy - 1e-12 * std::abs(cauchy)) << "spd " << c.spd << " delta " << delta;
    }
  }
}

// The exact subproblem solution (Moré-Sorensen conditions, Nocedal-Wright Thm. 4.1): ‖s‖_M ≤ Δ, (H + σM)s = −g
// with σ ≥ 0, H + σM positive semidefinite, σ = 0 unless s is on the sphere; and so at least the decrease of the
// dogleg and of the Cauchy point, on SPD and indefinite Hessians, in ℓ2 and in a Galerkin-like metric.
TEST(TrustRegionQpExact, SatisfiesTheOptimalityConditionsAndBeatsTheDogleg) {
  for (const bool with_metric : {false, true}) {
    const NormMetric metric = random_metric(20, 7);
    const NormMetric* m = with_metric ? &metric : nullptr;
    const Eigen::MatrixXd M = with_metric ? dense(metric.matrix()) : Eigen::MatrixXd::Identity(60, 60);
    for (const Case& c : cases()) {
      ExactTrustRegion exact;
      exact.prepare(c.H, c.g, m);
      Dogleg dogleg;
      dogleg.prepare(c.H, c.g, m);
      const Eigen::MatrixXd H = dense(c.H);
      for (double r : kRadii) {
        const QpResult q = exact.step(r);
        const double norm = metric_norm(M, q.s);
        EXPECT_LE(norm, r * (1 + 1e-8));
        EXPECT_NEAR(q.model_decrease, model_decrease(c.H, c.g, q.s), 1e-9 * std::max(1.0, std::abs(q.model_decrease)));
        // σ from the residual of (H + σM)s = −g along s; then the residual vanishes and H + σM ⪰ 0.
        const VecX Hs = H * q.s, Ms = M * q.s;
        const double sigma = -(c.g + Hs).dot(Ms) / Ms.squaredNorm();
        EXPECT_GE(sigma, -1e-8 * (1 + H.norm()));
        EXPECT_LT((Hs + sigma * Ms + c.g).norm(), 1e-7 * (c.g.norm() + H.norm() * q.s.norm())) << "radius " << r;
        const double lmin = Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd>(H + sigma * M, M).eigenvalues()[0];
        EXPECT_GE(lmin, -1e-7 * H.norm()) << "radius " << r;
        if (q.reason == QpStop::Converged) EXPECT_LT(std::abs(sigma), 1e-8 * (1 + H.norm()));
        EXPECT_GE(q.model_decrease, dogleg.step(r).model_decrease * (1 - 1e-9)) << "radius " << r;
      }
    }
  }
}

// With the radius shift the dogleg of an indefinite H solves the secular equation for λ: in ℓ2 (no hard case in
// these random cases) the step is then the exact one to within the 10% of its length that the tolerance allows,
// so it fills most of the ball and gets most of the exact step's decrease, where the factorization's smallest λ
// gives a Newton point of one fixed length whatever Δ.
TEST(TrustRegionQp, RadiusShiftPutsTheIndefiniteStepOnTheSphereNearTheExactStep) {
  int beaten = 0, compared = 0;
  for (const Case& c : cases()) {
    if (c.spd) continue;
    ExactTrustRegion exact;
    exact.prepare(c.H, c.g);
    Dogleg ladder, radius;
    ladder.prepare(c.H, c.g);
    radius.set_radius_shift(true);
    radius.prepare(c.H, c.g);
    const int after_prepare = radius.factorizations();
    for (double r : kRadii) {
      const QpResult e = exact.step(r);
      const QpResult q = radius.step(r);
      const QpResult l = ladder.step(r);
      EXPECT_LE(q.s.norm(), r * (1 + 1e-12)) << "radius " << r;
      EXPECT_NEAR(q.model_decrease, model_decrease(c.H, c.g, q.s), 1e-9 * std::max(1.0, q.model_decrease));
      EXPECT_GE(q.model_decrease, cauchy_point(c.H, c.g, r).model_decrease * (1 - 1e-12)) << "radius " << r;
      // An indefinite H has no interior minimizer: the exact step is on the sphere, and so is this one, to 10%.
      EXPECT_GE(q.s.norm(), 0.9 * r) << "radius " << r;
      EXPECT_GE(q.model_decrease, 0.8 * e.model_decrease) << "radius " << r << ", λ " << radius.shift();
      EXPECT_LE(q.model_decrease, e.model_decrease * (1 + 1e-9)) << "radius " << r;
      EXPECT_GT(radius.shift(), -eigenvalues(c.H).minCoeff());  // H + λI stays positive definite
      ++compared;
      if (q.model_decrease > l.model_decrease * (1 + 1e-6)) ++beaten;
    }
    EXPECT_GT(radius.factorizations(), after_prepare);  // the radius moved λ
    EXPECT_LE(radius.factorizations(), after_prepare + 6 * static_cast<int>(kRadii.size()));
  }
  // Where Δ is larger than the ladder's Newton point the radius shift goes farther and decreases the model more.
  EXPECT_GT(beaten, compared / 4);
}

// The hard case: g orthogonal to the eigenvector of the most negative eigenvalue. The dogleg's shifted Newton point
// barely moves along it; the exact step fills the ball and goes along it.
TEST(TrustRegionQpExact, HardCaseFillsTheBallAlongTheNegativeCurvature) {
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(6, 6);
  D.diagonal() << -2.0, 1.0, 3.0, 4.0, 5.0, 6.0;
  const BlockMatrix3 H = dense_blocks(D);
  VecX g(6);
  g << 0.0, 0.1, 0.1, 0.1, 0.1, 0.1;
  ExactTrustRegion exact;
  exact.prepare(H, g);
  const QpResult q = exact.step(1.0);
  EXPECT_EQ(q.reason, QpStop::Boundary);
  EXPECT_NEAR(q.s.norm(), 1.0, 1e-10);
  EXPECT_GT(std::abs(q.s[0]), 0.9);
  EXPECT_NEAR(q.model_decrease, -(g.dot(q.s) + 0.5 * q.s.dot(D * q.s)), 1e-12);
  // The minimizer of the model on the ball: −½·2·s₀² dominates, so the decrease is about 1.
  EXPECT_GT(q.model_decrease, 0.95);
}

TEST(TrustRegionQpExact, RefusesLargeProblems) {
  const Index points = ExactTrustRegion::max_dofs / 3 + 1;
  std::vector<std::pair<Index, Index>> pairs;
  for (Index i = 0; i < points; ++i) pairs.push_back({i, i});
  BlockMatrix3 H(points, std::move(pairs));
  ExactTrustRegion exact;
  EXPECT_THROW(exact.prepare(H, VecX::Zero(3 * points)), Error);
}
