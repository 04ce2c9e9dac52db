// Cloth–cloth contact: the layer's energy, the term's derivatives, neighbour filtering and step limits.
#include <mgcloth/collision/distance.hpp>
#include <mgcloth/collision/intersections.hpp>
#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/physics/cloth_contact.hpp>

#include "contact_fixtures.hpp"
#include "term_checks.hpp"

#include <gtest/gtest.h>

#include <random>

namespace mgcloth::physics {
namespace {

using fixtures::sheet;

TEST(ContactLayer, DerivativesAndSmoothnessAtBothJunctions) {
  const ContactLayer L(1e-3, 0.25, 2.0);
  for (double d : {0.05e-3, 0.2e-3, 0.3e-3, 0.6e-3, 0.95e-3}) {
    double d1 = 0, d2 = 0;
    L.value(d, &d1, &d2);
    const double h = 1e-9;
    double a1 = 0, b1 = 0;
    const double fd1 = (L.value(d + h) - L.value(d - h)) / (2 * h);
    L.value(d + h, &a1);
    L.value(d - h, &b1);
    EXPECT_NEAR(d1, fd1, 1e-6 * std::abs(d1) + 1e-9) << d;
    EXPECT_NEAR(d2, (a1 - b1) / (2 * h), 1e-5 * std::abs(d2) + 1e-6) << d;
    EXPECT_LT(d1, 0.0);  // repulsive everywhere inside the layer
    EXPECT_GT(d2, 0.0);  // convex in d
  }
  // C²: value, slope and curvature continuous where the barrier starts (τ) and where the layer ends (r).
  for (double at : {L.tau, L.r}) {
    double l1 = 0, l2 = 0, r1 = 0, r2 = 0;
    const double lv = L.value(at * (1 - 1e-9), &l1, &l2), rv = L.value(at * (1 + 1e-9), &r1, &r2);
    EXPECT_NEAR(lv, rv, 1e-9 * L.k * L.r * L.r + 1e-18);
    EXPECT_NEAR(l1, r1, 1e-6 * L.k * L.r);
    EXPECT_NEAR(l2, r2, 1e-5 * L.k);
  }
  // Bounded curvature in the outer layer [τ, r): the cubic's 2k at most; unbounded approaching zero.
  for (double d = L.tau; d < L.r; d += 0.01e-3) {
    double d2 = 0;
    L.value(d, nullptr, &d2);
    EXPECT_LE(d2, 2.0 * L.k * (1 + 1e-12));
  }
  // The barrier's energy grows without bound (logarithmically) and its force like 1/d as d → 0.
  EXPECT_GT(L.value(1e-12), L.value(1e-9));
  EXPECT_GT(L.value(1e-9), L.value(1e-6));
  double f_near = 0, f_half = 0;
  L.value(1e-9, &f_near);
  L.value(L.tau / 2, &f_half);
  EXPECT_GT(-f_near, 1e4 * -f_half);
  EXPECT_EQ(L.value(0.0), kInf);
  EXPECT_EQ(L.value(L.r), 0.0);
}

// Two small sheets a fraction of the layer apart, perturbed: every pair type shows up.
TEST(ClothContact, GradientAndHessianMatchFiniteDifferences) {
  for (unsigned seed : {1u, 2u, 3u}) {
    VecX x;
    std::vector<ContactSurface> s;
    s.push_back(sheet("a", 0.02, 16, 0.0, 0, x));
    s.push_back(sheet("b", 0.02, 16, 0.5e-3, static_cast<Index>(x.size() / 3), x));
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-0.15e-3, 0.15e-3);
    for (Index i = 0; i < x.size(); ++i) x[i] += u(rng);
    // Shift the top sheet sideways so that its vertices sit over triangle interiors and edges cross.
    for (Index i = s[1].offset; i < x.size() / 3; ++i) x.segment<2>(3 * i) += Vec2(0.0031, 0.0017);
    ClothContact c(s, static_cast<Index>(x.size() / 3), ClothContactParams{});
    c.update_stencils(x);
    EXPECT_GT(c.stats(x).pairs, 10);
    EXPECT_GT(c.value(x), 0.0);
    check_term(c, x, 1e-5);
  }
}

TEST(ClothContact, FlatSheetAtRestHasNoContactAndNoEnergy) {
  // Edges of 1 cm under a 1 mm and a 5 mm layer: only topological and material-space neighbours are that near.
  for (double thickness : {1e-3, 5e-3}) {
    VecX x;
    std::vector<ContactSurface> s{sheet("a", 0.3, 900, 0.0, 0, x, thickness)};
    ClothContact c(s, static_cast<Index>(x.size() / 3), ClothContactParams{});
    EXPECT_EQ(c.value(x), 0.0);
    EXPECT_EQ(c.stats(x).pairs, 0);
  }
}

TEST(ClothContact, MaterialSpaceNeighboursAreNotContact) {
  // Edges of 1 cm under a 3 cm layer: every pair of the flat sheet is a material-space neighbour.
  VecX x;
  std::vector<ContactSurface> s{sheet("a", 0.1, 121, 0.0, 0, x, 0.03)};
  ClothContact c(s, static_cast<Index>(x.size() / 3), ClothContactParams{});
  EXPECT_EQ(c.stats(x).pairs, 0);
  // The same sheet folded onto itself: the halves are far apart in material space and do touch.
  VecX y = x;
  for (Index i = 0; i < y.size() / 3; ++i)
    if (y[3 * i] > 0.05) {
      y[3 * i] = 0.1 - y[3 * i];
      y[3 * i + 2] = 0.01;
    }
  EXPECT_GT(c.stats(y).pairs, 0);
}

// Where the mesh spacing is below the layer, primitives near on the cloth get half their material distance as
// their layer: a compression cloth meets in folds and at seams (10%) stays free of contact forces, a crush to a third
// of the spacing meets a barrier (without one, a seam pulling a 3 mm mesh under a 2 mm layer squeezed such pairs to
// rounding distances, and they crossed).
TEST(ClothContact, PrimitivesNearOnTheClothRepelOnlyWhenCrushed) {
  VecX x;
  std::vector<ContactSurface> s{sheet("a", 0.1, 121, 0.0, 0, x, 0.03)};  // 1 cm edges, 3 cm layer
  const Index n = static_cast<Index>(x.size() / 3);
  const auto squeezed = [&](double f) {
    VecX y = x;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-0.5e-3, 0.5e-3);
    for (Index i = 0; i < n; ++i) {
      y[3 * i] = f * y[3 * i] + u(rng);  // no ties (parallel edges, coplanar points) in the distances
      y[3 * i + 1] += u(rng);
      y[3 * i + 2] += u(rng);
    }
    return y;
  };
  ClothContact c(s, n, ClothContactParams{});
  EXPECT_EQ(c.value(x), 0.0);
  const VecX mild = squeezed(0.9);
  EXPECT_EQ(c.stats(mild).pairs, 0);
  EXPECT_EQ(c.value(mild), 0.0);
  const VecX crushed = squeezed(0.3);
  c.update_stencils(crushed);
  EXPECT_GT(c.stats(crushed).pairs, 100);
  EXPECT_GT(c.value(crushed), 0.0);
  // It pushes the crushed sheet back open: the energy falls along the stretch that undoes the crush.
  VecX open = VecX::Zero(x.size());
  for (Index i = 0; i < n; ++i) open[3 * i] = crushed[3 * i] - 0.015;
  VecX g = VecX::Zero(x.size());
  c.add_gradient(crushed, g);
  EXPECT_LT(g.dot(open), 0.0);
  check_term(c, crushed, 1e-5);
}

