#pragma once
#include <mgcloth/core/types.hpp>

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
  bool overlaps(const Aabb& o) const { return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all(); }
};

/// A bounding-volume hierarchy over boxes: built top-down, refit bottom-up when the boxes move.
class Bvh {
 public:
  void build(const std::vector<Aabb>& boxes);
  /// Same boxes (count and order) at new places; the tree's shape is kept.
  void refit(const std::vector<Aabb>& boxes);
  /// Calls f(i) for every box i that overlaps `box`.
  template <class F>
  void query(const Aabb& box, F&& f) const;
  size_t size() const { return m_leaf_box.size(); }

 private:
  struct Node {
    Aabb box;
    Index left = -1, right = -1;  ///< children, or -1 for a leaf
    Index first = 0, count = 0;   ///< a leaf's range in m_order
  };
  std::vector<Node> m_nodes;
  std::vector<Index> m_order;
  std::vector<Aabb> m_leaf_box;
  friend class BroadPhase;
};

/// Broad phase over a surface: boxes of triangles, edges and vertices, their BVHs refit every call and rebuilt when
/// refitting has let them grow, queries in parallel. Deterministic: the candidates come out in the same order
/// whatever the thread count.
class BroadPhase {
 public:
  explicit BroadPhase(const SurfaceTopology* surface);
  /// Pairs whose boxes at x, each grown by `inflate` on every side, overlap.
  void find(const VecX& x, double inflate, Candidates& out);
  /// Pairs whose boxes swept from x to x + d (each grown by `inflate`) overlap: every pair that can come within
  /// 2·inflate of each other while the points move linearly.
  void find_swept(const VecX& x, const VecX& d, double inflate, Candidates& out);

 private:
  const SurfaceTopology* m_surface;
  Bvh m_triangles, m_edges;
  // (implementation state: boxes, rebuild heuristics)
};

/// O(n²) reference of BroadPhase::find, for tests.
void find_brute_force(const SurfaceTopology& surface, const VecX& x, double inflate, Candidates& out);

}  // namespace mgcloth::collision
