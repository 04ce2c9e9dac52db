// The broad phase against its O(n²) reference: random soups, crumpled and folded sheets, swept boxes, refits after
// motion, thread counts, and the pairs that share a point.
#include <mgcloth/collision/broad_phase.hpp>
#include <mgcloth/core/error.hpp>

#include "sheets.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <omp.h>
#include <random>
#include <functional>

namespace mgcloth::collision {
namespace {

using Pairs = std::vector<std::array<Index, 2>>;
using test::displace;
using test::flat_grid;
using test::folded_grid;
using test::grid_triangles;

/// Restores OpenMP's thread count when a test changes it.
struct ThreadCount {
  int saved = omp_get_max_threads();
  ~ThreadCount() { omp_set_num_threads(saved); }
};

/// A soup of n small random triangles in the unit cube; some share points, so exclusion is exercised too.
struct Soup {
  std::vector<Tri> triangles;
  VecX x;
};
Soup random_soup(Index n, double size, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0), s(-size, size);
  std::uniform_int_distribution<int> coin(0, 3);
  Soup soup;
  std::vector<Vec3> points;
  for (Index t = 0; t < n; ++t) {
    const Vec3 c(u(rng), u(rng), u(rng));
    Tri tri;
    for (int k = 0; k < 3; ++k) {
      // A quarter of the corners reuse an earlier point, which makes fans and shared edges.
      if (k > 0 && !points.empty() && coin(rng) == 0) {
        std::uniform_int_distribution<Index> pick(0, static_cast<Index>(points.size()) - 1);
        Index p = pick(rng);
        if (std::find(tri.begin(), tri.begin() + k, p) == tri.begin() + k) {
          tri[k] = p;
          continue;
        }
      }
      points.push_back(c + Vec3(s(rng), s(rng), s(rng)));
      tri[k] = static_cast<Index>(points.size()) - 1;
    }
    soup.triangles.push_back(tri);
  }
  soup.x.resize(3 * static_cast<Index>(points.size()));
  for (size_t p = 0; p < points.size(); ++p) vertex(soup.x, static_cast<Index>(p)) = points[p];
  return soup;
}

/// The swept reference, written here from the definition rather than shared with the library.
Candidates swept_brute_force(const SurfaceTopology& s, const VecX& x, const VecX& d, double inflate) {
  auto box = [&](std::initializer_list<Index> points) {
    Aabb b;
    for (Index p : points) {
      b.expand(vertex(x, p));
      b.expand(Vec3(vertex(x, p) + vertex(d, p)));
    }
    b.inflate(inflate);
    return b;
  };
  std::vector<Aabb> vertices, triangles, edges;
  for (Index p : s.vertices) vertices.push_back(box({p}));
  for (const Tri& t : s.triangles) triangles.push_back(box({t[0], t[1], t[2]}));
  for (const auto& e : s.edges) edges.push_back(box({e[0], e[1]}));
  Candidates c;
  for (Index v = 0; v < static_cast<Index>(s.vertices.size()); ++v)
    for (Index t = 0; t < static_cast<Index>(s.triangles.size()); ++t) {
      const Tri& tri = s.triangles[t];
      const Index p = s.vertices[v];
      if (p != tri[0] && p != tri[1] && p != tri[2] && vertices[v].overlaps(triangles[t]))
        c.vertex_triangle.push_back({v, t});
    }
  for (Index a = 0; a < static_cast<Index>(s.edges.size()); ++a)
    for (Index b = a + 1; b < static_cast<Index>(s.edges.size()); ++b) {
      const auto &ea = s.edges[a], &eb = s.edges[b];
      if (ea[0] != eb[0] && ea[0] != eb[1] && ea[1] != eb[0] && ea[1] != eb[1] && edges[a].overlaps(edges[b]))
        c.edge_edge.push_back({a, b});
    }
  return c;
}

/// Equal as sets, and the broad phase's list ascending without repeats (its documented, history-free order).
void expect_same(const Candidates& got, const Candidates& want) {
  auto ascending = [](const Pairs& p) {
    return std::adjacent_find(p.begin(), p.end(), std::greater_equal<>()) == p.end();
  };
  EXPECT_TRUE(ascending(got.vertex_triangle));
  EXPECT_TRUE(ascending(got.edge_edge));
  auto as_set = [](Pairs p) {
    std::sort(p.begin(), p.end());
    p.erase(std::unique(p.begin(), p.end()), p.end());
    return p;
  };
  EXPECT_TRUE(got.vertex_triangle == as_set(want.vertex_triangle))
      << got.vertex_triangle.size() << " vertex–triangle pairs, want " << want.vertex_triangle.size();
  EXPECT_TRUE(got.edge_edge == as_set(want.edge_edge))
      << got.edge_edge.size() << " edge–edge pairs, want " << want.edge_edge.size();
}

void expect_identical(const Candidates& a, const Candidates& b) {
  EXPECT_EQ(a.vertex_triangle, b.vertex_triangle);
  EXPECT_EQ(a.edge_edge, b.edge_edge);
}

/// find and find_swept against the references at several inflations.
void check_against_brute_force(const SurfaceTopology& s, const VecX& x, const VecX& d,
                               const std::vector<double>& inflations) {
  for (double inflate : inflations) {
    SCOPED_TRACE(::testing::Message() << "inflate " << inflate);
    Candidates want, got;
    find_brute_force(s, x, inflate, want);
    BroadPhase bp(&s);
    bp.find(x, inflate, got);
    expect_same(got, want);
    ASSERT_FALSE(want.vertex_triangle.empty());
    ASSERT_FALSE(want.edge_edge.empty());
    bp.find_swept(x, d, inflate, got);
    const Candidates swept = swept_brute_force(s, x, d, inflate);
    expect_same(got, swept);
    // The swept boxes hold the static ones, so they can only add pairs.
    EXPECT_GE(got.vertex_triangle.size(), want.vertex_triangle.size());
    // The pairs that touch a marked point, static and swept, for a few points and for many.
    for (int every : {37, 3}) {
      SCOPED_TRACE(::testing::Message() << "every " << every << "th point marked");
      std::vector<char> marked(static_cast<size_t>(x.size() / 3), 0);
      for (size_t p = 0; p < marked.size(); p += static_cast<size_t>(every)) marked[p] = 1;
      const auto touching = [&](const Candidates& c) {
        Candidates out;
        for (const auto& [v, t] : c.vertex_triangle) {
          const Tri& tri = s.triangles[t];
          if (marked[s.vertices[v]] || marked[tri[0]] || marked[tri[1]] || marked[tri[2]])
            out.vertex_triangle.push_back({v, t});
        }
        for (const auto& [a, b] : c.edge_edge)
          if (marked[s.edges[a][0]] || marked[s.edges[a][1]] || marked[s.edges[b][0]] || marked[s.edges[b][1]])
            out.edge_edge.push_back({a, b});
        return out;
      };
      const Candidates want_static = touching(want), want_swept = touching(swept);
      ASSERT_FALSE(want_static.vertex_triangle.empty());
      ASSERT_LT(want_static.edge_edge.size(), want.edge_edge.size());
      bp.find_touching(x, nullptr, inflate, marked, got);
      expect_same(got, want_static);
      bp.find_touching(x, &d, inflate, marked, got);
      expect_same(got, want_swept);
    }
  }
}

TEST(SurfaceTopology, EdgesOnceAscendingAndVerticesAscending) {
  // Two triangles sharing edge 3–7, and one apart; points 0–2 and 4 unused.
  const SurfaceTopology s = make_surface_topology({{7, 3, 5}, {3, 7, 6}, {9, 8, 10}});
  const Pairs edges = {{3, 5}, {3, 6}, {3, 7}, {5, 7}, {6, 7}, {8, 9}, {8, 10}, {9, 10}};
  EXPECT_EQ(s.edges, edges);
  EXPECT_EQ(s.vertices, (std::vector<Index>{3, 5, 6, 7, 8, 9, 10}));
  EXPECT_EQ(s.triangles.size(), 3u);
}

TEST(SurfaceTopology, RejectsBadTrianglesByIndex) {
  try {
    make_surface_topology({{0, 1, 2}, {1, 2, 2}});
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(make_surface_topology({{0, -1, 2}}), Error);
}

TEST(Bvh, QueriesMatchALinearScanAndRefitMatchesABuild) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0), s(0.0, 0.05);
  auto random_boxes = [&](Index n) {
    std::vector<Aabb> boxes(n);
    for (Aabb& b : boxes) {
      b.expand(Vec3(u(rng), u(rng), u(rng)));
      b.expand(Vec3(b.lo + Vec3(s(rng), s(rng), s(rng))));
    }
    return boxes;
  };
  auto hits = [](const Bvh& bvh, const Aabb& q) {
    std::vector<Index> h;
    bvh.query(q, [&](Index i) { h.push_back(i); });
    std::sort(h.begin(), h.end());
    return h;
  };
  for (Index n : {0, 1, 3, 4, 5, 17, 1000}) {
    SCOPED_TRACE(::testing::Message() << n << " boxes");
    const std::vector<Aabb> a = random_boxes(n), b = random_boxes(n), queries = random_boxes(200);
    Bvh built, refit;
    built.build(b);
    refit.build(a);
    refit.refit(b);
    EXPECT_EQ(built.size(), static_cast<size_t>(n));
    size_t total = 0;
    for (const Aabb& q : queries) {
      std::vector<Index> want;
      for (Index i = 0; i < n; ++i)
        if (b[i].overlaps(q)) want.push_back(i);
      EXPECT_EQ(hits(built, q), want);
      EXPECT_EQ(hits(refit, q), want);
      total += want.size();
    }
    if (n >= 100) {
      EXPECT_GT(total, 0u);
      // Moving the boxes to unrelated places leaves the refit tree's nodes overlapping: the area that triggers
      // rebuilds must see it.
      EXPECT_GT(refit.total_surface_area(), 2.0 * built.total_surface_area());
    }
  }
  Bvh bvh;
  bvh.build(random_boxes(10));
  EXPECT_THROW(bvh.refit(random_boxes(11)), Error);
}