// Two panels of one garment, each its own chart over the same material square (as a sewing pattern's panels are):
// panel b is copied from panel a, its points after a's.
ContactSurface two_panels(VecX& x) {
  ContactSurface s = fixtures::sheet("garment", 0.05, 36, 0.0, 0, x);
  const Index n = s.material.cols();
  s.material.conservativeResize(2, 2 * n);
  s.material.rightCols(n) = s.material.leftCols(n);
  for (Index t = 0, nt = static_cast<Index>(s.tris.size()); t < nt; ++t) {
    const Tri a = s.tris[static_cast<size_t>(t)];
    s.tris.push_back({a[0] + n, a[1] + n, a[2] + n});
  }
  s.area.conservativeResize(2 * n);
  s.area.tail(n) = s.area.head(n);
  x.conservativeResize(6 * n);
  x.tail(3 * n) = x.head(3 * n);
  return s;
}

// A mesh finer than the cache's margins: a cache that reached r + 2δ for every pair held each point's neighbours on
// the cloth (on the full-size dress 4.4M pairs, 74K in contact). Pairs of one piece reach their own layer, so a
// sheet at rest with a spacing of 1.5 r caches none of them; folded, the halves meet and are cached.
TEST(ClothContact, TheCacheHoldsNoNeighboursOnTheClothThatCannotEnterTheirLayer) {
  VecX x;
  std::vector<ContactSurface> s{sheet("a", 0.045, 961, 0.0, 0, x, 1e-3)};
  ClothContact c(s, static_cast<Index>(x.size() / 3), ClothContactParams{});
  const ContactStats rest = c.stats(x);
  EXPECT_EQ(rest.cached, 0);
  EXPECT_EQ(rest.pairs, 0);
  VecX y = x;
  for (Index i = 0; i < y.size() / 3; ++i)
    if (y[3 * i] > 0.0225) {
      y[3 * i] = 0.045 - y[3 * i];
      y[3 * i + 2] = 1.2e-3;
    }
  const ContactStats folded = c.stats(y);
  EXPECT_GT(folded.cached, 0);
  EXPECT_EQ(folded.pairs, 0);  // 1.2 mm apart, outside the 1 mm layer
  y.reshaped(3, y.size() / 3).row(2) *= 0.5;
  EXPECT_GT(c.stats(y).pairs, 0);
}

