#include <mgcloth/collision/broad_phase.hpp>
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace mgcloth::collision {

namespace {

using Pair = std::array<Index, 2>;

double surface_area(const Aabb& b) {
  const Vec3 e = b.hi - b.lo;
  return 2.0 * (e.x() * e.y() + e.y() * e.z() + e.z() * e.x());
}

bool share_end(const std::array<Index, 2>& a, const std::array<Index, 2>& b) {
  return a[0] == b[0] || a[0] == b[1] || a[1] == b[0] || a[1] == b[1];
}

bool has_point(const Tri& t, Index p) { return t[0] == p || t[1] == p || t[2] == p; }

/// The boxes of every primitive, from the (unexpanded) box of each point, grown by `inflate`. BroadPhase and the
/// brute-force reference share this so that both test the same boxes bit for bit.
template <class PointBox>
void make_boxes(const SurfaceTopology& s, const PointBox& point_box, double inflate, std::vector<Aabb>& triangles,
                std::vector<Aabb>& edges, std::vector<Aabb>& vertices) {
  triangles.resize(s.triangles.size());
  edges.resize(s.edges.size());
  vertices.resize(s.vertices.size());
  parallel_for(static_cast<Index>(triangles.size()), [&](Index t) {
    Aabb b = point_box(s.triangles[t][0]);
    b.expand(point_box(s.triangles[t][1]));
    b.expand(point_box(s.triangles[t][2]));
    b.inflate(inflate);
    triangles[t] = b;
  });
  parallel_for(static_cast<Index>(edges.size()), [&](Index e) {
    Aabb b = point_box(s.edges[e][0]);
    b.expand(point_box(s.edges[e][1]));
    b.inflate(inflate);
    edges[e] = b;
  });
  parallel_for(static_cast<Index>(vertices.size()), [&](Index v) {
    Aabb b = point_box(s.vertices[v]);
    b.inflate(inflate);
    vertices[v] = b;
  });
}

void check_input(const SurfaceTopology& s, const VecX& x, double inflate, const char* what = "position") {
  const Index points = static_cast<Index>(x.size() / 3);
  if (!s.vertices.empty() && s.vertices.back() >= points)
    throw_error("broad phase: the surface uses point {} but the positions hold {} points", s.vertices.back(), points);
  if (!(inflate >= 0.0) || !std::isfinite(inflate))
    throw_error("broad phase: the inflation must be finite and non-negative, not {}", inflate);
  // A NaN would make the tree's median split compare inconsistently, and a box that overlaps nothing hides contact.
  for (Index p : s.vertices)
    if (!vertex(x, p).allFinite())
      throw_error<SolveError>("broad phase: the {} of point {} is not finite ({}, {}, {})", what, p, x[3 * p],
                              x[3 * p + 1], x[3 * p + 2]);
}

/// The pairs of query primitives [0, n) in fixed chunks, each chunk's list ascending, the lists concatenated in
/// chunk order: the same output for any thread count. Chunks are handed out dynamically because contact clusters
/// (a fold, a stack of layers) make some chunks far more expensive than others.
template <class Query>
void gather_pairs(Index n, std::vector<std::vector<Pair>>& chunks, std::vector<Pair>& out, const Query& query) {
  constexpr Index kChunk = 256;
  const Index count = (n + kChunk - 1) / kChunk;
  if (static_cast<Index>(chunks.size()) < count) chunks.resize(count);
  auto run = [&](Index c) {
    std::vector<Pair>& pairs = chunks[c];
    pairs.clear();
    const Index end = std::min(n, (c + 1) * kChunk);
    for (Index i = c * kChunk; i < end; ++i) {
      const size_t first = pairs.size();
      query(i, pairs);
      // A traversal's order depends on the tree's shape, which depends on when it was last rebuilt.
      std::sort(pairs.begin() + static_cast<std::ptrdiff_t>(first), pairs.end());
    }
  };
  if (count < 2 || omp_get_max_threads() == 1) {
    for (Index c = 0; c < count; ++c) run(c);
  } else {
#pragma omp parallel for schedule(dynamic, 1)
    for (Index c = 0; c < count; ++c) run(c);
  }
  std::vector<size_t> offset(count + 1, 0);
  for (Index c = 0; c < count; ++c) offset[c + 1] = offset[c] + chunks[c].size();
  out.resize(offset[count]);
  // The chunks' memory is given back: a search along a long step can find far more pairs than the next one.
  parallel_for(
      count,
      [&](Index c) {
        std::copy(chunks[c].begin(), chunks[c].end(), out.begin() + offset[c]);
        std::vector<Pair>().swap(chunks[c]);
      },
      2);
}

/// The pairs ascending: bucketed by their first index (counting), each bucket sorted.
void sort_pairs(Index n, const std::vector<Pair>& in, std::vector<Pair>& out) {
  std::vector<Index> start(static_cast<size_t>(n) + 1, 0);
  for (const Pair& p : in) ++start[p[0] + 1];
  for (Index i = 0; i < n; ++i) start[i + 1] += start[i];
  out.resize(in.size());
  std::vector<Index> cursor(start.begin(), start.end() - 1);
  for (const Pair& p : in) out[cursor[p[0]]++] = p;
  parallel_for(
      n, [&](Index i) { std::sort(out.begin() + start[i], out.begin() + start[i + 1]); }, 1024);
}

}  // namespace

SurfaceTopology make_surface_topology(std::vector<Tri> triangles) {
  SurfaceTopology s;
  s.edges.reserve(3 * triangles.size());
  s.vertices.reserve(3 * triangles.size());
  for (size_t t = 0; t < triangles.size(); ++t) {
    const Tri& tri = triangles[t];
    for (int k = 0; k < 3; ++k) {
      if (tri[k] < 0) throw_error("surface: triangle {} has a negative vertex index {}", t, tri[k]);
      if (tri[k] == tri[(k + 1) % 3]) throw_error("surface: triangle {} repeats vertex {}", t, tri[k]);
      const Index a = tri[k], b = tri[(k + 1) % 3];
      s.edges.push_back({std::min(a, b), std::max(a, b)});
      s.vertices.push_back(a);
    }
  }
  std::sort(s.edges.begin(), s.edges.end());
  s.edges.erase(std::unique(s.edges.begin(), s.edges.end()), s.edges.end());
  std::sort(s.vertices.begin(), s.vertices.end());
  s.vertices.erase(std::unique(s.vertices.begin(), s.vertices.end()), s.vertices.end());
  s.triangles = std::move(triangles);
  return s;
}

// ---------------------------------------------------------------------------------------------------------------
// Bvh

void Bvh::build(const std::vector<Aabb>& boxes) {
  const Index n = static_cast<Index>(boxes.size());
  m_nodes.clear();
  m_order.resize(n);
  std::iota(m_order.begin(), m_order.end(), 0);
  m_leaf_box.resize(n);
  if (n == 0) return;
  std::vector<Vec3> centroid(n);
  for (Index i = 0; i < n; ++i) centroid[i] = 0.5 * (boxes[i].lo + boxes[i].hi);
  m_nodes.reserve(2 * ((n + kLeafSize - 1) / kLeafSize));
  m_nodes.emplace_back();
  m_nodes[0].first = 0;
  m_nodes[0].count = n;
  // Nodes are split in creation order, and children are always created after their parent.
  for (size_t k = 0; k < m_nodes.size(); ++k) {
    const Index first = m_nodes[k].first, count = m_nodes[k].count;
    if (count <= kLeafSize) continue;
    Aabb bounds;
    for (Index i = first; i < first + count; ++i) bounds.expand(centroid[m_order[i]]);
    int axis = 0;
    (bounds.hi - bounds.lo).maxCoeff(&axis);
    const Index mid = first + count / 2;
    // Ties broken by index, so the tree (and thus nothing downstream) depends on the standard library's nth_element.
    std::nth_element(m_order.begin() + first, m_order.begin() + mid, m_order.begin() + first + count,
                     [&](Index a, Index b) {
                       const double ca = centroid[a][axis], cb = centroid[b][axis];
                       return ca < cb || (ca == cb && a < b);
                     });
    const Index left = static_cast<Index>(m_nodes.size());
    m_nodes.emplace_back();
    m_nodes.emplace_back();
    Node& node = m_nodes[k];
    node.left = left;
    node.right = left + 1;
    m_nodes[left].first = first;
    m_nodes[left].count = mid - first;
    m_nodes[left + 1].first = mid;
    m_nodes[left + 1].count = first + count - mid;
  }
  for (Index k = 0; k < n; ++k) m_leaf_box[k] = boxes[m_order[k]];
  update_nodes();
}

void Bvh::refit(const std::vector<Aabb>& boxes) {
  if (boxes.size() != m_leaf_box.size())
    throw_error("Bvh::refit: {} boxes, but the tree was built over {}", boxes.size(), m_leaf_box.size());
  const Index n = static_cast<Index>(boxes.size());
  parallel_for(n, [&](Index k) { m_leaf_box[k] = boxes[m_order[k]]; }, 4096);
  update_nodes();
}

void Bvh::update_nodes() {
  for (Index k = static_cast<Index>(m_nodes.size()) - 1; k >= 0; --k) {
    Node& node = m_nodes[k];
    Aabb b;
    if (node.left < 0) {
      for (Index i = node.first; i < node.first + node.count; ++i) b.expand(m_leaf_box[i]);
    } else {
      b = m_nodes[node.left].box;
      b.expand(m_nodes[node.right].box);
    }
    node.box = b;
  }
}

std::vector<Index> Bvh::positions() const {
  std::vector<Index> out(m_order.size());
  for (size_t k = 0; k < m_order.size(); ++k) out[static_cast<size_t>(m_order[k])] = static_cast<Index>(k);
  return out;
}

double Bvh::total_surface_area() const {
  double sum = 0.0;
  for (const Node& node : m_nodes) sum += surface_area(node.box);
  return sum;
}

// ---------------------------------------------------------------------------------------------------------------
// BroadPhase

BroadPhase::BroadPhase(const SurfaceTopology* surface) : m_surface(surface) {
  if (!surface) throw_error("BroadPhase: no surface");
  const Index points = surface->vertices.empty() ? 0 : surface->vertices.back() + 1;
  m_vertex_of_point.assign(static_cast<size_t>(points), -1);
  for (size_t v = 0; v < surface->vertices.size(); ++v) m_vertex_of_point[surface->vertices[v]] = static_cast<Index>(v);
}

void BroadPhase::find(const VecX& x, double inflate, Candidates& out) {
  check_input(*m_surface, x, inflate);
  find_with(
      [&](Index p) {
        Aabb b;
        b.lo = b.hi = vertex(x, p);
        return b;
      },
      inflate, out);
}

void BroadPhase::find_swept(const VecX& x, const VecX& d, double inflate, Candidates& out) {
  if (d.size() != x.size())
    throw_error("broad phase: the displacement has {} entries, the positions {}", d.size(), x.size());
  check_input(*m_surface, x, inflate);
  check_input(*m_surface, d, inflate, "displacement");
  find_with(
      [&](Index p) {
        const Vec3 a = vertex(x, p), b = a + vertex(d, p);
        Aabb box;
        box.lo = a.cwiseMin(b);
        box.hi = a.cwiseMax(b);
        return box;
      },
      inflate, out);
}

// Why 1.5×: a cloth that folds or crumples keeps each node's triangles a compact patch, so refit trees stay as good as
// fresh ones (folding a 10K sheet flat into four layers over 20 calls grows no tree by 1.25×); what spoils them is
// motion that pulls apart what a node grouped, such as layers unfolding. There, never rebuilding made the calls 3×
// slower, and rebuilding once the area had grown by 1.25× or 1.5× was fastest over the sequence, ~10% ahead of 2×
// and of rebuilding every call (a build costs about a fifth of a call's queries). Of the two, 1.5× rebuilds less
// often for the same time. Measured with `mgcloth_bench_broad_phase --sweep`.
void BroadPhase::update_tree(const std::vector<Aabb>& boxes, Bvh& tree, double& area_at_build, bool fresh) {
  if (!fresh && tree.size() == boxes.size()) {
    tree.refit(boxes);
    if (tree.total_surface_area() <= m_rebuild_growth * area_at_build) return;
  }
  tree.build(boxes);
  area_at_build = tree.total_surface_area();
  ++m_builds;
}

template <class PointBox>
void BroadPhase::update_trees(const PointBox& point_box, double inflate) {
  make_boxes(*m_surface, point_box, inflate, m_triangle_boxes, m_edge_boxes, m_vertex_boxes);
  const bool fresh = m_builds == 0;
  update_tree(m_triangle_boxes, m_triangles, m_triangle_area_at_build, fresh);
  update_tree(m_edge_boxes, m_edges, m_edge_area_at_build, fresh);
}

void BroadPhase::find_touching(const VecX& x, const VecX* d, double inflate, const std::vector<char>& marked,
                               Candidates& out) {
  const SurfaceTopology& s = *m_surface;
  check_input(s, x, inflate);
  if (d) {
    if (d->size() != x.size())
      throw_error("broad phase: the displacement has {} entries, the positions {}", d->size(), x.size());
    check_input(s, *d, inflate, "displacement");
  }
  if (static_cast<Index>(marked.size()) * 3 != x.size())
    throw_error("broad phase: {} marks for {} points", marked.size(), x.size() / 3);
  update_trees(
      [&](Index p) {
        const Vec3 a = vertex(x, p), b = d ? Vec3(a + vertex(*d, p)) : a;
        Aabb box;
        box.lo = a.cwiseMin(b);
        box.hi = a.cwiseMax(b);
        return box;
      },
      inflate);
  const auto is_marked = [&](Index p) { return marked[static_cast<size_t>(p)] != 0; };
  std::vector<Index> verts, tris, edges;
  for (Index v = 0; v < static_cast<Index>(s.vertices.size()); ++v)
    if (is_marked(s.vertices[v])) verts.push_back(v);
  for (Index t = 0; t < static_cast<Index>(s.triangles.size()); ++t)
    if (is_marked(s.triangles[t][0]) || is_marked(s.triangles[t][1]) || is_marked(s.triangles[t][2])) tris.push_back(t);
  for (Index e = 0; e < static_cast<Index>(s.edges.size()); ++e)
    if (is_marked(s.edges[e][0]) || is_marked(s.edges[e][1])) edges.push_back(e);
  // Vertex–triangle pairs from the marked vertices' side and from the marked triangles' side. A vertex's box lies in
  // the box of each triangle it belongs to, so the vertices near a triangle are among those of the triangles its box
  // overlaps.
  const Index nv = static_cast<Index>(verts.size());
  gather_pairs(nv + static_cast<Index>(tris.size()), m_chunks, m_unordered, [&](Index i, std::vector<Pair>& pairs) {
    if (i < nv) {
      const Index v = verts[i], p = s.vertices[v];
      m_triangles.query(m_vertex_boxes[v], [&](Index t) {
        if (!has_point(s.triangles[t], p)) pairs.push_back({v, t});
      });
      return;
    }
    const Index t = tris[i - nv];
    const Aabb& box = m_triangle_boxes[t];
    m_triangles.query(box, [&](Index u) {
      for (Index p : s.triangles[u]) {
        const Index v = m_vertex_of_point[p];
        if (!has_point(s.triangles[t], p) && m_vertex_boxes[v].overlaps(box)) pairs.push_back({v, t});
      }
    });
  });
  // Both sides find most pairs, so each pair is met about twice.
  sort_pairs(static_cast<Index>(s.vertices.size()), m_unordered, out.vertex_triangle);
  out.vertex_triangle.erase(std::unique(out.vertex_triangle.begin(), out.vertex_triangle.end()),
                            out.vertex_triangle.end());
  gather_pairs(static_cast<Index>(edges.size()), m_chunks, m_unordered, [&](Index i, std::vector<Pair>& pairs) {
    const Index a = edges[i];
    m_edges.query(m_edge_boxes[a], [&](Index b) {
      if (!share_end(s.edges[a], s.edges[b])) pairs.push_back({std::min(a, b), std::max(a, b)});
    });
  });
  sort_pairs(static_cast<Index>(s.edges.size()), m_unordered, out.edge_edge);
  out.edge_edge.erase(std::unique(out.edge_edge.begin(), out.edge_edge.end()), out.edge_edge.end());
  std::vector<Pair>().swap(m_unordered);
}

template <class PointBox>
void BroadPhase::find_with(const PointBox& point_box, double inflate, Candidates& out) {
  const SurfaceTopology& s = *m_surface;
  update_trees(point_box, inflate);
  gather_pairs(static_cast<Index>(s.vertices.size()), m_chunks, out.vertex_triangle,
               [&](Index v, std::vector<Pair>& pairs) {
                 const Index p = s.vertices[v];
                 m_triangles.query(m_vertex_boxes[v], [&](Index t) {
                   if (!has_point(s.triangles[t], p)) pairs.push_back({v, t});
                 });
               });
  // Edges against their own tree: each pair is met once, from whichever of the two comes first in the tree's leaf
  // order (half the traversal of querying every edge for all its partners), then put in ascending order.
  const std::vector<Index> position = m_edges.positions();
  gather_pairs(static_cast<Index>(s.edges.size()), m_chunks, m_unordered, [&](Index a, std::vector<Pair>& pairs) {
    m_edges.query_after(m_edge_boxes[a], position[a], [&](Index b) {
      if (!share_end(s.edges[a], s.edges[b])) pairs.push_back({std::min(a, b), std::max(a, b)});
    });
  });
  sort_pairs(static_cast<Index>(s.edges.size()), m_unordered, out.edge_edge);
  std::vector<Pair>().swap(m_unordered);
}

void find_brute_force(const SurfaceTopology& s, const VecX& x, double inflate, Candidates& out) {
  check_input(s, x, inflate);
  std::vector<Aabb> triangles, edges, vertices;
  make_boxes(
      s,
      [&](Index p) {
        Aabb b;
        b.lo = b.hi = vertex(x, p);
        return b;
      },
      inflate, triangles, edges, vertices);
  out.clear();
  for (Index v = 0; v < static_cast<Index>(vertices.size()); ++v)
    for (Index t = 0; t < static_cast<Index>(triangles.size()); ++t)
      if (!has_point(s.triangles[t], s.vertices[v]) && vertices[v].overlaps(triangles[t]))
        out.vertex_triangle.push_back({v, t});
  for (Index a = 0; a < static_cast<Index>(edges.size()); ++a)
    for (Index b = a + 1; b < static_cast<Index>(edges.size()); ++b)
      if (!share_end(s.edges[a], s.edges[b]) && edges[a].overlaps(edges[b])) out.edge_edge.push_back({a, b});
}

}  // namespace mgcloth::collision
