#include <mgcloth/core/error.hpp>
#include <mgcloth/hierarchy/reverse_subdivision.hpp>
#include "quad_fixtures.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>
#include <string>

namespace mgcloth::hierarchy {
namespace {

using mesh::QuadMesh;
using R = ReverseRule;

Index count(const ReverseRuleCounts& c, R r) { return c[static_cast<size_t>(r)]; }

using fixtures::cube;
using fixtures::fan;

VecX random_points(Index n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  VecX q(3 * n);
  for (Eigen::Index i = 0; i < q.size(); ++i) q[i] = uni(rng);
  return q;
}

/// Q S q = q and P S q = q for random q (eq. 5.16), and every row of Q sums to one; returns the rules Q used.
ReverseRuleCounts expect_exact_projections(const QuadMesh& coarse, const SubdivisionStep& step,
                                           const std::string& what) {
  ReverseRuleCounts counts{};
  const linalg::StencilTable Q = reverse_subdivision(coarse, step, &counts);
  EXPECT_EQ(Q.num_rows, coarse.num_vertices()) << what;
  EXPECT_EQ(Q.num_cols, step.fine.num_vertices()) << what;
  // Observed: 9 on grids (a ghost row substitutes rows within the same fine one-ring), 2n + 1 = 11 at valence 5,
  // 12 beside the one-cell notch.
  EXPECT_LE(Q.max_row_length(), 12) << what;
  const LeastSquaresProjection P(step.subdivision);
  for (unsigned seed : {1u, 2u}) {
    const VecX q = random_points(coarse.num_vertices(), seed);
    VecX fine, back_q, back_p;
    step.subdivision.apply(q, fine);
    Q.apply(fine, back_q);
    P.apply(fine, back_p);
    const double scale = q.cwiseAbs().maxCoeff();
    EXPECT_LE((back_q - q).cwiseAbs().maxCoeff(), 1e-12 * scale) << what << ": Q S != I";
    EXPECT_LE((back_p - q).cwiseAbs().maxCoeff(), 1e-12 * scale) << what << ": P S != I";
  }
  for (Index i = 0; i < Q.num_rows; ++i) {
    double s = 0.0;
    for (Index k = Q.offsets[i]; k < Q.offsets[i + 1]; ++k) s += Q.weights[k];
    EXPECT_NEAR(s, 1.0, 1e-12) << what << ": row " << i;
  }
  Index total = 0;
  for (Index c : counts) total += c;
  EXPECT_EQ(total, coarse.num_vertices()) << what;
  return counts;
}

ReverseRuleCounts expect_exact_on_hierarchy(const QuadMesh& coarsest, int levels, const std::string& what) {
  const SubdivisionHierarchy h(coarsest, levels);
  ReverseRuleCounts sum{};
  for (int l = 0; l + 1 < levels; ++l) {
    const ReverseRuleCounts c =
        expect_exact_projections(h.mesh(l), h.step(l), what + " level " + std::to_string(l) + "->" + std::to_string(l + 1));
    for (size_t r = 0; r < sum.size(); ++r) sum[r] += c[r];
  }
  return sum;
}

// Rules: ordinary interior (5.19), ghost points (B.2), corner ghost points (B.4).
TEST(ReverseSubdivision, RectangleWithGhostLayer) {
  const ReverseRuleCounts c = expect_exact_on_hierarchy(mesh::make_quad_rectangle(1.0, 1.0, 4, 4, true), 4, "4x4 ghost");
  EXPECT_GT(count(c, R::kOrdinary), 0);
  EXPECT_GT(count(c, R::kGhost), 0);
  EXPECT_EQ(count(c, R::kCornerGhost), 3 * 4);  // the four corners of the ghost ring on each of 3 levels
  EXPECT_EQ(count(c, R::kBoundary) + count(c, R::kCorner) + count(c, R::kExtraordinary) + count(c, R::kValence3), 0);
}

// Rules: ordinary, ghost, corner ghost, around the re-entrant corner's ghost cells too (uniform and the paper's
// non-uniform 0.3 m notch).
TEST(ReverseSubdivision, NotchedSquareWithGhostLayer) {
  for (double notch : {0.5, 0.3}) {
    const ReverseRuleCounts c =
        expect_exact_on_hierarchy(mesh::make_notched_square(1.0, notch, 4, true), 3, "notch " + std::to_string(notch));
    EXPECT_GT(count(c, R::kOrdinary), 0);
    EXPECT_GT(count(c, R::kGhost), 0);
    EXPECT_GT(count(c, R::kCornerGhost), 0);
  }
}

// Rules: ordinary, boundary (A.2 reversed), corner (valence 2).
TEST(ReverseSubdivision, RectangleWithoutGhostLayer) {
  const ReverseRuleCounts c = expect_exact_on_hierarchy(mesh::make_quad_rectangle(2.0, 1.0, 3, 2, false), 3, "3x2");
  EXPECT_GT(count(c, R::kOrdinary), 0);
  EXPECT_GT(count(c, R::kBoundary), 0);
  EXPECT_EQ(count(c, R::kCorner), 2 * 4);
  EXPECT_EQ(count(c, R::kGhost) + count(c, R::kCornerGhost), 0);
}

// Rules: extraordinary (valence 5), boundary (of valence 3), corner; with a ghost layer: ghost, corner ghost.
TEST(ReverseSubdivision, ValenceFive) {
  const ReverseRuleCounts c = expect_exact_on_hierarchy(fan(5), 3, "pentagon fan");
  EXPECT_EQ(count(c, R::kExtraordinary), 2);  // the centre on both levels
  EXPECT_GT(count(c, R::kBoundary), 0);
  EXPECT_GT(count(c, R::kCorner), 0);
  const ReverseRuleCounts g = expect_exact_on_hierarchy(fan(5, true), 3, "pentagon fan, ghost layer");
  EXPECT_EQ(count(g, R::kExtraordinary), 2);
  EXPECT_GT(count(g, R::kGhost), 0);
  EXPECT_GT(count(g, R::kCornerGhost), 0);
}

// Rules: valence 3 (App. C: B.2 through an edge to a reconstructed neighbour), next to boundary, corner and
// (once subdivided) ordinary points; with a ghost layer next to ghost and corner ghost points; and on a closed
// mesh (the cube subdivided once, eight isolated valence-3 points among ordinary ones).
TEST(ReverseSubdivision, ValenceThree) {
  const ReverseRuleCounts c = expect_exact_on_hierarchy(fan(3), 3, "three-quad fan");
  EXPECT_EQ(count(c, R::kValence3), 2);
  EXPECT_GT(count(c, R::kBoundary), 0);
  EXPECT_GT(count(c, R::kCorner), 0);
  EXPECT_GT(count(c, R::kOrdinary), 0);
  const ReverseRuleCounts g = expect_exact_on_hierarchy(fan(3, true), 3, "three-quad fan, ghost layer");
  EXPECT_EQ(count(g, R::kValence3), 2);
  EXPECT_GT(count(g, R::kGhost), 0);
  EXPECT_GT(count(g, R::kCornerGhost), 0);
  const ReverseRuleCounts k = expect_exact_on_hierarchy(subdivide(cube()).fine, 2, "cube subdivided once");
  EXPECT_EQ(count(k, R::kValence3), 8);
  EXPECT_EQ(count(k, R::kOrdinary), subdivide(cube()).fine.num_vertices() - 8);
}

// Rules: valence 3 for points next to each other. Adjacent valence-3 points are reconstructed when another
// neighbour of each is reconstructed first: the cube without its top face has four adjacent valence-3 points at the
// bottom, each next to a boundary point.
TEST(ReverseSubdivision, AdjacentValenceThreeNextToBoundary) {
  QuadMesh box = cube();
  box.quads.erase(box.quads.begin() + 1);
  const ReverseRuleCounts c = expect_exact_projections(box, subdivide(box), "open box");
  EXPECT_EQ(count(c, R::kValence3), 4);
  EXPECT_EQ(count(c, R::kBoundary), 4);
}

// A closed mesh of valence-3 points only (the cube): (5.20) is singular at every point and no neighbour is ever
// reconstructed first. Here no projection exists at all: q = ±1 alternating over the cube's two colour classes has
// S q = 0 (face points 0, edge points 0, vertex points (1/3) v + (1/9) 3 (-v) = 0), so the LS fallback refuses too.
TEST(ReverseSubdivision, ClosedValenceThreeMeshIsAnError) {
  const QuadMesh m = cube();
  const SubdivisionStep step = subdivide(m);
  try {
    reverse_subdivision(m, step);
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("coarse point 0"), std::string::npos) << what;
    EXPECT_NE(what.find("valence 3"), std::string::npos) << what;
  }
  VecX q(3 * m.num_vertices()), fine;
  for (Index i = 0; i < m.num_vertices(); ++i) vertex(q, i).setConstant(((i ^ (i >> 1) ^ (i >> 2)) & 1) ? 1.0 : -1.0);
  step.subdivision.apply(q, fine);
  EXPECT_LE(fine.cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_THROW(LeastSquaresProjection{step.subdivision}, Error);
}

TEST(ReverseSubdivision, StepOfAnotherMeshIsAnError) {
  const SubdivisionStep step = subdivide(mesh::make_quad_rectangle(1.0, 1.0, 2, 2, false));
  EXPECT_THROW(reverse_subdivision(mesh::make_quad_rectangle(1.0, 1.0, 3, 2, false), step), Error);
}

// Every rule class is used somewhere in the cases above.
TEST(ReverseSubdivision, EveryRuleIsExercised) {
  ReverseRuleCounts sum{};
  const auto accumulate = [&](const ReverseRuleCounts& c) {
    for (size_t r = 0; r < sum.size(); ++r) sum[r] += c[r];
  };
  accumulate(expect_exact_on_hierarchy(mesh::make_quad_rectangle(1.0, 1.0, 4, 4, true), 2, "4x4 ghost"));
  accumulate(expect_exact_on_hierarchy(mesh::make_quad_rectangle(2.0, 1.0, 3, 2, false), 2, "3x2"));
  accumulate(expect_exact_on_hierarchy(fan(5), 2, "pentagon fan"));
  accumulate(expect_exact_on_hierarchy(fan(3), 2, "three-quad fan"));
  for (size_t r = 0; r < sum.size(); ++r) EXPECT_GT(sum[r], 0) << "rule " << r << " never used";
}

// Level 3 of the paper's square (3,675 dofs, Table 3) onto level 2 (1,083 dofs): Q is a table of short rows, the
// LS projection a Cholesky factor with fill-in (observed: 40,436 bytes against 153,352; and from level 4, 13,467
// dofs: 137,204 against 811,504).
TEST(ReverseSubdivision, SparseAndSmallerThanTheLeastSquaresFactor) {
  const SubdivisionHierarchy h(mesh::make_quad_rectangle(1.0, 1.0, 4, 4, true), 5);
  ASSERT_EQ(3 * h.mesh(3).num_vertices(), 3675);
  ASSERT_EQ(3 * h.mesh(2).num_vertices(), 1083);
  for (int l : {2, 3}) {
    const linalg::StencilTable Q = reverse_subdivision(h.mesh(l), h.step(l));
    const LeastSquaresProjection P(h.subdivision(l));
    std::cout << "level " << l + 1 << " -> " << l << ": Q " << Q.num_entries() << " entries, max row "
              << Q.max_row_length() << ", " << Q.memory_bytes() << " bytes; LS factor " << P.factor_nonzeros()
              << " nonzeros, " << P.memory_bytes() << " bytes\n";
    EXPECT_LE(Q.max_row_length(), 9);
    EXPECT_LT(3 * Q.memory_bytes(), P.memory_bytes()) << "level " << l + 1;
  }
}

}  // namespace
}  // namespace mgcloth::hierarchy