TEST(ClothContact, PanelsOfOneClothWhoseChartsOverlapStillTouch) {
  VecX x;
  const ContactSurface s = two_panels(x);
  const Index n = s.material.cols() / 2;
  // Panel b lies half the layer above panel a, shifted: the same material points, but not neighbours on the cloth.
  for (Index i = n; i < 2 * n; ++i) x.segment<3>(3 * i) += Vec3(0.0031, 0.0017, 0.5e-3);
  ClothContact c({s}, 2 * n, ClothContactParams{});
  c.update_stencils(x);
  EXPECT_GT(c.stats(x).pairs, 10);
  EXPECT_GT(c.value(x), 0.0);
}

TEST(ClothContact, TheTwoSidesOfAClosedSeamAreNotContactPairs) {
  VecX x;
  ContactSurface s = two_panels(x);
  const Index n = s.material.cols() / 2;
  // Panel b stands upright on a's edge u = 0.05, sewn to it there: both sides of the seam coincide.
  for (Index i = n; i < 2 * n; ++i) {
    const Vec2 u = s.material.col(i);
    x.segment<3>(3 * i) = Vec3(0.05, u.y(), 0.05 - u.x());
  }
  for (Index i = 0; i < n; ++i)
    if (std::abs(s.material(0, i) - 0.05) < 1e-12) s.stitch_groups.push_back({i, i + n});
  ASSERT_GE(s.stitch_groups.size(), 5u);
  ContactSurface unsewn = s;
  unsewn.stitch_groups.clear();
  // Unsewn, the coincident points are contact at distance 0; sewn, the seam is where the panels join.
  ClothContact cut({unsewn}, 2 * n, ClothContactParams{});
  cut.update_stencils(x);
  EXPECT_GT(cut.stats(x).pairs, 0);
  EXPECT_EQ(cut.value(x), kInf);
  ClothContact c({s}, 2 * n, ClothContactParams{});
  c.close_seams(x);
  c.update_stencils(x);
  EXPECT_EQ(c.stats(x).pairs, 0);
  EXPECT_EQ(c.value(x), 0.0);
  // Panel b sliding along the seam is not stopped by the seam's own points.
  VecX slide = VecX::Zero(x.size());
  for (Index i = n; i < 2 * n; ++i) slide[3 * i + 1] = 1e-3;
  EXPECT_EQ(c.max_step(x, slide, 1.0), 1.0);
  // The checker sees the closed seam as joined: no crossing; without the joining, the triangles touch there.
  EXPECT_GT(collision::find_intersections(x, c.triangles()).size(), 0u);
  EXPECT_EQ(collision::find_intersections(x, c.triangles(), 100, nullptr, SIZE_MAX, &c.joined_points()).size(), 0u);
  // An open seam (the panel lifted 1 cm) is not joined, and its two sides are contact like any primitives: the
  // panel coming down onto its seam is stopped by the layer.
  VecX open = x;
  for (Index i = n; i < 2 * n; ++i) open[3 * i + 2] += 0.01;
  c.close_seams(open);
  EXPECT_EQ(c.joined_points()[static_cast<size_t>(s.stitch_groups[0][1])], s.stitch_groups[0][1]);
  VecX down = VecX::Zero(x.size());
  for (Index i = n; i < 2 * n; ++i) down[3 * i + 2] = -0.01;
  EXPECT_LT(c.max_step(open, down, 1.0), 1.0);
  c.close_seams(x);
  EXPECT_EQ(c.max_step(open, down, 1.0), 1.0);
  // Folded flat onto panel a (inside its layer), panel b's interior is contact again, away from the seam.
  VecX flat = x;
  for (Index i = n; i < 2 * n; ++i) {
    const Vec2 u = s.material.col(i);
    flat.segment<3>(3 * i) = Vec3(0.05 - 0.9 * (0.05 - u.x()), u.y(), 0.5e-3 * (0.05 - u.x()) / 0.05 + 0.3e-3);
  }
  c.update_stencils(flat);
  EXPECT_GT(c.stats(flat).pairs, 10);
}