TEST(BroadPhase, MatchesBruteForceOnRandomSoups) {
  std::mt19937 rng(1);
  for (double size : {0.02, 0.08}) {
    const Soup soup = random_soup(400, size, rng);
    const SurfaceTopology s = make_surface_topology(soup.triangles);
    VecX d = VecX::Zero(soup.x.size());
    displace(d, 0.05, rng);
    check_against_brute_force(s, soup.x, d, {0.0, 1e-3, 0.01, 0.05});
  }
}

TEST(BroadPhase, MatchesBruteForceOnACrumpledAndAFoldedSheet) {
  std::mt19937 rng(2);
  const Index n = 24;
  const double h = 1.0 / (n - 1);
  const SurfaceTopology s = make_surface_topology(grid_triangles(n, n));
  VecX d = VecX::Zero(3 * n * n);
  displace(d, 0.5 * h, rng);
  {
    SCOPED_TRACE("crumpled");
    VecX x = flat_grid(n, n, h);
    displace(x, h, rng);
    check_against_brute_force(s, x, d, {0.0, 0.1 * h, 0.5 * h, 2.0 * h});
  }
  {
    SCOPED_TRACE("folded");
    VecX x = folded_grid(n, n, n / 2, h, 0.3 * h);
    displace(x, 0.05 * h, rng);
    check_against_brute_force(s, x, d, {0.0, 0.1 * h, 0.5 * h, 2.0 * h});
  }
}

