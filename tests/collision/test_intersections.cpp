// The intersection checker: one hand-built case per rule (no shared vertex, one, an edge), sheets flat, folded and
// pushed through themselves, and random soups against an exact reference written here with integer arithmetic.
#include <mgcloth/collision/intersections.hpp>
#include <mgcloth/core/error.hpp>

#include "sheets.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

namespace mgcloth::collision {
namespace {

using test::grid_point;
using test::grid_triangles;

VecX points(std::initializer_list<Vec3> p) {
  VecX x(3 * static_cast<Index>(p.size()));
  Index i = 0;
  for (const Vec3& q : p) vertex(x, i++) = q;
  return x;
}

size_t count(const VecX& x, const std::vector<Tri>& t) {
  size_t n = 0;
  find_intersections(x, t, 100, &n);
  return n;
}

// ---------------------------------------------------------------------------------------------------------------
// Hand-built cases

TEST(Intersections, CrossingTrianglesAreFoundAndSeparatedOnesAreNot) {
  const VecX x = points({{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0.5, 0.5, -1}, {0.5, 0.5, 1}, {-1, -1, 0.3}});
  const auto pairs = find_intersections(x, {{0, 1, 2}, {3, 4, 5}});
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0].a, 0);
  EXPECT_EQ(pairs[0].b, 1);
  VecX lifted = x;
  for (Index p = 3; p < 6; ++p) lifted[3 * p + 2] += 2.5;
  EXPECT_EQ(count(lifted, {{0, 1, 2}, {3, 4, 5}}), 0u);
}

TEST(Intersections, DistinctPointsThatTouchCount) {
  // Point 3 lies on triangle 0's face: a zero distance between points that are not the same vertex.
  const VecX x = points({{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0.5, 0.5, 0}, {0.5, 0.5, 1}, {1, 1, 1}});
  EXPECT_EQ(count(x, {{0, 1, 2}, {3, 4, 5}}), 1u);
}

TEST(Intersections, SharedVertexTouchingOnlyThereIsNotAnIntersection) {
  const VecX x = points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 1}, {0, -1, 1}});
  EXPECT_EQ(count(x, {{0, 1, 2}, {0, 3, 4}}), 0u);
}

TEST(Intersections, SharedVertexWithOneTrianglePassingThroughTheOther) {
  // Triangle 1 stands in the plane x = y; its edge 3–4 (opposite the shared point 0) pierces triangle 0.
  const VecX x = points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.3, 1}, {0.3, 0.3, -1}});
  const auto pairs = find_intersections(x, {{0, 1, 2}, {0, 3, 4}});
  ASSERT_EQ(pairs.size(), 1u);
  // The same, with the roles of the two triangles exchanged: the rule is tried both ways.
  EXPECT_EQ(count(x, {{0, 3, 4}, {0, 1, 2}}), 1u);
  // Shortened so that it stops short of triangle 0's far edge but still crosses its face.
  const VecX inside = points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.1, 0.1, 1}, {0.1, 0.1, -1}});
  EXPECT_EQ(count(inside, {{0, 1, 2}, {0, 3, 4}}), 1u);
}

// The two sides of a closed seam: points 0 and 5 are distinct vertices joined as one (each triangle keeps its own
// point's position), touching there only; an edge passing through the other triangle still counts.
TEST(Intersections, JoinedPointsCountAsSharedWithEachTriangleAtItsOwnPosition) {
  const VecX x = points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 1}, {0, -1, 1}, {0, 0, 1e-5}});
  const std::vector<Tri> t{{0, 1, 2}, {5, 3, 4}};
  const std::vector<Index> joined{0, 1, 2, 3, 4, 0};
  const auto found = [&](const VecX& y, const std::vector<Index>* j) {
    size_t n = 0;
    find_intersections(y, t, 100, &n, SIZE_MAX, j);
    return n;
  };
  EXPECT_EQ(found(x, &joined), 0u);
  VecX on = x;
  vertex(on, 5) = Vec3(0.0, 0.0, 0.0);  // the seam's sides at one place: distinct points that touch
  EXPECT_EQ(found(on, nullptr), 1u);
  EXPECT_EQ(found(on, &joined), 0u);
  // Triangle 1's far edge pierces triangle 0: an intersection, joined or not.
  VecX through = points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.3, 1}, {0.3, 0.3, -1}, {0, 0, 1e-5}});
  EXPECT_EQ(found(through, &joined), 1u);
  const std::vector<Index> short_list{0, 1};
  EXPECT_THROW(found(x, &short_list), Error);
}

