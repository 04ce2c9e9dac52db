#include <mgcloth/collision/ccd.hpp>
#include <mgcloth/collision/distance.hpp>
#include <mgcloth/core/error.hpp>

#include "collision/distance_reference.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace mgcloth::collision {
namespace {

using testing::random_vec;

using Points = std::array<Vec3, 4>;

enum class Kind { PointTriangle, EdgeEdge };

struct Motion {
  Kind kind;
  Points x, dx;
};

double distance_at(const Motion& m, double t) {
  Points y;
  for (int i = 0; i < 4; ++i) y[i] = m.x[i] + t * m.dx[i];
  const double d2 = m.kind == Kind::PointTriangle ? point_triangle_distance_sq(y[0], y[1], y[2], y[3])
                                                  : edge_edge_distance_sq(y[0], y[1], y[2], y[3]);
  return std::sqrt(d2);
}

double ccd(const Motion& m, double s, double t_max) {
  const Points& x = m.x;
  const Points& d = m.dx;
  return m.kind == Kind::PointTriangle ? point_triangle_ccd(x[0], x[1], x[2], x[3], d[0], d[1], d[2], d[3], s, t_max)
                                       : edge_edge_ccd(x[0], x[1], x[2], x[3], d[0], d[1], d[2], d[3], s, t_max);
}

// The contract: the path on [0, t] stays apart, sampled densely with the exact distance (every step of Alg. 1
// covers at most 0.9 of the distance at its start, so the distance never drops below a tenth of s·d0 there); the
// distance at t is at least s·d0 and, when t < t_max, below 10·s·d0.
void check_contract(const Motion& m, double s, double t_max, double t, const std::string& what) {
  const double d0 = distance_at(m, 0);
  ASSERT_GT(t, 0) << what;
  ASSERT_LE(t, t_max) << what;
  const int samples = 4000;
  for (int k = 0; k <= samples; ++k) {
    const double tk = t * k / samples;
    ASSERT_GT(distance_at(m, tk), 0.1 * s * d0 * (1 - 1e-9)) << what << " at t = " << tk << " of " << t;
  }
  const double dt = distance_at(m, t);
  EXPECT_GE(dt, s * d0 * (1 - 1e-9)) << what;
  if (t < t_max) {
    EXPECT_LT(dt, 10 * s * d0) << what;
  }
}

// A point driven through a random point of a moving triangle at time toi; the primitives may touch earlier elsewhere,
// never later, so the answer must come before toi.
Motion point_through_triangle(std::mt19937_64& rng, double toi, std::array<double, 3> bary) {
  Motion m{Kind::PointTriangle, {}, {}};
  for (int i = 1; i < 4; ++i) m.x[i] = random_vec(rng), m.dx[i] = random_vec(rng, 0.5);
  Vec3 hit = Vec3::Zero();
  for (int i = 0; i < 3; ++i) hit += bary[i] * (m.x[i + 1] + toi * m.dx[i + 1]);
  m.x[0] = random_vec(rng, 2.0);
  m.dx[0] = (hit - m.x[0]) / toi;
  return m;
}

// Two edges driven through a common point at time toi (sa, sb: where on each).
Motion edges_through(std::mt19937_64& rng, double toi, double sa, double sb) {
  Motion m{Kind::EdgeEdge, {}, {}};
  for (int i = 0; i < 4; ++i) m.x[i] = random_vec(rng), m.dx[i] = random_vec(rng, 0.5);
  const Vec3 on_a = (1 - sa) * (m.x[0] + toi * m.dx[0]) + sa * (m.x[1] + toi * m.dx[1]);
  const Vec3 on_b = (1 - sb) * (m.x[2] + toi * m.dx[2]) + sb * (m.x[3] + toi * m.dx[3]);
  // Translate b's whole motion so that its point meets a's at toi: shift the start and the velocity.
  const Vec3 shift = on_a - on_b, start_shift = random_vec(rng, 1.0);
  for (int i = 2; i < 4; ++i) m.x[i] += start_shift, m.dx[i] += (shift - start_shift) / toi;
  return m;
}

TEST(AdditiveCCD, RandomMotionsStayApart) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  int early = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Kind kind = trial % 2 ? Kind::EdgeEdge : Kind::PointTriangle;
    Motion m{kind, {}, {}};
    const double speed = std::pow(10.0, 2 * u01(rng) - 1);  // 0.1 to 10
    for (int i = 0; i < 4; ++i) m.x[i] = random_vec(rng), m.dx[i] = random_vec(rng, speed);
    if (distance_at(m, 0) < 1e-3) continue;
    const double s = trial % 3 == 0 ? 0.1 : trial % 3 == 1 ? 0.2 : 0.5;
    const double t_max = trial % 4 == 0 ? 0.5 : 1.0;
    const double t = ccd(m, s, t_max);
    check_contract(m, s, t_max, t, "trial " + std::to_string(trial));
    early += t < t_max;
  }
  EXPECT_GT(early, 50);  // the random motions include many that come close
}