TEST(BroadPhase, SameListForOneAndTwoThreads) {
  ThreadCount restore;
  std::mt19937 rng(3);
  const Index n = 60;  // 3600 vertices: several chunks of queries per thread
  const double h = 1.0 / (n - 1);
  const SurfaceTopology s = make_surface_topology(grid_triangles(n, n));
  VecX x = folded_grid(n, n, n / 2, h, 0.3 * h), d = VecX::Zero(3 * n * n);
  displace(x, 0.5 * h, rng);
  displace(d, h, rng);
  Candidates one, two, swept_one, swept_two;
  omp_set_num_threads(1);
  BroadPhase a(&s);
  a.find(x, 0.2 * h, one);
  a.find_swept(x, d, 0.1 * h, swept_one);
  omp_set_num_threads(2);
  BroadPhase b(&s);
  b.find(x, 0.2 * h, two);
  b.find_swept(x, d, 0.1 * h, swept_two);
  ASSERT_GT(one.vertex_triangle.size(), 1000u);
  expect_identical(one, two);
  expect_identical(swept_one, swept_two);
}

TEST(BroadPhase, RefitAfterMotionMatchesAFreshBuild) {
  std::mt19937 rng(4);
  const Index n = 40;
  const double h = 1.0 / (n - 1), inflate = 0.3 * h;
  const SurfaceTopology s = make_surface_topology(grid_triangles(n, n));
  VecX x = folded_grid(n, n, n / 2, h, 0.5 * h);
  displace(x, 0.1 * h, rng);
  BroadPhase bp(&s);
  Candidates got, fresh, want;
  bp.find(x, inflate, got);
  EXPECT_EQ(bp.builds(), 2);
  // A motion the size of the mesh spacing: the trees are refit, not rebuilt, and give what fresh ones give.
  for (int step = 0; step < 3; ++step) {
    displace(x, 0.3 * h, rng);
    bp.find(x, inflate, got);
    BroadPhase(&s).find(x, inflate, fresh);
    find_brute_force(s, x, inflate, want);
    expect_identical(got, fresh);
    expect_same(got, want);
  }
  EXPECT_EQ(bp.builds(), 2);
  // Scrambling the points spoils the refit trees: they are rebuilt, and the answer stays right.
  displace(x, 0.5, rng);
  bp.find(x, inflate, got);
  EXPECT_GT(bp.builds(), 2);
  find_brute_force(s, x, inflate, want);
  expect_same(got, want);
}

