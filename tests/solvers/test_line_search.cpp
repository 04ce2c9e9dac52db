#include <mgcloth/solvers/line_search.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using namespace mgcloth;
using solvers::backtrack;
using solvers::LineSearchParams;

namespace {
// A quadratic valley along the line (minimizer at α = 1) with a stiff cubic wall from α = 0.6 on, the shape of the
// energy along a direction that brings a cloth pair into its contact layer: the minimizer along the line is just
// inside the wall, near 0.6.
double walled(double a) {
  const double wall = std::max(0.0, a - 0.6);
  return 0.5 * (a - 1.0) * (a - 1.0) + 1e6 * wall * wall * wall;
}
constexpr double kSlope = -1.0;  // walled'(0)

// The minimizer along the line, by a fine scan.
double line_minimum() {
  double best = walled(0.0);
  for (int i = 1; i <= 100000; ++i) best = std::min(best, walled(i * 1e-5));
  return best;
}
}  // namespace

TEST(LineSearch, RefinementMovesTowardTheMinimizerPastAWall) {
  LineSearchParams p;
  p.interpolate = true;
  const auto plain = backtrack(walled, walled(0.0), kSlope, 1.0, p);
  ASSERT_TRUE(plain.success);
  ASSERT_GT(plain.trials, 1);
  EXPECT_EQ(plain.refined, 0);

  p.refine = 6;
  std::vector<double> tried;
  double placed = -1.0;
  const auto refined = backtrack(
      [&](double a) {
        tried.push_back(a);
        return walled(a);
      },
      walled(0.0), kSlope, 1.0, p, [&](double a) { placed = a; });
  ASSERT_TRUE(refined.success);
  EXPECT_EQ(refined.trials, plain.trials);
  EXPECT_EQ(refined.refined, 6);
  // Bisection of [accepted, rejected] keeps only decreases: the result lies in that bracket, is Armijo-acceptable,
  // and is much closer to the line minimum than the plain search (which stops at a tenth of the rejected trial).
  const double rejected = tried[static_cast<size_t>(plain.trials) - 2];
  EXPECT_GT(refined.alpha, plain.alpha);
  EXPECT_LT(refined.alpha, rejected);
  EXPECT_DOUBLE_EQ(refined.energy, walled(refined.alpha));
  EXPECT_LE(refined.energy, walled(0.0) + p.armijo * refined.alpha * kSlope);
  const double e_min = line_minimum();
  EXPECT_LT(refined.energy - e_min, 0.1 * (plain.energy - e_min));
  // Where the last midpoint tried was not kept, the caller's trial point is formed again at the accepted α.
  if (tried.back() != refined.alpha) {
    EXPECT_EQ(placed, refined.alpha);
  } else {
    EXPECT_EQ(placed, -1.0);
  }
}

TEST(LineSearch, RefinementLeavesAFirstTrialAcceptanceAlone) {
  LineSearchParams p;
  p.interpolate = true;
  p.refine = 3;
  int calls = 0;
  const auto r = backtrack(
      [&](double a) {
        ++calls;
        return walled(a);
      },
      walled(0.0), kSlope, 0.5, p);
  ASSERT_TRUE(r.success);
  EXPECT_EQ(r.alpha, 0.5);
  EXPECT_EQ(r.trials, 1);
  EXPECT_EQ(r.refined, 0);
  EXPECT_EQ(calls, 1);
}

TEST(LineSearch, RefinementWithoutPlaceEvaluatesTheAcceptedPointLast) {
  LineSearchParams p;
  p.interpolate = true;
  p.refine = 2;
  double last = -1.0;
  const auto r = backtrack(
      [&](double a) {
        last = a;
        return walled(a);
      },
      walled(0.0), kSlope, 1.0, p);
  ASSERT_TRUE(r.success);
  // Callers that keep the last evaluated point as the accepted one (the contract of backtrack) still find it there.
  EXPECT_EQ(last, r.alpha);
}

TEST(LineSearch, AFailedSearchIsNotRefined) {
  LineSearchParams p;
  p.refine = 4;
  p.max_steps = 5;
  int calls = 0;
  // An ascent direction: every trial fails.
  const auto r = backtrack(
      [&](double a) {
        ++calls;
        return 1.0 + a;
      },
      1.0, -1.0, 1.0, p);
  EXPECT_FALSE(r.success);
  EXPECT_EQ(calls, 5);
  EXPECT_EQ(r.refined, 0);
}
