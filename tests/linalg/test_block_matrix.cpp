#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/block_matrix.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>

#include "block_fixtures.hpp"

#include <gtest/gtest.h>

#include <random>

using namespace mgcloth;
using namespace mgcloth::linalg;

namespace {
/// A random SPD block matrix on a ring-with-chords graph.
BlockMatrix3 random_spd(Index n, std::uint64_t seed) {
  return random_ring_matrix(n, seed, 7, 20.0);
}
}  // namespace

TEST(BlockMatrix3, PatternIsSymmetricSortedWithDiagonal) {
  BlockMatrix3 A(5, {{0, 3}, {2, 1}, {2, 1}});
  EXPECT_EQ(A.num_blocks(), 5 + 4);
  for (Index r = 0; r < 5; ++r) {
    EXPECT_GE(A.diagonal(r), 0);
    for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k) {
      EXPECT_GE(A.find(A.col_indices()[k], r), 0);
      if (k > A.row_offsets()[r]) {
        EXPECT_LT(A.col_indices()[k - 1], A.col_indices()[k]);
      }
    }
  }
  EXPECT_EQ(A.find(0, 1), -1);
  EXPECT_THROW(BlockMatrix3(3, {{0, 3}}), Error);
}

TEST(BlockMatrix3, MultiplyMatchesScalarSparse) {
  const BlockMatrix3 A = random_spd(200, 1);
  const VecX x = VecX::Random(600);
  const VecX y = A * x;
  const VecX y_ref = A.to_sparse() * x;
  EXPECT_LE((y - y_ref).norm(), 1e-12 * y_ref.norm());
}

TEST(CholmodSolver, SolvesAndReusesSymbolicAnalysis) {
  BlockMatrix3 A = random_spd(300, 2);
  CholmodSolver chol;
  for (int round = 0; round < 3; ++round) {
    for (auto& b : A.blocks()) b *= 1.5;  // new values, same pattern
    ASSERT_TRUE(chol.factorize(A));
    const VecX b = VecX::Random(900);
    VecX x;
    chol.solve(b, x);
    EXPECT_LE((A * x - b).norm(), 1e-10 * b.norm());
  }
  EXPECT_EQ(chol.analyses(), 1);
  // A shift is applied to the diagonal only.
  ASSERT_TRUE(chol.factorize(A, 3.0));
  const VecX b = VecX::Random(900);
  VecX x;
  chol.solve(b, x);
  EXPECT_LE((A * x + 3.0 * x - b).norm(), 1e-10 * b.norm());
  // A different pattern triggers a new analysis.
  ASSERT_TRUE(chol.factorize(random_spd(50, 3)));
  EXPECT_EQ(chol.analyses(), 2);
}

TEST(CholmodSolver, ReportsIndefiniteMatrix) {
  BlockMatrix3 A = random_spd(40, 4);
  A.block(A.diagonal(5)) = -Mat3::Identity();
  CholmodSolver chol;
  EXPECT_FALSE(chol.factorize(A));
}

TEST(BlockMatrix3, FromRowsKeepsAValidPatternAndRefusesBrokenOnes) {
  const BlockMatrix3 A(4, {{0, 3}, {2, 1}});
  const BlockMatrix3 B = BlockMatrix3::from_rows(4, A.row_offsets(), A.col_indices());
  EXPECT_TRUE(B.same_pattern(A));
  for (Index r = 0; r < 4; ++r) EXPECT_EQ(B.diagonal(r), A.diagonal(r));
  EXPECT_THROW(BlockMatrix3::from_rows(2, {0, 1, 2}, {0, 0}), Error);          // row 1 lacks its diagonal
  EXPECT_THROW(BlockMatrix3::from_rows(2, {0, 2, 3}, {1, 0, 1}), Error);       // row 0 unsorted
  EXPECT_THROW(BlockMatrix3::from_rows(2, {0, 2, 3}, {0, 0, 1}), Error);       // row 0 repeats a column
  EXPECT_THROW(BlockMatrix3::from_rows(2, {0, 1, 2}, {0, 2}), Error);          // column outside
  EXPECT_THROW(BlockMatrix3::from_rows(2, {0, 1}, {0}), Error);                // offsets for one row
}