// Motions that truly collide at toi: CCD stops strictly before, and keeps its contract, for two separations.
template <class MakeMotion>
void expect_stops_before_impact(unsigned seed, int trials, MakeMotion&& make) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.05, 0.95);
  for (int trial = 0; trial < trials; ++trial) {
    const double toi = u01(rng);
    const Motion m = make(rng, toi);
    if (distance_at(m, 0) < 1e-3) continue;
    ASSERT_LT(distance_at(m, toi), 1e-12);
    for (const double s : {0.1, 0.5}) {
      const double t = ccd(m, s, 1.0);
      EXPECT_LT(t, toi) << trial;
      check_contract(m, s, 1.0, t, "trial " + std::to_string(trial));
    }
  }
}

TEST(AdditiveCCD, PointThroughTriangleInterior) {
  expect_stops_before_impact(12, 100, [](std::mt19937_64& rng, double toi) {
    std::uniform_real_distribution<double> u01(0.05, 0.9);
    const double a = u01(rng), b = u01(rng) * (1 - a);
    return point_through_triangle(rng, toi, {a, b, 1 - a - b});
  });
}

TEST(AdditiveCCD, CrossingEdges) {
  expect_stops_before_impact(13, 100, [](std::mt19937_64& rng, double toi) {
    std::uniform_real_distribution<double> u01(0.05, 0.95);
    const double sa = u01(rng), sb = u01(rng);
    return edges_through(rng, toi, sa, sb);
  });
}

// Contact exactly at a feature of lower dimension: a vertex onto an edge, an endpoint onto the other segment's
// interior, endpoints onto each other.
TEST(AdditiveCCD, VertexHitsEdgeExactly) {
  std::mt19937_64 rng(14);
  std::uniform_real_distribution<double> u01(0.05, 0.95);
  for (int trial = 0; trial < 60; ++trial) {
    const double toi = u01(rng), a = u01(rng);
    const std::vector<Motion> motions{point_through_triangle(rng, toi, {a, 1 - a, 0.0}),  // onto edge E0
                                      point_through_triangle(rng, toi, {1.0, 0.0, 0.0}),  // onto vertex t0
                                      edges_through(rng, toi, 0.0, u01(rng)),             // a0 onto segment b
                                      edges_through(rng, toi, 1.0, 0.0)};                 // a1 onto b0
    for (size_t k = 0; k < motions.size(); ++k) {
      const Motion& m = motions[k];
      if (distance_at(m, 0) < 1e-3) continue;
      ASSERT_LT(distance_at(m, toi), 1e-12);
      const double t = ccd(m, 0.2, 1.0);
      EXPECT_LT(t, toi) << trial << " case " << k;
      check_contract(m, 0.2, 1.0, t, "trial " + std::to_string(trial) + " case " + std::to_string(k));
    }
  }
}

