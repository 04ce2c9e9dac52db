#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/galerkin.hpp>

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <cstdlib>
#include <random>

using namespace mgcloth;
using namespace mgcloth::linalg;

TEST(Galerkin, MatchesScalarTripleProduct) {
  const Index nf = 150, nc = 40;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_int_distribution<Index> pick(0, nc - 1);
  // Fine pattern: a ring with chords; random symmetric blocks.
  std::vector<std::pair<Index, Index>> pairs;
  for (Index i = 0; i < nf; ++i) {
    pairs.emplace_back(i, (i + 1) % nf);
    pairs.emplace_back(i, (i + 5) % nf);
  }
  BlockMatrix3 A(nf, pairs);
  for (Index r = 0; r < nf; ++r)
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k) {
      const Index c = A.col_indices()[k];
      if (c < r) continue;
      Mat3 b;
      for (int q = 0; q < 9; ++q) b.data()[q] = u(rng);
      if (c == r) b = b + b.transpose() + 10 * Mat3::Identity();
      A.block(k) = b;
      A.block(A.find(c, r)) = b.transpose();
    }
  // Interpolation: 1 to 3 coarse vertices per fine vertex, weights summing to one.
  std::vector<Index> po{0}, pi;
  std::vector<double> pw;
  std::vector<Eigen::Triplet<double>> pt;
  for (Index i = 0; i < nf; ++i) {
    const int m = 1 + static_cast<int>(i % 3);
    std::vector<Index> cs;
    while (static_cast<int>(cs.size()) < m) {
      const Index c = pick(rng);
      if (std::find(cs.begin(), cs.end(), c) == cs.end()) cs.push_back(c);
    }
    for (Index c : cs) {
      pi.push_back(c);
      pw.push_back(1.0 / m);
      for (int d = 0; d < 3; ++d) pt.emplace_back(3 * i + d, 3 * c + d, 1.0 / m);
    }
    po.push_back(static_cast<Index>(pi.size()));
  }
  Eigen::SparseMatrix<double> P(3 * nf, 3 * nc);
  P.setFromTriplets(pt.begin(), pt.end());
  const Eigen::SparseMatrix<double> As = A.to_sparse();
  const Eigen::MatrixXd reference = Eigen::MatrixXd(P.transpose() * As * P);

  GalerkinProduct rap(A, nc, po, pi, pw);
  BlockMatrix3 Ac;
  rap.compute(A, Ac);
  const Eigen::MatrixXd ours(Ac.to_sparse());
  EXPECT_LE((ours - reference).norm(), 1e-12 * reference.norm());
  // The pattern is exactly the structural product (plus the diagonal): every coarse pair that a fine block reaches.
  std::vector<std::pair<Index, Index>> reached;
  for (Index i = 0; i < nf; ++i)
    for (Index k = A.row_offsets()[i]; k < A.row_offsets()[i + 1]; ++k) {
      const Index j = A.col_indices()[k];
      for (Index a = po[i]; a < po[i + 1]; ++a)
        for (Index b = po[j]; b < po[j + 1]; ++b) reached.emplace_back(pi[a], pi[b]);
    }
  EXPECT_TRUE(rap.coarse_pattern().same_pattern(BlockMatrix3(nc, reached)));
  // New values, same pattern: only the numeric pass runs, and it stays exact.
  for (auto& b : A.blocks()) b *= -2.0;
  rap.compute(A, Ac);
  EXPECT_LE((Eigen::MatrixXd(Ac.to_sparse()) + 2.0 * reference).norm(), 1e-12 * reference.norm());
}