TEST(ClothContact, MaxStepStopsASheetBeforeItPassesThroughAnother) {
  VecX x;
  std::vector<ContactSurface> s;
  s.push_back(sheet("a", 0.05, 36, 0.0, 0, x));
  const Index top = static_cast<Index>(x.size() / 3);
  s.push_back(sheet("b", 0.05, 36, 0.01, top, x));
  ClothContact c(s, static_cast<Index>(x.size() / 3), ClothContactParams{});
  for (Index i = top; i < x.size() / 3; ++i) x.segment<2>(3 * i) += Vec2(0.002, 0.003);
  // The top sheet tilts down through the bottom one in one step (its far edge 2 cm down, so that the end state
  // crosses it); its far edge meets the bottom sheet at α ≈ 0.52.
  VecX d = VecX::Zero(x.size());
  for (Index i = top; i < x.size() / 3; ++i) d[3 * i + 2] = -0.02 * (x[3 * i] - 0.002) / 0.05;
  const double a = c.max_step(x, d, 1.0);
  EXPECT_GT(a, 0.3);
  EXPECT_LT(a, 0.52);
  const VecX y = x + a * d;
  EXPECT_EQ(collision::find_intersections(y, c.triangles()).size(), 0u);
  EXPECT_GT(collision::find_intersections(x + d, c.triangles()).size(), 0u);
  // Moving apart, or sideways in its own plane, is not limited.
  VecX down = VecX::Zero(x.size());
  for (Index i = top; i < x.size() / 3; ++i) down[3 * i + 2] = -0.02;
  EXPECT_EQ(collision::find_intersections(x + down, c.triangles()).size(), 0u);  // passed through: only CCD sees it
  EXPECT_LT(c.max_step(x, down, 1.0), 0.5);
  EXPECT_EQ(c.max_step(x, -d, 1.0), 1.0);
  VecX side = VecX::Zero(x.size());
  for (Index i = top; i < x.size() / 3; ++i) side[3 * i] = 0.05;
  EXPECT_EQ(c.max_step(x, side, 1.0), 1.0);
}

// A step that moves one sheet through another by forty times the mesh spacing is checked in pieces (so that a
// rebuild along it does not hold every pair its swept boxes meet): the impact in the first piece, or in a later one,
// still stops it just before the sheets meet, and a step moving them apart as far is not limited at all.
TEST(ClothContact, ALongStepIsCheckedInPiecesAndStopsAtItsImpact) {
  for (double gap : {0.01, 0.06}) {
    VecX x;
    std::vector<ContactSurface> s;
    s.push_back(sheet("a", 0.05, 121, 0.0, 0, x));  // 5 mm spacing
    const Index top = static_cast<Index>(x.size() / 3);
    s.push_back(sheet("b", 0.05, 121, gap, top, x));
    const Index n = static_cast<Index>(x.size() / 3);
    for (Index i = top; i < n; ++i) x.segment<2>(3 * i) += Vec2(0.0013, 0.0021);
    ClothContact c(s, n, ClothContactParams{});
    VecX d = VecX::Zero(x.size());
    for (Index i = top; i < n; ++i) d[3 * i + 2] = -0.2;
    const double impact = gap / 0.2;
    const double a = c.max_step(x, d, 1.0);
    EXPECT_LT(a, impact) << gap;
    // A piece moves the top sheet 1 cm (5 mm relative to the mean), so the pair closes to ccd_separation of at most
    // 1 cm: the sheet stops within about 1 mm of the other, α within 0.005 of the impact (0.0075 with the CCD's
    // margin). Checked whole, the 6 cm gap would stop at 6 mm (α = 0.27).
    EXPECT_GT(a, impact - 0.0075) << gap;
    const VecX y = x + a * d;
    EXPECT_EQ(collision::find_intersections(y, c.triangles()).size(), 0u) << gap;
    ClothContact fresh(s, n, ClothContactParams{});
    EXPECT_GT(fresh.stats(y).min_distance, 0.0) << gap;
    EXPECT_EQ(c.max_step(x, -d, 1.0), 1.0) << gap;
  }
}

