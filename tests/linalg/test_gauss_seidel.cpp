#include <mgcloth/linalg/chebyshev.hpp>
#include <mgcloth/linalg/coloring.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>

#include <gtest/gtest.h>

#include <cstdlib>

#include <Eigen/Eigenvalues>
#include <random>

using namespace mgcloth;
using namespace mgcloth::linalg;

namespace {
/// SPD block matrix of a 2D grid graph (8 neighbours), diagonally dominant only weakly.
BlockMatrix3 grid_spd(Index n, std::uint64_t seed) {
  std::vector<std::pair<Index, Index>> pairs;
  auto id = [n](Index i, Index j) { return i * n + j; };
  for (Index i = 0; i < n; ++i)
    for (Index j = 0; j < n; ++j)
      for (Index di = 0; di <= 1; ++di)
        for (Index dj = -1; dj <= 1; ++dj) {
          const Index i2 = i + di, j2 = j + dj;
          if ((di == 0 && dj <= 0) || i2 >= n || j2 < 0 || j2 >= n) continue;
          pairs.emplace_back(id(i, j), id(i2, j2));
        }
  BlockMatrix3 A(n * n, pairs);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.5, 1.0);
  for (Index r = 0; r < A.rows(); ++r)
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k) {
      const Index c = A.col_indices()[k];
      if (c <= r) continue;
      const double w = u(rng);
      const Mat3 b = -w * Mat3::Identity();
      A.block(k) = b;
      A.block(A.find(c, r)) = b;
      A.block(A.diagonal(r)) -= b;
      A.block(A.diagonal(c)) -= b;
    }
  for (Index r = 0; r < A.rows(); ++r) A.block(A.diagonal(r)) += 0.01 * Mat3::Identity();
  return A;
}
}  // namespace

TEST(Coloring, NoTwoCoupledRowsShareAColor) {
  const BlockMatrix3 A = grid_spd(20, 1);
  const auto colors = color_rows(A);
  std::vector<Index> color(A.rows(), -1);
  Index total = 0;
  for (Index c = 0; c < static_cast<Index>(colors.size()); ++c)
    for (Index r : colors[c]) {
      color[r] = c;
      ++total;
    }
  EXPECT_EQ(total, A.rows());
  for (Index r = 0; r < A.rows(); ++r)
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k)
      if (A.col_indices()[k] != r) {
        EXPECT_NE(color[r], color[A.col_indices()[k]]);
      }
  EXPECT_LE(colors.size(), 5u);  // an 8-neighbour grid needs 4; greedy in row order finds 4 or 5
}

TEST(GaussSeidel, SymmetricSweepsConverge) {
  const BlockMatrix3 A = grid_spd(16, 2);
  MultiColorGaussSeidel gs(A);
  gs.set_matrix(A);
  const VecX b = VecX::Random(3 * A.rows());
  VecX x = VecX::Zero(b.size());
  double prev = b.norm();
  for (int k = 0; k < 5; ++k) {
    gs.symmetric_sweeps(b, x, 20);
    const double res = (b - A * x).norm();
    EXPECT_LT(res, prev);
    prev = res;
  }
  EXPECT_LT(prev, 0.5 * b.norm());
}

TEST(GaussSeidel, SmoothingOperatorIsSymmetricPositiveDefinite) {
  // Wang 2018, Theorem 4.1: K symmetric sweeps from x = 0 apply an SPD matrix to b.
  const BlockMatrix3 A = grid_spd(5, 3);
  MultiColorGaussSeidel gs(A);
  gs.set_matrix(A);
  const Index n = 3 * A.rows();
  for (int sweeps : {1, 3}) {
    Eigen::MatrixXd M(n, n);
    for (Index j = 0; j < n; ++j) {
      VecX e = VecX::Unit(n, j), x = VecX::Zero(n);
      gs.symmetric_sweeps(e, x, sweeps);
      M.col(j) = x;
    }
    EXPECT_LE((M - M.transpose()).norm(), 1e-12 * M.norm()) << sweeps;
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (M + M.transpose())).eigenvalues().minCoeff(), 0.0);
  }
}

TEST(GaussSeidel, MaskedRowsAreLeftAlone) {
  const BlockMatrix3 A = grid_spd(6, 4);
  MultiColorGaussSeidel gs(A);
  gs.set_matrix(A);
  std::vector<char> mask(A.rows(), 1);
  mask[7] = 0;
  const VecX b = VecX::Random(3 * A.rows());
  VecX x = VecX::Constant(b.size(), 0.25);
  gs.symmetric_sweeps(b, x, 2, &mask);
  EXPECT_TRUE((x.segment<3>(21).array() == 0.25).all());
  EXPECT_FALSE((x.segment<3>(24).array() == 0.25).all());
}