TEST(Intersections, SharedVertexCoplanarFans) {
  const std::vector<Tri> t = {{0, 1, 2}, {0, 3, 4}};
  // Angles at the shared point 0: triangle 0 spans 0°–90°.
  EXPECT_EQ(count(points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {-1, 2, 0}}), t), 1u);   // 45°–117°: overlap
  EXPECT_EQ(count(points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}}), t), 0u);  // 180°–270°
  EXPECT_EQ(count(points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 2, 0}, {-1, 1, 0}}), t), 1u);   // a common side
  EXPECT_EQ(count(points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 1, 0}, {-1, -1, 0}}), t), 0u);  // 135°–225°
  // Triangle 1 inside triangle 0: only its far edge, lying in triangle 0, shows it.
  EXPECT_EQ(count(points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.2, 0.1, 0}, {0.1, 0.2, 0}}), t), 1u);
}

TEST(Intersections, FoldOverAcrossASharedEdge) {
  const std::vector<Tri> t = {{0, 1, 2}, {1, 0, 3}};
  const Vec3 u(0, 0, 0), w(1, 0, 0), a(0, 1, 0);
  EXPECT_EQ(count(points({u, w, a, {1, 1, 0}}), t), 1u);       // folded flat onto itself
  EXPECT_EQ(count(points({u, w, a, {0.5, 0.1, 0}}), t), 1u);   // a sliver folded onto its neighbour
  EXPECT_EQ(count(points({u, w, a, {0.5, -1, 0}}), t), 0u);    // flat, the two sides of the edge
  EXPECT_EQ(count(points({u, w, a, {0.5, 1, 0.5}}), t), 0u);   // bent
  // Off the plane by far less than round-off of any constructed test: the predicates are exact.
  EXPECT_EQ(count(points({u, w, a, {0.5, 1, 1e-300}}), t), 0u);
}

TEST(Intersections, TheSameTriangleTwiceOverlapsItself) {
  const VecX x = points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  EXPECT_EQ(count(x, {{0, 1, 2}, {2, 1, 0}}), 1u);
}

// Obstacle triangles come last: pairs of two of them are not checked, pairs of one with a cloth triangle are.
TEST(Intersections, PairsOfFixedTrianglesAreNotChecked) {
  // Triangle 0 (a cloth) crosses triangles 1 and 2 (an obstacle), which cross each other.
  const VecX x = points({{-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, {0.5, 0.5, -1}, {0.5, 0.5, 1}, {-1, -1, 0.3},
                         {0.4, -1, 0.2}, {0.4, 2, 0.2}, {-2, 0.5, -0.5}});
  const std::vector<Tri> t{{0, 1, 2}, {3, 4, 5}, {6, 7, 8}};
  size_t all = 0, cloth = 0;
  find_intersections(x, t, 100, &all);
  const auto pairs = find_intersections(x, t, 100, &cloth, 1);
  ASSERT_EQ(all, 3u);
  EXPECT_EQ(cloth, 2u);
  for (const TrianglePair& p : pairs) EXPECT_EQ(p.a, 0);
  size_t none = 0;
  find_intersections(x, t, 100, &none, 0);
  EXPECT_EQ(none, 0u);
}

TEST(Intersections, DegenerateTrianglesAreSkipped) {
  // Triangle 1 is a segment through triangle 0's face; triangle 2 has two coincident corners.
  const VecX x = points({{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0.5, 0.5, -1}, {0.5, 0.5, 0}, {0.5, 0.5, 1}, {0.4, 0.4, 1}});
  EXPECT_EQ(count(x, {{0, 1, 2}, {3, 4, 5}, {3, 6, 6}}), 0u);
}

TEST(Intersections, AtMostMaxPairsAscendingAndTheCountOfAll) {
  // Five horizontal triangles stacked, all pierced by one vertical triangle.
  std::vector<Vec3> p;
  std::vector<Tri> t;
  for (int k = 0; k < 5; ++k) {
    const Index b = static_cast<Index>(p.size());
    p.insert(p.end(), {{0, 0, double(k)}, {2, 0, double(k)}, {0, 2, double(k)}});
    t.push_back({b, b + 1, b + 2});
  }
  const Index b = static_cast<Index>(p.size());
  p.insert(p.end(), {{0.5, 0.5, -1}, {0.5, 0.5, 6}, {-1, -1, 2.5}});
  t.insert(t.begin() + 2, Tri{b, b + 1, b + 2});  // triangle 2
  VecX x(3 * static_cast<Index>(p.size()));
  for (size_t i = 0; i < p.size(); ++i) vertex(x, static_cast<Index>(i)) = p[i];
  size_t n = 0;
  const auto pairs = find_intersections(x, t, 3, &n);
  EXPECT_EQ(n, 5u);
  ASSERT_EQ(pairs.size(), 3u);
  EXPECT_EQ(pairs[0].a, 0);
  EXPECT_EQ(pairs[0].b, 2);
  EXPECT_EQ(pairs[1].a, 1);
  EXPECT_EQ(pairs[1].b, 2);
  EXPECT_EQ(pairs[2].a, 2);
  EXPECT_EQ(pairs[2].b, 3);
}

TEST(Intersections, RejectsAMissingOrNonFinitePoint) {
  try {
    find_intersections(points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}), {{0, 1, 2}, {0, 2, 3}});
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 1"), std::string::npos) << e.what();
  }
  VecX bad = points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  bad[4] = std::nan("");
  EXPECT_THROW(find_intersections(bad, {{0, 1, 2}}), Error);
}