TEST(ClothContact, CachedPairsGiveTheSameEnergyAsAFreshTerm) {
  VecX x;
  std::vector<ContactSurface> s;
  s.push_back(sheet("a", 0.03, 25, 0.0, 0, x));
  const Index top = static_cast<Index>(x.size() / 3);
  s.push_back(sheet("b", 0.03, 25, 2e-3, top, x));
  ClothContact cached(s, static_cast<Index>(x.size() / 3), ClothContactParams{});
  EXPECT_EQ(cached.value(x), 0.0);
  // Small moves reuse the cache (within δ), larger ones rebuild it; both must see what a fresh term sees.
  for (double dz : {-0.4e-3, -0.9e-3, -1.3e-3, -1.6e-3, -1.9e-3}) {
    VecX y = x;
    for (Index i = top; i < y.size() / 3; ++i) y[3 * i + 2] += dz;
    ClothContact fresh(s, static_cast<Index>(x.size() / 3), ClothContactParams{});
    EXPECT_DOUBLE_EQ(cached.value(y), fresh.value(y)) << dz;
  }
  // After max_step along a long step the cache holds (the last checked piece of) the segment: trial points on it,
  // and before it, see every pair.
  VecX d = VecX::Zero(x.size());
  for (Index i = top; i < x.size() / 3; ++i) d.segment<3>(3 * i) = Vec3(0.004, -0.003, -0.0035);
  const double a = cached.max_step(x, d, 1.0);
  EXPECT_GT(a, 0.3);
  for (double f : {1.0, 0.8, 0.5, 0.25}) {
    const VecX y = x + f * a * d;
    ClothContact fresh(s, static_cast<Index>(x.size() / 3), ClothContactParams{});
    EXPECT_DOUBLE_EQ(cached.value(y), fresh.value(y)) << f;
    if (f == 1.0) {
      EXPECT_GT(fresh.value(y), 0.0);
    }
  }
}

// A stack moving far as a whole while its sheets move a little relative to each other: the cache follows the common
// motion, so every trial point must still see what a fresh term sees, and no step may let two primitives touch.
TEST(ClothContact, AStackMovingAsAWholeKeepsEnergyAndStepLimitsExact) {
  VecX x;
  std::vector<ContactSurface> s;
  s.push_back(sheet("a", 0.03, 25, 0.0, 0, x));
  const Index top = static_cast<Index>(x.size() / 3);
  s.push_back(sheet("b", 0.03, 25, 1.4e-3, top, x));
  const Index n = static_cast<Index>(x.size() / 3);
  ClothContact cached(s, n, ClothContactParams{});
  const collision::SurfaceTopology topo = collision::make_surface_topology(cached.triangles());
  const auto shares = [](const auto& a, const auto& b) {
    for (Index i : a)
      for (Index j : b)
        if (i == j) return true;
    return false;
  };
  // The smallest distance over every pair of primitives that share no point (brute force).
  const auto min_distance = [&](const VecX& y) {
    const auto p = [&](Index i) { return Vec3(y.segment<3>(3 * i)); };
    double best = kInf;
    for (Index v : topo.vertices)
      for (const Tri& t : topo.triangles)
        if (!shares(std::array<Index, 1>{v}, t))
          best = std::min(best, collision::point_triangle_distance_sq(p(v), p(t[0]), p(t[1]), p(t[2])));
    for (size_t a = 0; a < topo.edges.size(); ++a)
      for (size_t b = a + 1; b < topo.edges.size(); ++b)
        if (!shares(topo.edges[a], topo.edges[b]))
          best = std::min(best, collision::edge_edge_distance_sq(p(topo.edges[a][0]), p(topo.edges[a][1]),
                                                                 p(topo.edges[b][0]), p(topo.edges[b][1])));
    return std::sqrt(best);
  };
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int limited = 0;
  for (int k = 0; k < 12; ++k) {
    // Centimetres of common motion, up to a millimetre of relative motion (the top sheet pushed down on average).
    const Vec3 common(0.03 * u(rng), 0.03 * u(rng), 0.05 * u(rng));
    VecX d(x.size());
    for (Index i = 0; i < n; ++i) {
      const Vec3 rel = i < top ? Vec3::Zero() : Vec3(0.3e-3 * u(rng), 0.3e-3 * u(rng), 0.6e-3 * (u(rng) - 0.5));
      d.segment<3>(3 * i) = common + rel;
    }
    const double a = cached.max_step(x, d, 1.0);
    ASSERT_GT(a, 0.0);
    if (a < 1.0) ++limited;
    for (double f : {1.0, 0.7, 0.4, 0.1}) {
      const VecX y = x + f * a * d;
      ClothContact fresh(s, n, ClothContactParams{});
      // The same pairs; a cache updated locally holds them in another order, so the sums differ by round-off.
      const double want = fresh.value(y);
      EXPECT_NEAR(cached.value(y), want, 1e-12 * std::abs(want)) << k << " " << f;
      EXPECT_GT(min_distance(y), 0.0) << k << " " << f;
    }
    EXPECT_EQ(collision::find_intersections(x + a * d, cached.triangles()).size(), 0u) << k;
    x += 0.9 * a * d;
  }
  EXPECT_GT(limited, 0);  // the sheets did meet: some steps were stopped
}