// A point sliding in the triangle's plane toward an edge, and parallel edges closing on each other.
TEST(AdditiveCCD, InPlaneAndParallelApproach) {
  const Vec3 t0(0, 0, 0), t1(1, 0, 0), t2(0, 1, 0), zero = Vec3::Zero();
  const Motion in_plane{Kind::PointTriangle, {Vec3(0.3, -0.5, 0), t0, t1, t2}, {Vec3(0.1, 1, 0), zero, zero, zero}};
  const double t = ccd(in_plane, 0.1, 1.0);
  EXPECT_LT(t, 0.5);
  check_contract(in_plane, 0.1, 1.0, t, "in-plane");

  const Motion parallel{Kind::EdgeEdge, {t0, t1, Vec3(0.2, 0, 1), Vec3(1.2, 0, 1)}, {zero, zero, Vec3(0, 0, -2), Vec3(0, 0, -2)}};
  const double tp = ccd(parallel, 0.1, 1.0);
  EXPECT_LT(tp, 0.5);
  check_contract(parallel, 0.1, 1.0, tp, "parallel");

  // Collinear segments sliding into each other along their line.
  const Motion collinear{Kind::EdgeEdge, {t0, t1, Vec3(2, 0, 0), Vec3(3, 0, 0)}, {zero, zero, Vec3(-2, 0, 0), Vec3(-2, 0, 0)}};
  const double tc = ccd(collinear, 0.1, 1.0);
  EXPECT_LT(tc, 0.5);
  check_contract(collinear, 0.1, 1.0, tc, "collinear");
}

// A fast point that is far from the triangle at both ends of the step but passes through it in between.
TEST(AdditiveCCD, NoTunnelling) {
  const Vec3 zero = Vec3::Zero();
  const Motion fast{Kind::PointTriangle,
                    {Vec3(0.2, 0.2, 1), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)},
                    {Vec3(0, 0, -2), zero, zero, zero}};
  ASSERT_NEAR(distance_at(fast, 0), 1, 1e-15);
  ASSERT_NEAR(distance_at(fast, 1), 1, 1e-15);
  const double t = ccd(fast, 0.1, 1.0);
  EXPECT_LT(t, 0.5);
  check_contract(fast, 0.1, 1.0, t, "point");

  const Motion edges{Kind::EdgeEdge,
                     {Vec3(-1, 0, 1), Vec3(1, 0, 1), Vec3(0, -1, -1), Vec3(0, 1, -1)},
                     {Vec3(0, 0, -4), Vec3(0, 0, -4), Vec3(0, 0, 4), Vec3(0, 0, 4)}};
  ASSERT_NEAR(distance_at(edges, 0), 2, 1e-15);
  ASSERT_NEAR(distance_at(edges, 1), 6, 1e-15);
  const double te = ccd(edges, 0.1, 1.0);
  EXPECT_LT(te, 0.25);
  check_contract(edges, 0.1, 1.0, te, "edges");
}

// Oblique passes through a large triangle and between crossing edges, the relative motion's normal part a fraction r
// of l_p, for small and large separations: a step longer than d/l_p would cross and come out on the far side at
// more than s·d0 (for s = 0.01, r = 0.9 a step of 1.5·d/l_p does), so only the step bound keeps these from tunnelling.
TEST(AdditiveCCD, NoTunnellingObliquePasses) {
  const Vec3 zero = Vec3::Zero();
  for (const double r : {1.0, 0.95, 0.9, 0.7, 0.5})
    for (const double s : {0.01, 0.1, 0.5}) {
      const double w = 2 * std::sqrt(1 / (r * r) - 1);  // tangential speed for a normal speed of 2
      const Motion point{Kind::PointTriangle,
                         {Vec3(0, 0, 1), Vec3(-10, -10, 0), Vec3(10, -10, 0), Vec3(0, 10, 0)},
                         {Vec3(w, 0, -2), zero, zero, zero}};
      const double t = ccd(point, s, 1.0);
      EXPECT_LT(t, 0.5) << "r " << r << " s " << s;
      check_contract(point, s, 1.0, t, "point r " + std::to_string(r) + " s " + std::to_string(s));
      const Vec3 half(0.5 * w, 0, -1);  // a moves by +half, b by −half
      const Motion edges{Kind::EdgeEdge,
                         {Vec3(-10, 0, 0.5), Vec3(10, 0, 0.5), Vec3(0, -10, -0.5), Vec3(0, 10, -0.5)},
                         {half, half, -half, -half}};
      const double te = ccd(edges, s, 1.0);
      EXPECT_LT(te, 0.5) << "r " << r << " s " << s;
      check_contract(edges, s, 1.0, te, "edges r " + std::to_string(r) + " s " + std::to_string(s));
    }
}

