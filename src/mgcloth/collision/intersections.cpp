#include <mgcloth/collision/intersections.hpp>
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

#include <algorithm>

namespace mgcloth::collision {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Segment = Kernel::Segment_3;
using Triangle = Kernel::Triangle_3;
// Boxes identified by the address of their triangle: thread-safe, unlike ID_EXPLICIT's global counter.
using Box = CGAL::Box_intersection_d::Box_with_handle_d<double, 3, const Tri*>;

/// Whether two non-degenerate triangles intersect anywhere but in what they share by construction.
///
/// - No shared vertex: any common point, touching included (a zero distance is what contact must prevent).
/// - One shared vertex v, A = (v, a0, a1), B = (v, b0, b1): they meet elsewhere iff the edge of one opposite v meets
///   the other triangle. If [a0, a1] meets B at q, q ≠ v (v is not on the opposite edge of a non-degenerate
///   triangle), so they meet elsewhere. Conversely, if A and B are not coplanar, A ∩ B lies on the line L where their
///   planes meet, which passes through v; A ∩ L is a segment [v, p] (v is an extreme point of A, so it is an end)
///   with p on [a0, a1], likewise B ∩ L = [v, q] with q on [b0, b1]; if they overlap beyond v, the shorter one's far
///   end lies in the other triangle. If A and B are coplanar, they meet beyond v iff their angles at v share a ray
///   from v; along that ray each triangle holds a segment from v ending on its opposite edge, and again the shorter
///   one's end lies in the other triangle. So the rule is exact in every case, touching included (a coplanar fan
///   whose angles share only a side overlaps along that side, which counts).
/// - A shared edge uw, A = (u, w, a), B = (u, w, b): if a, b and uw are not coplanar, the planes meet only in the
///   line uw and A ∩ B = [u, w]. Coplanar with a and b on opposite sides of uw, A ∩ B = [u, w] too (a flat sheet).
///   Coplanar on the same side, they overlap in a region: a fold pressed flat onto itself.
/// - Three shared vertices: the same triangle twice, which overlaps itself everywhere.
bool intersect_beyond_shared(const Tri& ta, const std::array<Point, 3>& A, const Tri& tb,
                             const std::array<Point, 3>& B) {
  int shared = 0, ia[3], ib[3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (ta[i] == tb[j]) {
        ia[shared] = i;
        ib[shared] = j;
        ++shared;
      }
  switch (shared) {
    case 0:
      return CGAL::do_intersect(Triangle(A[0], A[1], A[2]), Triangle(B[0], B[1], B[2]));
    case 1: {
      const int i = ia[0], j = ib[0];
      return CGAL::do_intersect(Segment(A[(i + 1) % 3], A[(i + 2) % 3]), Triangle(B[0], B[1], B[2])) ||
             CGAL::do_intersect(Segment(B[(j + 1) % 3], B[(j + 2) % 3]), Triangle(A[0], A[1], A[2]));
    }
    case 2: {
      const Point &u = A[ia[0]], &w = A[ia[1]], &a = A[3 - ia[0] - ia[1]], &b = B[3 - ib[0] - ib[1]];
      return CGAL::coplanar(u, w, a, b) && CGAL::coplanar_orientation(u, w, a, b) == CGAL::POSITIVE;
    }
    default:
      return true;
  }
}

}  // namespace

std::vector<TrianglePair> find_intersections(const VecX& x, const std::vector<Tri>& triangles, size_t max_pairs,
                                             size_t* count, size_t fixed_from, const std::vector<Index>* joined) {
  const Index points = static_cast<Index>(x.size() / 3);
  const Index n = static_cast<Index>(triangles.size());
  std::vector<std::array<Point, 3>> corners(n);
  std::vector<char> degenerate(n, 0);
  for (Index t = 0; t < n; ++t)
    for (int k = 0; k < 3; ++k) {
      const Index p = triangles[t][k];
      if (p < 0 || p >= points)
        throw_error("intersection check: triangle {} uses point {}, but there are {} points", t, p, points);
      // CGAL's predicates are undefined on NaN, and an infinite point cannot be placed.
      if (!vertex(x, p).allFinite())
        throw_error("intersection check: point {} of triangle {} is not finite ({}, {}, {})", p, t, x[3 * p],
                    x[3 * p + 1], x[3 * p + 2]);
    }
  if (joined && static_cast<Index>(joined->size()) != points)
    throw_error("intersection check: {} joined entries for {} points", joined->size(), points);
  parallel_for(n, [&](Index t) {
    for (int k = 0; k < 3; ++k) {
      const auto p = vertex(x, triangles[t][k]);
      corners[t][k] = Point(p.x(), p.y(), p.z());
    }
    degenerate[t] = CGAL::collinear(corners[t][0], corners[t][1], corners[t][2]);
  });

  std::vector<Box> boxes;
  boxes.reserve(n);
  for (Index t = 0; t < n; ++t)
    if (!degenerate[t]) {
      const auto& c = corners[t];
      boxes.emplace_back(c[0].bbox() + c[1].bbox() + c[2].bbox(), &triangles[t]);
    }
  std::vector<TrianglePair> candidates;
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), [&](const Box& p, const Box& q) {
    const Index a = static_cast<Index>(p.handle() - triangles.data()),
                b = static_cast<Index>(q.handle() - triangles.data());
    if (static_cast<size_t>(std::min(a, b)) >= fixed_from) return;
    candidates.push_back({std::min(a, b), std::max(a, b)});
  });

  std::vector<char> hit(candidates.size(), 0);
  parallel_for(static_cast<Index>(candidates.size()), [&](Index k) {
    const auto [a, b] = candidates[k];
    if (!joined) {
      hit[k] = intersect_beyond_shared(triangles[a], corners[a], triangles[b], corners[b]);
      return;
    }
    // Shared points by their joined names, positions each triangle's own.
    Tri ja = triangles[a], jb = triangles[b];
    for (Index& v : ja) v = (*joined)[static_cast<size_t>(v)];
    for (Index& v : jb) v = (*joined)[static_cast<size_t>(v)];
    // A triangle with two points of one group (at a seam's end) keeps its own names: the cases below need three
    // distinct corners.
    const auto distinct = [](const Tri& t) { return t[0] != t[1] && t[1] != t[2] && t[0] != t[2]; };
    if (!distinct(ja) || !distinct(jb)) {
      ja = triangles[a];
      jb = triangles[b];
    }
    hit[k] = intersect_beyond_shared(ja, corners[a], jb, corners[b]);
  });
  std::vector<TrianglePair> pairs;
  for (size_t k = 0; k < candidates.size(); ++k)
    if (hit[k]) pairs.push_back(candidates[k]);
  // box_intersection_d reports in an order of its own; the first max_pairs must not depend on it.
  std::sort(pairs.begin(), pairs.end(), [](const TrianglePair& p, const TrianglePair& q) {
    return p.a < q.a || (p.a == q.a && p.b < q.b);
  });
  if (count) *count = pairs.size();
  if (pairs.size() > max_pairs) pairs.resize(max_pairs);
  return pairs;
}

}  // namespace mgcloth::collision