// Patches of a few points pushed through the sheet below: the cache is updated for those points alone and the
// collision detection searches only their pairs along the step, yet energy and gradient equal a fresh term's, and no
// step lets a pair reach zero distance (brute force over every pair of the patch) or the sheets intersect.
TEST(ClothContact, LocalUpdatesOfTheCacheKeepEnergyGradientAndStepLimitsExact) {
  VecX x;
  std::vector<ContactSurface> s;
  s.push_back(sheet("a", 0.06, 400, 0.0, 0, x));
  const Index top = static_cast<Index>(x.size() / 3);
  // Farther apart than the cache's reach (r + 2δ = 1.5 mm), so that the pairs a patch meets are not cached yet.
  s.push_back(sheet("b", 0.06, 400, 2.5e-3, top, x));
  const Index n = static_cast<Index>(x.size() / 3);
  ClothContact cached(s, n, ClothContactParams{});
  const collision::SurfaceTopology topo = collision::make_surface_topology(cached.triangles());
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<Index> pick(top, n - 1);
  int limited = 0;
  EXPECT_EQ(cached.value(x), 0.0);
  for (int k = 0; k < 16; ++k) {
    const Vec3 centre = x.segment<3>(3 * pick(rng));
    std::vector<char> in_patch(static_cast<size_t>(n), 0);
    VecX d = VecX::Zero(x.size());
    Index count = 0;
    for (Index i = top; i < n; ++i)
      if ((x.segment<2>(3 * i) - centre.head<2>()).norm() < 6e-3) {
        in_patch[static_cast<size_t>(i)] = 1;
        ++count;
        d.segment<3>(3 * i) = Vec3(0.5e-3 * u(rng), 0.5e-3 * u(rng), -5e-3 * (1.0 + 0.5 * u(rng)));
      }
    ASSERT_GT(count, 2);
    ASSERT_LT(count, n / 8);
    const double a = cached.max_step(x, d, 1.0);
    ASSERT_GT(a, 0.0);
    if (a < 1.0) ++limited;
    for (double f : {1.0, 0.5}) {
      const VecX y = x + f * a * d;
      ClothContact fresh(s, n, ClothContactParams{});
      const double want = fresh.value(y);
      EXPECT_NEAR(cached.value(y), want, 1e-12 * std::abs(want)) << k << " " << f;
      VecX g1 = VecX::Zero(x.size()), g2 = VecX::Zero(x.size());
      cached.add_gradient(y, g1);
      fresh.add_gradient(y, g2);
      EXPECT_LE((g1 - g2).norm(), 1e-10 * (1.0 + g2.norm())) << k << " " << f;
    }
    const VecX y = x + a * d;
    const auto p = [&](Index i) { return Vec3(y.segment<3>(3 * i)); };
    const auto patch = [&](Index i) { return in_patch[static_cast<size_t>(i)] != 0; };
    double closest = kInf;
    for (Index v : topo.vertices)
      for (const Tri& t : topo.triangles)
        if (v != t[0] && v != t[1] && v != t[2] && (patch(v) || patch(t[0]) || patch(t[1]) || patch(t[2])))
          closest = std::min(closest, collision::point_triangle_distance_sq(p(v), p(t[0]), p(t[1]), p(t[2])));
    for (size_t e = 0; e < topo.edges.size(); ++e)
      for (size_t f = 0; f < topo.edges.size(); ++f) {
        const auto &A = topo.edges[e], &B = topo.edges[f];
        if (e == f || A[0] == B[0] || A[0] == B[1] || A[1] == B[0] || A[1] == B[1]) continue;
        if (patch(A[0]) || patch(A[1]))
          closest = std::min(closest, collision::edge_edge_distance_sq(p(A[0]), p(A[1]), p(B[0]), p(B[1])));
      }
    EXPECT_GT(closest, 0.0) << k;
    EXPECT_EQ(collision::find_intersections(y, cached.triangles()).size(), 0u) << k;
    x += 0.9 * a * d;
  }
  EXPECT_GT(limited, 8);  // most patches did reach the sheet below
}