TEST(AdditiveCCD, FarOrStillPairsReturnTmax) {
  std::mt19937_64 rng(15);
  for (int trial = 0; trial < 100; ++trial) {
    const Kind kind = trial % 2 ? Kind::EdgeEdge : Kind::PointTriangle;
    Motion m{kind, {}, {}};
    for (int i = 0; i < 4; ++i) m.x[i] = random_vec(rng), m.dx[i] = random_vec(rng, 0.05);
    m.x[0] += Vec3(5, 0, 0);
    if (kind == Kind::EdgeEdge) m.x[1] += Vec3(5, 0, 0);
    // The relative motion (at most ~0.35 here) cannot close the distance (≥ 3) to half of it.
    EXPECT_EQ(ccd(m, 0.5, 1.0), 1.0) << trial;
    EXPECT_EQ(ccd(m, 0.5, 0.3), 0.3) << trial;
    Motion still = m;
    for (auto& d : still.dx) d.setZero();
    EXPECT_EQ(ccd(still, 0.1, 1.0), 1.0);
    Motion translated = m;
    for (auto& d : translated.dx) d = Vec3(3, -7, 2);  // a common translation is no relative motion
    EXPECT_EQ(ccd(translated, 0.1, 1.0), 1.0);
  }
}

// Sliding past at a distance far below the motion takes about l_p/(0.9·d) iterations; at the cap the time reached
// is returned, which is still safe.
TEST(AdditiveCCD, IterationCapIsConservative) {
  const Vec3 zero = Vec3::Zero();
  const Motion sliding{Kind::PointTriangle,
                       {Vec3(0.1, 0.1, 1e-7), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)},
                       {Vec3(0.5, 0.5, 0), zero, zero, zero}};
  const double t = ccd(sliding, 0.5, 1.0);
  EXPECT_GT(t, 0);
  EXPECT_LT(t, 1.0);
  check_contract(sliding, 0.5, 1.0, t, "sliding");
  EXPECT_GT(distance_at(sliding, t), 0.5 * 1e-7);  // stopped by the cap, not by coming close
}

TEST(AdditiveCCD, TouchingOrInvalidArguments) {
  const Vec3 zero = Vec3::Zero(), t0(0, 0, 0), t1(1, 0, 0), t2(0, 1, 0), up(0, 0, 1);
  EXPECT_EQ(point_triangle_ccd(Vec3(0.2, 0.2, 0), t0, t1, t2, up, zero, zero, zero, 0.1, 1.0), 0.0);
  EXPECT_EQ(edge_edge_ccd(t0, t1, Vec3(0.5, -1, 0), Vec3(0.5, 1, 0), up, up, zero, zero, 0.1, 1.0), 0.0);
  const Vec3 p(0.2, 0.2, 1);
  EXPECT_THROW(point_triangle_ccd(p, t0, t1, t2, up, zero, zero, zero, 0.0, 1.0), Error);
  EXPECT_THROW(point_triangle_ccd(p, t0, t1, t2, up, zero, zero, zero, 1.0, 1.0), Error);
  EXPECT_THROW(edge_edge_ccd(p, t1, t0, t2, up, zero, zero, zero, 0.1, 0.0), Error);
  EXPECT_THROW(edge_edge_ccd(p, t1, t0, t2, up, zero, zero, zero, 0.1, kInf), Error);
}

}  // namespace
}  // namespace mgcloth::collision