TEST(Chebyshev, AcceleratesSymmetricGaussSeidel) {
  const BlockMatrix3 A = grid_spd(24, 5);
  MultiColorGaussSeidel gs(A);
  gs.set_matrix(A);
  const double rho = estimate_gauss_seidel_rho(A, gs);
  EXPECT_GT(rho, 0.5);
  EXPECT_LT(rho, 1.0);
  std::srand(7);  // VecX::Random draws from std::rand: fixed here, so the test does not depend on those run before
  const VecX b = VecX::Random(3 * A.rows());
  VecX plain = VecX::Zero(b.size()), fast = VecX::Zero(b.size());
  gs.symmetric_sweeps(b, plain, 40);
  chebyshev_gauss_seidel(gs, b, fast, 40, rho);
  const double r_plain = (b - A * plain).norm(), r_fast = (b - A * fast).norm();
  EXPECT_LT(r_fast, 0.5 * r_plain) << "plain " << r_plain << " chebyshev " << r_fast;
}

TEST(Chebyshev, SmoothingOperatorIsSymmetricPositiveDefinite) {
  const BlockMatrix3 A = grid_spd(5, 6);
  MultiColorGaussSeidel gs(A);
  gs.set_matrix(A);
  const double rho = estimate_gauss_seidel_rho(A, gs);
  const Index n = 3 * A.rows();
  Eigen::MatrixXd M(n, n);
  for (Index j = 0; j < n; ++j) {
    VecX x = VecX::Zero(n);
    chebyshev_gauss_seidel(gs, VecX::Unit(n, j), x, 6, rho);
    M.col(j) = x;
  }
  EXPECT_LE((M - M.transpose()).norm(), 1e-10 * M.norm());
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (M + M.transpose())).eigenvalues().minCoeff(), 0.0);
}

TEST(GaussSeidel, MultiColorEqualsSequentialGaussSeidelInColorOrder) {
  // Rows of one color are uncoupled, so relaxing them in parallel is exactly sequential block Gauss-Seidel over the
  // rows listed color by color (forward), then in the reverse of that order (backward).
  const BlockMatrix3 A = grid_spd(9, 5);
  MultiColorGaussSeidel gs(A);
  gs.set_matrix(A);
  std::vector<Index> order;
  for (const auto& c : gs.colors()) order.insert(order.end(), c.begin(), c.end());
  ASSERT_EQ(static_cast<Index>(order.size()), A.rows());
  const VecX b = VecX::Random(3 * A.rows());
  VecX x = VecX::Random(b.size()), y = x;
  auto relax = [&](Index r) {
    Vec3 s = b.segment<3>(3 * r);
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k)
      if (A.col_indices()[k] != r) s -= A.block(k) * y.segment<3>(3 * A.col_indices()[k]);
    y.segment<3>(3 * r) = A.block(A.diagonal(r)).inverse() * s;
  };
  for (int sweep = 0; sweep < 2; ++sweep) {
    for (Index r : order) relax(r);
    for (auto it = order.rbegin(); it != order.rend(); ++it) relax(*it);
  }
  gs.symmetric_sweeps(b, x, 2);
  EXPECT_LT((x - y).norm(), 1e-12 * y.norm());
}

TEST(GaussSeidel, AdaptiveMaskSkipsRowsWithSmallResidual) {
  const BlockMatrix3 A = grid_spd(8, 6);
  const VecX b = VecX::Random(3 * A.rows());
  VecX x = VecX::Zero(b.size());
  std::vector<char> mask;
  const VecX r = b - A * x;
  const Index active = adaptive_mask(r, 0.5 * r.norm() / std::sqrt(static_cast<double>(A.rows())), mask);
  Index count = 0;
  for (Index i = 0; i < A.rows(); ++i) {
    const bool large = r.segment<3>(3 * i).norm() >= 0.5 * r.norm() / std::sqrt(static_cast<double>(A.rows()));
    EXPECT_EQ(mask[i] != 0, large) << "row " << i;
    count += large;
  }
  EXPECT_EQ(active, count);
  EXPECT_GT(count, 0);
  EXPECT_LT(count, A.rows());
}

namespace {
/// grid_spd with full 3x3 off-diagonal blocks (A_cr = A_rcᵀ, not symmetric themselves), whose entries float cannot
/// hold exactly.
BlockMatrix3 grid_spd_full_blocks(Index n, std::uint64_t seed) {
  BlockMatrix3 A = grid_spd(n, seed);
  std::mt19937_64 rng(seed + 1);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  for (Index r = 0; r < A.rows(); ++r)
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k) {
      const Index c = A.col_indices()[k];
      if (c <= r) continue;
      Mat3 e;
      for (int i = 0; i < 9; ++i) e.data()[i] = u(rng);
      A.block(k) += e;
      A.block(A.find(c, r)) += e.transpose();
      A.block(A.diagonal(r)) += 0.6 * Mat3::Identity();  // |e| ≤ 0.6 in the 2-norm: stays diagonally dominant
      A.block(A.diagonal(c)) += 0.6 * Mat3::Identity();
    }
  return A;
}
}  // namespace