// Two sheets as in test GradientAndHessianMatchFiniteDifferences, the upper one kinematic (an obstacle mesh): the
// unknown is the lower sheet alone, and the upper sheet's points follow it as kinematic points.
struct SheetUnderObstacle {
  VecX x;                 ///< both sheets, as one unknown
  VecX lower, upper;      ///< the lower sheet's points (the unknown), the upper's (kinematic)
  std::vector<ContactSurface> both;  ///< both as cloths
  std::vector<ContactSurface> split;  ///< the upper one kinematic
  explicit SheetUnderObstacle(unsigned seed, double gap = 0.5e-3) {
    both.push_back(sheet("a", 0.02, 16, 0.0, 0, x));
    both.push_back(sheet("b", 0.02, 16, gap, static_cast<Index>(x.size() / 3), x));
    // Only the lower sheet is jittered: the upper one stays flat, so that its areas in space (an obstacle's) equal
    // those in its material (a cloth's), and the two terms below weigh its pairs alike.
    const Index na = both[1].offset;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-0.15e-3, 0.15e-3);
    for (Index i = 0; i < 3 * na; ++i) x[i] += u(rng);
    for (Index i = na; i < x.size() / 3; ++i) x.segment<2>(3 * i) += Vec2(0.0031, 0.0017);
    lower = x.head(3 * na);
    upper = x.tail(x.size() - 3 * na);
    split = both;
    split[1].kinematic = true;
    split[1].offset = 0;
  }
  Index lower_points() const { return static_cast<Index>(lower.size() / 3); }
};

// The same pairs, energy, gradient rows and Hessian block as when the obstacle's points were unknowns too, and
// derivatives that match finite differences of the unknown alone.
TEST(ClothContact, AKinematicSurfaceActsOnTheClothAsTheSameSurfaceAsAnUnknownWould) {
  for (unsigned seed : {1u, 2u, 3u}) {
    SheetUnderObstacle s(seed);
    ClothContact full(s.both, static_cast<Index>(s.x.size() / 3), ClothContactParams{});
    ClothContact kin(s.split, s.lower_points(), ClothContactParams{}, s.upper);
    EXPECT_EQ(kin.num_kinematic(), static_cast<Index>(s.upper.size() / 3));
    full.update_stencils(s.x);
    kin.update_stencils(s.lower);
    EXPECT_GT(kin.stats(s.lower).pairs, 10);
    EXPECT_EQ(kin.stats(s.lower).pairs, full.stats(s.x).pairs);
    EXPECT_NEAR(kin.value(s.lower), full.value(s.x), 1e-12 * full.value(s.x));
    VecX gk = VecX::Zero(s.lower.size()), gf = VecX::Zero(s.x.size());
    kin.add_gradient(s.lower, gk);
    full.add_gradient(s.x, gf);
    EXPECT_LE((gk - gf.head(s.lower.size())).norm(), 1e-12 * gf.norm());
    std::vector<std::pair<Index, Index>> pk, pf;
    kin.collect_pattern(pk);
    full.collect_pattern(pf);
    linalg::BlockMatrix3 Hk(s.lower_points(), pk), Hf(static_cast<Index>(s.x.size() / 3), pf);
    kin.bind(Hk);
    full.bind(Hf);
    Hk.set_zero();
    Hf.set_zero();
    kin.add_hessian(s.lower, Hk, true);
    full.add_hessian(s.x, Hf, true);
    const Eigen::MatrixXd Dk(Hk.to_sparse()), Df(Hf.to_sparse());
    const Index m = s.lower.size();
    EXPECT_LE((Dk - Df.topLeftCorner(m, m)).norm(), 1e-12 * Df.norm());
    check_term(kin, s.lower, 1e-5);
    // The checker sees both sheets, in the numbering of triangles().
    EXPECT_EQ(kin.with_kinematic(s.lower), s.x);
    EXPECT_EQ(collision::find_intersections(kin.with_kinematic(s.lower), kin.triangles()).size(), 0u);
  }
}

TEST(ClothContact, AKinematicSurfaceNeverTouchesItself) {
  // A sheet folded onto itself touches itself as a cloth (MaterialSpaceNeighboursAreNotContact); as an obstacle it
  // does not, and a cloth far from it sees nothing either.
  VecX y;
  std::vector<ContactSurface> s{sheet("obstacle", 0.1, 121, 0.0, 0, y, 0.03)};
  for (Index i = 0; i < y.size() / 3; ++i)
    if (y[3 * i] > 0.05) {
      y[3 * i] = 0.1 - y[3 * i];
      y[3 * i + 2] = 0.01;
    }
  s[0].kinematic = true;
  VecX x;
  s.insert(s.begin(), sheet("cloth", 0.05, 36, 0.5, 0, x));  // kinematic surfaces come last
  ClothContact c(s, static_cast<Index>(x.size() / 3), ClothContactParams{}, y);
  EXPECT_EQ(c.stats(x).pairs, 0);
  EXPECT_EQ(c.value(x), 0.0);
  VecX down = VecX::Zero(x.size());
  for (Index i = 0; i < x.size() / 3; ++i) down[3 * i + 2] = -0.4;  // still 7 cm above the fold
  EXPECT_EQ(c.max_step(x, down, 1.0), 1.0);
}