// ---------------------------------------------------------------------------------------------------------------
// An exact reference on integer coordinates: two closed triangles meet iff an edge of one meets the other (the
// intersection, if any, is a convex set whose extreme points lie on edges of one triangle or the other).

using I = __int128;
using P = std::array<long long, 3>;

I orient3d(const P& a, const P& b, const P& c, const P& d) {
  const I b0 = b[0] - a[0], b1 = b[1] - a[1], b2 = b[2] - a[2];
  const I c0 = c[0] - a[0], c1 = c[1] - a[1], c2 = c[2] - a[2];
  const I d0 = d[0] - a[0], d1 = d[1] - a[1], d2 = d[2] - a[2];
  return b0 * (c1 * d2 - c2 * d1) - b1 * (c0 * d2 - c2 * d0) + b2 * (c0 * d1 - c1 * d0);
}

std::array<I, 3> normal(const P& a, const P& b, const P& c) {
  const I u0 = b[0] - a[0], u1 = b[1] - a[1], u2 = b[2] - a[2];
  const I v0 = c[0] - a[0], v1 = c[1] - a[1], v2 = c[2] - a[2];
  return {u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0};
}

bool degenerate(const P& a, const P& b, const P& c) {
  const auto n = normal(a, b, c);
  return n[0] == 0 && n[1] == 0 && n[2] == 0;
}