TEST(GaussSeidel, SinglePrecisionIsExactlyGaussSeidelOfTheRoundedMatrix) {
  const BlockMatrix3 A = grid_spd_full_blocks(9, 11);
  BlockMatrix3 rounded = A;
  for (Mat3& b : rounded.blocks())
    for (int e = 0; e < 9; ++e) b.data()[e] = static_cast<float>(b.data()[e]);
  MultiColorGaussSeidel single(A, MultiColorGaussSeidel::Precision::Single), exact(rounded), dbl(A);
  single.set_matrix(A);
  exact.set_matrix(rounded);
  dbl.set_matrix(A);
  EXPECT_EQ(single.precision(), MultiColorGaussSeidel::Precision::Single);
  std::srand(3);
  const VecX b = VecX::Random(3 * A.rows());
  VecX xs = VecX::Zero(b.size()), xe = xs, xd = xs;
  single.symmetric_sweeps(b, xs, 3);
  exact.symmetric_sweeps(b, xe, 3);
  dbl.symmetric_sweeps(b, xd, 3);
  EXPECT_LE((xs - xe).norm(), 1e-14 * xe.norm());
  // It did round: the double smoother of A differs at float's precision, and no more.
  EXPECT_GT((xs - xd).norm(), 1e-10 * xd.norm());
  EXPECT_LT((xs - xd).norm(), 1e-5 * xd.norm());
}

TEST(GaussSeidel, SinglePrecisionSmootherIsSymmetricPositiveDefinite) {
  // Ã keeps A's symmetry (each entry and its transpose partner round alike), so Theorem 4.1 holds for Ã.
  const BlockMatrix3 A = grid_spd_full_blocks(5, 12);
  MultiColorGaussSeidel gs(A, MultiColorGaussSeidel::Precision::Single);
  gs.set_matrix(A);
  const Index n = 3 * A.rows();
  Eigen::MatrixXd M(n, n);
  for (Index j = 0; j < n; ++j) {
    VecX x = VecX::Zero(n);
    gs.symmetric_sweeps(VecX::Unit(n, j), x, 2);
    M.col(j) = x;
  }
  EXPECT_LE((M - M.transpose()).norm(), 1e-12 * M.norm());
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (M + M.transpose())).eigenvalues().minCoeff(), 0.0);
}

TEST(GaussSeidel, ColorOrderedCopyFollowsNewValuesAndPatterns) {
  // set_matrix() with new values on the same pattern (blocks that were multiples of the identity now full, then
  // full blocks again), then with another pattern, gives what a fresh smoother gives.
  const BlockMatrix3 A = grid_spd(7, 13), B = grid_spd_full_blocks(7, 14), B2 = grid_spd_full_blocks(7, 16),
                     C = grid_spd(6, 15);
  MultiColorGaussSeidel gs(A);
  gs.set_matrix(A);
  std::srand(4);
  for (const BlockMatrix3* M : {&B, &B2, &A, &C}) {
    gs.set_matrix(*M);
    MultiColorGaussSeidel fresh(*M);
    fresh.set_matrix(*M);
    const VecX b = VecX::Random(3 * M->rows());
    VecX x = VecX::Zero(b.size()), y = x;
    gs.symmetric_sweeps(b, x, 2);
    fresh.symmetric_sweeps(b, y, 2);
    // Round-off apart: back on A, blocks classified full on B stay full where a fresh smoother stores scalars, and
    // the sums run in another order.
    EXPECT_LE((x - y).norm(), 1e-14 * y.norm());
  }
}

TEST(GaussSeidel, ProductFromTheCopyIsTheMatrixProduct) {
  // The copy stores scalar blocks as one number and full blocks apart; its product must still be A x, for either
  // kind of block and after new values.
  const BlockMatrix3 A = grid_spd(8, 21), B = grid_spd_full_blocks(8, 22);
  MultiColorGaussSeidel gs(A);
  std::srand(5);
  for (const BlockMatrix3* M : {&A, &B, &A}) {
    gs.set_matrix(*M);
    ASSERT_TRUE(gs.can_multiply());
    const VecX x = VecX::Random(3 * M->rows());
    VecX y;
    gs.multiply(x, y);
    const VecX reference = *M * x;
    EXPECT_LE((y - reference).norm(), 1e-14 * reference.norm());
  }
  MultiColorGaussSeidel single(A, MultiColorGaussSeidel::Precision::Single);
  single.set_matrix(A);
  EXPECT_FALSE(single.can_multiply());
}
