#pragma once
#include <mgcloth/core/types.hpp>

#include <algorithm>
#include <array>
#include <vector>

namespace mgcloth::collision {

/// The surfaces that collide, in the numbering of the unknown's points (one objective may hold several cloths).
struct SurfaceTopology {
  std::vector<Tri> triangles;
  std::vector<std::array<Index, 2>> edges;  ///< each undirected edge of `triangles` once
  std::vector<Index> vertices;              ///< each point used by a triangle once, ascending
};

/// Builds edges and vertices from the triangles.
SurfaceTopology make_surface_topology(std::vector<Tri> triangles);

/// Candidate pairs of the narrow phase. Pairs that share a point (a vertex of its own triangle, edges with a common
/// end) are never candidates.
struct Candidates {
  std::vector<std::array<Index, 2>> vertex_triangle;  ///< (index into vertices, index into triangles)
  std::vector<std::array<Index, 2>> edge_edge;        ///< (edge a, edge b), a < b, indices into edges
  void clear() {
    vertex_triangle.clear();
    edge_edge.clear();
  }
};

/// Axis-aligned box.
struct Aabb {
  Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);
  void expand(const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void expand(const Aabb& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
  /// Grows the box by r on every side.
  void inflate(double r) {
    lo.array() -= r;
    hi.array() += r;
  }
  bool overlaps(const Aabb& o) const { return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all(); }
};

/// A bounding-volume hierarchy over boxes: built top-down, refit bottom-up when the boxes move.
class Bvh {
 public:
  /// Median split on the longest axis of the boxes' centroids, leaves of at most kLeafSize boxes.
  void build(const std::vector<Aabb>& boxes);
  /// Same boxes (count and order) at new places; the tree's shape is kept.
  void refit(const std::vector<Aabb>& boxes);
  /// Calls f(i) for every box i that overlaps `box`.
  template <class F>
  void query(const Aabb& box, F&& f) const;
  /// The same, restricted to the boxes after position `after` in the tree's leaf order (see position()): a query of
  /// the tree against itself that meets each pair once, and prunes the subtrees entirely before it.
  template <class F>
  void query_after(const Aabb& box, Index after, F&& f) const;
  /// Per box, its position in the leaf order.
  std::vector<Index> positions() const;
  size_t size() const { return m_leaf_box.size(); }
  /// Σ over the nodes of their boxes' surface areas: by the surface-area heuristic (MacDonald & Booth 1990), what
  /// the number of nodes a query visits grows with. A refit tree whose boxes have moved away from the ones they
  /// were grouped with has a larger one than a fresh tree over the same boxes.
  double total_surface_area() const;

  static constexpr Index kLeafSize = 4;

 private:
  struct Node {
    Aabb box;
    Index left = -1, right = -1;  ///< children, or -1 for a leaf
    Index first = 0, count = 0;   ///< a leaf's range in m_order
  };
  void update_nodes();
  std::vector<Node> m_nodes;  ///< children after their parent, so a backward sweep refits
  std::vector<Index> m_order;
  std::vector<Aabb> m_leaf_box;  ///< the boxes in m_order's order, so a leaf's boxes are contiguous
  friend class BroadPhase;
};

template <class F>
void Bvh::query_after(const Aabb& box, Index after, F&& f) const {
  if (m_nodes.empty() || !m_nodes[0].box.overlaps(box)) return;
  // Children are tested before they are pushed, so every node popped overlaps the query box. Median splits keep the
  // depth below log2(n) + 1, so a fixed stack of 64 holds any tree of int-indexed boxes. A node's leaves are the
  // contiguous range [first, first + count) of the leaf order.
  const auto wanted = [&](const Node& n) { return n.first + n.count > after + 1 && n.box.overlaps(box); };
  Index stack[64];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = m_nodes[stack[--top]];
    if (node.left < 0) {
      for (Index k = std::max(node.first, after + 1); k < node.first + node.count; ++k)
        if (m_leaf_box[k].overlaps(box)) f(m_order[k]);
    } else {
      if (wanted(m_nodes[node.right])) stack[top++] = node.right;
      if (wanted(m_nodes[node.left])) stack[top++] = node.left;
    }
  }
}

template <class F>
void Bvh::query(const Aabb& box, F&& f) const {
  query_after(box, -1, f);
}

/// Broad phase over a surface: boxes of triangles, edges and vertices, their BVHs refit every call and rebuilt when
/// refitting has let them grow, queries in parallel. Deterministic: the candidates come out in the same order
/// whatever the thread count, and that order is ascending (lexicographic), so it does not depend on the trees'
/// history either (a fresh BroadPhase, as after a resume, gives the same list).
class BroadPhase {
 public:
  explicit BroadPhase(const SurfaceTopology* surface);
  /// Pairs whose boxes at x, each grown by `inflate` on every side, overlap.
  void find(const VecX& x, double inflate, Candidates& out);
  /// Pairs whose boxes swept from x to x + d (each grown by `inflate`) overlap: every pair that can come within
  /// 2·inflate of each other while the points move linearly.
  void find_swept(const VecX& x, const VecX& d, double inflate, Candidates& out);
  /// The pairs of find_swept (find when d is null) that have a point p with marked[p] != 0, ascending: what a local
  /// update of a pair cache needs when only those points moved. The trees hold every primitive's box (refit or
  /// rebuilt as in find), but only the marked points' primitives are queried, so the cost follows their count.
  void find_touching(const VecX& x, const VecX* d, double inflate, const std::vector<char>& marked, Candidates& out);
  /// How many times a tree was built (the first call builds both): for tests and statistics.
  Index builds() const { return m_builds; }

  /// A tree is rebuilt when its total surface area has grown this much since its build (see broad_phase.cpp).
  static constexpr double kRebuildGrowth = 1.5;
  /// Another threshold, for measurements: 0 rebuilds every call, infinity never (but for a change of count).
  void set_rebuild_growth(double growth) { m_rebuild_growth = growth; }

 private:
  template <class PointBox>
  void find_with(const PointBox& point_box, double inflate, Candidates& out);
  template <class PointBox>
  void update_trees(const PointBox& point_box, double inflate);
  void update_tree(const std::vector<Aabb>& boxes, Bvh& tree, double& area_at_build, bool fresh);

  const SurfaceTopology* m_surface;
  Bvh m_triangles, m_edges;
  std::vector<Aabb> m_triangle_boxes, m_edge_boxes, m_vertex_boxes;
  double m_triangle_area_at_build = 0.0, m_edge_area_at_build = 0.0;
  std::vector<std::vector<std::array<Index, 2>>> m_chunks;  ///< per-chunk results (scratch, emptied after use)
  std::vector<std::array<Index, 2>> m_unordered;             ///< pairs before sorting (scratch, emptied after use)
  std::vector<Index> m_vertex_of_point;                      ///< per point, its index in vertices (-1: none)
  Index m_builds = 0;
  double m_rebuild_growth = kRebuildGrowth;
};

/// O(n²) reference of BroadPhase::find, for tests.
void find_brute_force(const SurfaceTopology& surface, const VecX& x, double inflate, Candidates& out);

}  // namespace mgcloth::collision