using Q = std::array<I, 2>;
int sign(I v) { return (v > 0) - (v < 0); }
int orient2d(const Q& a, const Q& b, const Q& c) {
  return sign((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
}
bool on_segment(const Q& p, const Q& q, const Q& r) {  // r collinear with pq
  return std::min(p[0], q[0]) <= r[0] && r[0] <= std::max(p[0], q[0]) && std::min(p[1], q[1]) <= r[1] &&
         r[1] <= std::max(p[1], q[1]);
}
bool segments_meet(const Q& p, const Q& q, const Q& r, const Q& s) {
  const int d1 = orient2d(p, q, r), d2 = orient2d(p, q, s), d3 = orient2d(r, s, p), d4 = orient2d(r, s, q);
  if (d1 * d2 < 0 && d3 * d4 < 0) return true;
  return (d1 == 0 && on_segment(p, q, r)) || (d2 == 0 && on_segment(p, q, s)) || (d3 == 0 && on_segment(r, s, p)) ||
         (d4 == 0 && on_segment(r, s, q));
}
bool inside(const Q& a, const Q& b, const Q& c, const Q& p) {
  const int o1 = orient2d(a, b, p), o2 = orient2d(b, c, p), o3 = orient2d(c, a, p);
  return (o1 >= 0 && o2 >= 0 && o3 >= 0) || (o1 <= 0 && o2 <= 0 && o3 <= 0);
}

/// Closed segment pq against the closed, non-degenerate triangle abc.
bool segment_meets_triangle(const P& p, const P& q, const P& a, const P& b, const P& c) {
  const int sp = sign(orient3d(a, b, c, p)), sq = sign(orient3d(a, b, c, q));
  if (sp * sq > 0) return false;
  if (sp == 0 && sq == 0) {
    // In the triangle's plane: drop the normal's largest axis, an affine bijection of the plane onto 2D.
    const auto n = normal(a, b, c);
    auto abs = [](I v) { return v < 0 ? -v : v; };
    const int drop = abs(n[0]) >= abs(n[1]) && abs(n[0]) >= abs(n[2]) ? 0 : abs(n[1]) >= abs(n[2]) ? 1 : 2;
    auto flat = [&](const P& v) { return Q{v[(drop + 1) % 3], v[(drop + 2) % 3]}; };
    const Q P2 = flat(p), Q2 = flat(q), A = flat(a), B = flat(b), C = flat(c);
    return inside(A, B, C, P2) || inside(A, B, C, Q2) || segments_meet(P2, Q2, A, B) || segments_meet(P2, Q2, B, C) ||
           segments_meet(P2, Q2, C, A);
  }
  // The line pq crosses the plane once, within the segment: it passes through the closed triangle iff it sees the
  // triangle's edges all turning the same way.
  const int s1 = sign(orient3d(p, q, a, b)), s2 = sign(orient3d(p, q, b, c)), s3 = sign(orient3d(p, q, c, a));
  return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
}

bool triangles_meet(const std::array<P, 3>& A, const std::array<P, 3>& B) {
  for (int k = 0; k < 3; ++k)
    if (segment_meets_triangle(A[k], A[(k + 1) % 3], B[0], B[1], B[2]) ||
        segment_meets_triangle(B[k], B[(k + 1) % 3], A[0], A[1], A[2]))
      return true;
  return false;
}

/// Every pair of non-degenerate triangles that share no point and meet, ascending.
struct Reference {
  std::vector<std::pair<Index, Index>> pairs;
};
Reference reference(const std::vector<P>& p, const std::vector<Tri>& t) {
  Reference r;
  auto corners = [&](const Tri& tri) { return std::array<P, 3>{p[tri[0]], p[tri[1]], p[tri[2]]}; };
  for (Index a = 0; a < static_cast<Index>(t.size()); ++a)
    for (Index b = a + 1; b < static_cast<Index>(t.size()); ++b) {
      const Tri &ta = t[a], &tb = t[b];
      bool shared = false;
      for (Index i : ta)
        for (Index j : tb) shared |= i == j;
      const auto A = corners(ta), B = corners(tb);
      if (shared || degenerate(A[0], A[1], A[2]) || degenerate(B[0], B[1], B[2])) continue;
      if (triangles_meet(A, B)) r.pairs.push_back({a, b});
    }
  return r;
}

VecX to_x(const std::vector<P>& p) {
  VecX x(3 * static_cast<Index>(p.size()));
  for (size_t i = 0; i < p.size(); ++i)
    for (int k = 0; k < 3; ++k) x[3 * i + k] = static_cast<double>(p[i][k]);
  return x;
}

std::vector<std::pair<Index, Index>> found(const VecX& x, const std::vector<Tri>& t) {
  std::vector<std::pair<Index, Index>> f;
  for (const TrianglePair& q : find_intersections(x, t, size_t(-1))) f.push_back({q.a, q.b});
  return f;
}

TEST(IntersectionsReference, HandBuiltCasesAgree) {
  // The reference itself, on cases whose answer is known.
  const std::array<P, 3> A = {P{0, 0, 0}, P{4, 0, 0}, P{0, 4, 0}};
  EXPECT_TRUE(triangles_meet(A, {P{1, 1, -1}, P{1, 1, 1}, P{-2, -2, 0}}));
  EXPECT_FALSE(triangles_meet(A, {P{1, 1, 1}, P{1, 1, 2}, P{-2, -2, 1}}));
  EXPECT_TRUE(triangles_meet(A, {P{2, 2, 0}, P{5, 5, 0}, P{5, 2, 0}}));   // coplanar, a corner on the edge
  EXPECT_FALSE(triangles_meet(A, {P{3, 3, 0}, P{5, 5, 0}, P{5, 3, 0}}));  // coplanar, apart
  EXPECT_TRUE(triangles_meet(A, {P{1, 1, 0}, P{1, 2, 5}, P{2, 1, 5}}));   // a corner on the face
}

TEST(Intersections, RandomSoupsAgreeWithAnExactReference) {
  std::mt19937_64 rng(11);
  struct Regime {
    long long range, size;
    Index triangles;
    bool flatten;
  };
  // A tiny lattice gives touching, coplanar and collinear configurations in numbers; a fine one, general position.
  for (const Regime& g : {Regime{6, 6, 60, false}, Regime{6, 6, 60, true}, Regime{1 << 20, 1 << 18, 200, false}}) {
    SCOPED_TRACE(::testing::Message() << "range " << g.range << (g.flatten ? ", flattened" : ""));
    std::uniform_int_distribution<long long> center(0, g.range), offset(-g.size / 2, g.size / 2);
    std::uniform_int_distribution<int> coin(0, 2);
    std::vector<P> p;
    std::vector<Tri> t;
    for (Index k = 0; k < g.triangles; ++k) {
      const P c = {center(rng), center(rng), center(rng)};
      const Index b = static_cast<Index>(p.size());
      for (int i = 0; i < 3; ++i) {
        P q = {c[0] + offset(rng), c[1] + offset(rng), c[2] + offset(rng)};
        if (g.flatten && coin(rng) > 0) q[2] = g.range / 2;  // many triangles in one plane
        p.push_back(q);
      }
      t.push_back({b, b + 1, b + 2});
    }
    const Reference r = reference(p, t);
    EXPECT_GT(r.pairs.size(), 5u);
    EXPECT_LT(r.pairs.size(), t.size() * (t.size() - 1) / 2);
    EXPECT_EQ(found(to_x(p), t), r.pairs);
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Sheets

TEST(Intersections, FlatSheetHasNone) {
  const Index n = 20;
  EXPECT_EQ(count(test::flat_grid(n, n, 0.05), grid_triangles(n, n)), 0u);
}

TEST(Intersections, SheetFoldedOverItselfPushedThroughNamesTheTriangles) {
  // Integer coordinates so that the exact reference applies: spacing 4, upper layer 2 above the lower one.
  const Index nx = 9, ny = 7, fold = 4;
  const std::vector<Tri> t = grid_triangles(nx, ny);
  auto positions = [&](long long gap) {
    std::vector<P> p(nx * ny);
    for (Index j = 0; j < ny; ++j)
      for (Index i = 0; i < nx; ++i)
        p[grid_point(nx, i, j)] = i <= fold ? P{4 * i, 4 * j, 0} : P{4 * (2 * fold - i), 4 * j, gap};
    return p;
  };
  std::vector<P> p = positions(2);
  EXPECT_EQ(count(to_x(p), t), 0u) << "the fold alone";
  // Folded flat, the layers lie on each other: every upper triangle overlaps lower ones.
  EXPECT_GT(count(to_x(positions(0)), t), 0u);

  // One point of the upper layer pushed down through the lower layer.
  const Index spike = grid_point(nx, 7, 3);
  p[spike][2] = -2;
  const auto pairs = found(to_x(p), t);
  EXPECT_EQ(pairs, reference(p, t).pairs) << "the pairs that share no point";
  ASSERT_FALSE(pairs.empty());
  auto has = [](const Tri& tri, Index v) { return tri[0] == v || tri[1] == v || tri[2] == v; };
  auto lower = [&](const Tri& tri) {
    for (Index v : tri)
      if (v % nx > fold) return false;
    return true;
  };
  std::set<Index> ring_hit;
  for (const auto& [a, b] : pairs) {
    const bool a_ring = has(t[a], spike), b_ring = has(t[b], spike);
    EXPECT_NE(a_ring, b_ring) << a << ", " << b;
    const Index ring = a_ring ? a : b, other = a_ring ? b : a;
    EXPECT_TRUE(lower(t[other])) << "triangle " << other << " is not in the lower layer";
    ring_hit.insert(ring);
  }
  // The spike's six triangles all go down through the lower layer.
  Index ring_size = 0;
  for (const Tri& tri : t) ring_size += has(tri, spike);
  EXPECT_EQ(ring_size, 6);
  EXPECT_EQ(static_cast<Index>(ring_hit.size()), ring_size);
}

}  // namespace
}  // namespace mgcloth::collision