TEST(Galerkin, CoarseOperatorOfAnSpdMatrixIsSymmetricPositiveDefinite) {
  // A random SPD block matrix on a path graph and a full-rank interpolation (every coarse vertex is a fine one).
  const Index nf = 30, nc = 11;
  std::vector<std::pair<Index, Index>> pairs;
  for (Index i = 0; i + 1 < nf; ++i) pairs.emplace_back(i, i + 1);
  for (Index i = 0; i + 3 < nf; i += 2) pairs.emplace_back(i, i + 3);
  linalg::BlockMatrix3 A(nf, pairs);
  std::srand(3);  // Eigen's Random
  for (Index r = 0; r < nf; ++r)
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k) {
      const Index c = A.col_indices()[k];
      if (c < r) continue;
      const Mat3 b = c == r ? Mat3(Mat3::Random() * 0.1) : Mat3(Mat3::Random());
      A.block(k) = c == r ? Mat3(b + b.transpose()) : b;
      if (c != r) A.block(A.find(c, r)) = b.transpose();
    }
  // Make it SPD by diagonal dominance.
  for (Index r = 0; r < nf; ++r) {
    double off = 0.0;
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k)
      if (A.col_indices()[k] != r) off += A.block(k).cwiseAbs().sum();
    A.block(A.diagonal(r)) += (off + 1.0) * Mat3::Identity();
  }
  std::vector<Index> offsets{0}, indices;
  std::vector<double> weights;
  for (Index i = 0; i < nf; ++i) {
    const double t = static_cast<double>(i) * (nc - 1) / (nf - 1);
    const Index j = std::min<Index>(static_cast<Index>(t), nc - 2);
    indices.push_back(j), weights.push_back(1.0 - (t - j));
    indices.push_back(j + 1), weights.push_back(t - j);
    offsets.push_back(static_cast<Index>(indices.size()));
  }
  linalg::GalerkinProduct rap(A, nc, offsets, indices, weights);
  linalg::BlockMatrix3 C;
  rap.compute(A, C);
  const Eigen::MatrixXd Cd = Eigen::MatrixXd(C.to_sparse());
  EXPECT_LT((Cd - Cd.transpose()).norm(), 1e-12 * Cd.norm());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Cd);
  EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0);
}

TEST(Galerkin, ConstantBlocksSummedOnceGiveTheSameProduct) {
  // A 1D chain with a wider stencil; every block at distance 2 is constant. After compute_constant, new values of
  // the other blocks must give the product of the whole new matrix; new constant values need compute_constant.
  const Index nf = 60, nc = 20;
  std::vector<std::pair<Index, Index>> pairs;
  for (Index i = 0; i + 1 < nf; ++i) pairs.emplace_back(i, i + 1);
  for (Index i = 0; i + 2 < nf; ++i) pairs.emplace_back(i, i + 2);
  BlockMatrix3 A(nf, pairs);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-1, 1);
  const auto fill = [&](BlockMatrix3& M, bool variable, bool constant) {
    for (Index r = 0; r < nf; ++r)
      for (Index k = M.row_offsets()[r]; k < M.row_offsets()[r + 1]; ++k) {
        const Index c = M.col_indices()[k];
        const bool is_constant = std::abs(c - r) == 2;
        if (c < r || (is_constant ? !constant : !variable)) continue;
        Mat3 b;
        for (int q = 0; q < 9; ++q) b.data()[q] = u(rng);
        M.block(k) = b;
        M.block(M.find(c, r)) = b.transpose();
      }
  };
  fill(A, true, true);
  std::vector<char> constant(static_cast<size_t>(A.num_blocks()), 0);
  for (Index r = 0; r < nf; ++r)
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k) constant[k] = std::abs(A.col_indices()[k] - r) == 2;
  std::vector<Index> po{0}, pi;
  std::vector<double> pw;
  for (Index i = 0; i < nf; ++i) {  // linear interpolation between every third vertex
    const Index c = std::min<Index>(i / 3, nc - 1), c2 = std::min<Index>(c + 1, nc - 1);
    pi.push_back(c);
    pw.push_back(c2 == c ? 1.0 : 1.0 - (i % 3) / 3.0);
    if (c2 != c && i % 3 != 0) {
      pi.push_back(c2);
      pw.push_back((i % 3) / 3.0);
    }
    po.push_back(static_cast<Index>(pi.size()));
  }
  GalerkinProduct plain(A, nc, po, pi, pw), split(A, nc, po, pi, pw);
  split.set_constant_blocks(constant);
  BlockMatrix3 Ac;
  EXPECT_THROW(split.compute(A, Ac), Error);  // the constant share not summed yet
  split.compute_constant(A);
  const auto agree = [&](const BlockMatrix3& M) {
    BlockMatrix3 P, S;
    plain.compute(M, P);
    split.compute(M, S);
    const Eigen::MatrixXd p(P.to_sparse()), s(S.to_sparse());
    return (p - s).norm() <= 1e-13 * p.norm();
  };
  EXPECT_TRUE(agree(A));
  for (int round = 0; round < 2; ++round) {
    fill(A, true, false);
    EXPECT_TRUE(agree(A)) << "round " << round;
  }
  fill(A, false, true);
  split.compute_constant(A);
  EXPECT_TRUE(agree(A));
  split.clear_constant_blocks();
  fill(A, true, true);
  EXPECT_TRUE(agree(A));
}