TEST(ClothContact, MaxStepStopsAClothBeforeItPassesThroughAnObstacleMesh) {
  // As MaxStepStopsASheetBeforeItPassesThroughAnother, with the lower sheet an obstacle.
  VecX y, x;
  std::vector<ContactSurface> s;
  s.push_back(sheet("obstacle", 0.05, 36, 0.0, 0, y));
  s.back().kinematic = true;
  s.insert(s.begin(), sheet("cloth", 0.05, 36, 0.01, 0, x));  // kinematic surfaces come last
  for (Index i = 0; i < x.size() / 3; ++i) x.segment<2>(3 * i) += Vec2(0.002, 0.003);
  ClothContact c(s, static_cast<Index>(x.size() / 3), ClothContactParams{}, y);
  VecX d = VecX::Zero(x.size());
  for (Index i = 0; i < x.size() / 3; ++i) d[3 * i + 2] = -0.02 * (x[3 * i] - 0.002) / 0.05;
  const double a = c.max_step(x, d, 1.0);
  EXPECT_GT(a, 0.3);
  EXPECT_LT(a, 0.52);
  EXPECT_EQ(collision::find_intersections(c.with_kinematic(x + a * d), c.triangles()).size(), 0u);
  EXPECT_GT(collision::find_intersections(c.with_kinematic(x + d), c.triangles()).size(), 0u);
  EXPECT_TRUE(std::isfinite(c.value(x + a * d)));
  EXPECT_EQ(c.max_step(x, -d, 1.0), 1.0);
}

TEST(ClothContact, MaxJointStepStopsAnObstacleMovingIntoAClothUnlessTheClothMovesAlong) {
  VecX y, x;
  std::vector<ContactSurface> s;
  s.push_back(sheet("obstacle", 0.05, 36, -0.01, 0, y));
  s.back().kinematic = true;
  s.insert(s.begin(), sheet("cloth", 0.05, 36, 0.0, 0, x));  // kinematic surfaces come last
  for (Index i = 0; i < x.size() / 3; ++i) x.segment<2>(3 * i) += Vec2(0.002, 0.003);
  ClothContact c(s, static_cast<Index>(x.size() / 3), ClothContactParams{}, y);
  // The obstacle rises 2 cm, through the cloth at half way: the check stops it where the gap is down to a tenth.
  VecX up = VecX::Zero(y.size());
  for (Index i = 0; i < y.size() / 3; ++i) up[3 * i + 2] = 0.02;
  const VecX still = VecX::Zero(x.size());
  const double f = c.max_joint_step(x, still, y + up);
  EXPECT_GT(f, 0.4);
  EXPECT_LT(f, 0.5);
  c.set_kinematic_positions(y + f * up);
  EXPECT_TRUE(std::isfinite(c.value(x)));
  EXPECT_EQ(collision::find_intersections(c.with_kinematic(x), c.triangles()).size(), 0u);
  // Carried along, the cloth lets it go all the way; the check starts from where the obstacle is now.
  VecX carried = VecX::Zero(x.size());
  for (Index i = 0; i < x.size() / 3; ++i) carried[3 * i + 2] = 0.02;
  EXPECT_EQ(c.max_joint_step(x, carried, y + f * up + up), 1.0);
  EXPECT_THROW(c.set_kinematic_positions(VecX::Zero(3)), Error);
  EXPECT_THROW(c.max_joint_step(x, still, VecX::Zero(3)), Error);
}

TEST(ClothContact, RejectsBadParameters) {
  VecX x;
  std::vector<ContactSurface> s{sheet("a", 0.03, 25, 0.0, 0, x)};
  ClothContactParams p;
  p.stiffness = -1.0;
  EXPECT_THROW(ClothContact(s, static_cast<Index>(x.size() / 3), p), InputError);
  p = {};
  p.ccd_separation = 1.0;
  EXPECT_THROW(ClothContact(s, static_cast<Index>(x.size() / 3), p), InputError);
  s[0].thickness = std::nan("");
  EXPECT_THROW(ClothContact(s, static_cast<Index>(x.size() / 3), ClothContactParams{}), InputError);
}

}  // namespace
}  // namespace mgcloth::physics
