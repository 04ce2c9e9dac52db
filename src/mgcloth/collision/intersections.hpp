#pragma once
#include <mgcloth/core/types.hpp>

#include <array>
#include <limits>
#include <vector>

namespace mgcloth::collision {

/// Two triangles of a surface that intersect.
struct TrianglePair {
  Index a = 0, b = 0;  ///< triangle indices, a < b
};

/// The independent checker of the contact guarantee: every pair of triangles (from `triangles`, points in x) that
/// intersect, decided by exact predicates (CGAL's Exact_predicates_inexact_constructions_kernel) after CGAL's own
/// box intersection as the broad phase, so that it shares nothing with the contact code. Triangles that share a
/// vertex or an edge touch there by construction; they count as intersecting only where they also cross elsewhere
/// (an edge of one passing through the other away from the shared part). Degenerate (zero-area) triangles are
/// skipped. At most `max_pairs` pairs are returned (the count of all is `count`, if non-null). Pairs of two triangles
/// at or after `fixed_from` are not checked: obstacle meshes come last, and whether an obstacle crosses itself or
/// another obstacle is no question of the cloth's guarantee.
///
/// `joined` (optional, one entry per point): points with equal entries count as one point where triangles share it,
/// each triangle keeping its own point's position: the two sides of a closed seam, which meet there by construction
/// but are not the same vertex. A triangle pair sharing one such point then intersects only where an edge of one
/// opposite it meets the other.
std::vector<TrianglePair> find_intersections(const VecX& x, const std::vector<Tri>& triangles, size_t max_pairs = 100,
                                             size_t* count = nullptr,
                                             size_t fixed_from = std::numeric_limits<size_t>::max(),
                                             const std::vector<Index>* joined = nullptr);

}  // namespace mgcloth::collision