TEST(BroadPhase, PairsSharingAPointAreNeverCandidates) {
  const Index n = 6;
  const SurfaceTopology s = make_surface_topology(grid_triangles(n, n));
  const VecX x = flat_grid(n, n, 0.1);
  Candidates got;
  // Every box overlaps every other: exactly the pairs that share no point remain.
  BroadPhase(&s).find(x, 10.0, got);
  const size_t nv = s.vertices.size(), nt = s.triangles.size();
  EXPECT_EQ(got.vertex_triangle.size(), nv * nt - 3 * nt);
  size_t disjoint_edges = 0;
  for (size_t a = 0; a < s.edges.size(); ++a)
    for (size_t b = a + 1; b < s.edges.size(); ++b) {
      const auto &ea = s.edges[a], &eb = s.edges[b];
      disjoint_edges += ea[0] != eb[0] && ea[0] != eb[1] && ea[1] != eb[0] && ea[1] != eb[1];
    }
  EXPECT_EQ(got.edge_edge.size(), disjoint_edges);
  for (const auto& [v, t] : got.vertex_triangle) {
    const Tri& tri = s.triangles[t];
    EXPECT_TRUE(s.vertices[v] != tri[0] && s.vertices[v] != tri[1] && s.vertices[v] != tri[2]);
  }
  for (const auto& [a, b] : got.edge_edge) {
    EXPECT_LT(a, b);
    const auto &ea = s.edges[a], &eb = s.edges[b];
    EXPECT_TRUE(ea[0] != eb[0] && ea[0] != eb[1] && ea[1] != eb[0] && ea[1] != eb[1]);
  }
}

TEST(BroadPhase, RejectsPositionsThatMissPointsAndBadInflation) {
  const SurfaceTopology s = make_surface_topology(grid_triangles(3, 3));
  const VecX x = flat_grid(3, 3, 1.0);
  Candidates c;
  BroadPhase bp(&s);
  EXPECT_THROW(bp.find(x.head(3 * 8), 0.1, c), Error);
  EXPECT_THROW(bp.find(x, -0.1, c), Error);
  EXPECT_THROW(bp.find_swept(x, x.head(3), 0.1, c), Error);
  VecX bad = x;
  bad[3 * 4 + 1] = std::nan("");
  try {
    bp.find(bad, 0.1, c);
    FAIL();
  } catch (const SolveError& e) {
    EXPECT_NE(std::string(e.what()).find("point 4"), std::string::npos) << e.what();
  }
  EXPECT_THROW(bp.find_swept(x, bad, 0.1, c), SolveError);
  bp.find(x, 0.0, c);
  // Touching boxes overlap: a grid at inflation 0 has the pairs of neighbouring cells whose boxes share a side.
  EXPECT_FALSE(c.vertex_triangle.empty());
}

}  // namespace
}  // namespace mgcloth::collision
