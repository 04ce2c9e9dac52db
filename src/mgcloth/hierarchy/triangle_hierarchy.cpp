#include <mgcloth/core/error.hpp>
#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/mesh/topology.hpp>

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <numbers>
#include <memory>
#include <random>
#include <unordered_map>

namespace mgcloth::hierarchy {

namespace {

double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// Uniform grid of buckets over a box in material space.
class BucketGrid {
 public:
  BucketGrid(const Vec2& lo, const Vec2& hi, double cell) : m_lo(lo), m_cell(cell) {
    m_nx = std::max<Index>(1, static_cast<Index>((hi.x() - lo.x()) / cell) + 1);
    m_ny = std::max<Index>(1, static_cast<Index>((hi.y() - lo.y()) / cell) + 1);
    m_cells.resize(static_cast<std::size_t>(m_nx) * m_ny);
  }
  Index cx(double x) const { return std::clamp<Index>(static_cast<Index>((x - m_lo.x()) / m_cell), 0, m_nx - 1); }
  Index cy(double y) const { return std::clamp<Index>(static_cast<Index>((y - m_lo.y()) / m_cell), 0, m_ny - 1); }
  std::vector<Index>& at(Index x, Index y) { return m_cells[static_cast<std::size_t>(y) * m_nx + x]; }
  const std::vector<Index>& at(Index x, Index y) const { return m_cells[static_cast<std::size_t>(y) * m_nx + x]; }
  void add_point(const Vec2& p, Index i) { at(cx(p.x()), cy(p.y())).push_back(i); }
  void add_box(const Vec2& lo, const Vec2& hi, Index i) {
    for (Index y = cy(lo.y()); y <= cy(hi.y()); ++y)
      for (Index x = cx(lo.x()); x <= cx(hi.x()); ++x) at(x, y).push_back(i);
  }
  Index nx() const { return m_nx; }
  Index ny() const { return m_ny; }
  double cell() const { return m_cell; }

 private:
  Vec2 m_lo;
  double m_cell;
  Index m_nx = 1, m_ny = 1;
  std::vector<std::vector<Index>> m_cells;
};

double turning_angle(const Vec2& p, const Vec2& v, const Vec2& n) {
  const Vec2 a = v - p, b = n - v;
  return std::atan2(std::abs(a.x() * b.y() - a.y() * b.x()), a.dot(b));
}

/// Stitch partners of every vertex (the other members of its stitch group), in CSR form.
struct Partners {
  std::vector<Index> offsets, list;
  Partners(Index n, const std::vector<std::vector<Index>>& groups) : offsets(n + 1, 0) {
    for (const auto& g : groups)
      for (Index v : g) offsets[v + 1] += static_cast<Index>(g.size()) - 1;
    for (Index i = 0; i < n; ++i) offsets[i + 1] += offsets[i];
    list.resize(offsets[n]);
    std::vector<Index> fill(offsets.begin(), offsets.end() - 1);
    for (const auto& g : groups)
      for (Index v : g)
        for (Index w : g)
          if (w != v) list[fill[v]++] = w;
  }
  bool stitched(Index v) const { return offsets[v + 1] > offsets[v]; }
  template <class F> void for_each(Index v, F&& f) const {
    for (Index k = offsets[v]; k < offsets[v + 1]; ++k) f(list[k]);
  }
};

/// Marks the boundary vertices a coarse level keeps on one loop: forced ones (corners, keep vertices, seam ends,
/// vertices already chosen through a stitch partner) and vertices evenly spaced by arc length (about r apart)
/// between them. A seam stretch whose partner stretch was sampled already (done) is not sampled again: its
/// vertices come from the partner, so both panels of a seam keep the same stitched vertices (App. B step 2).
void select_boundary(const mesh::TriMesh& m, const std::vector<Index>& loop, double r, double corner_angle,
                     const std::vector<char>& forced_in, const Partners& partners, const std::vector<char>& is_adjacent_seam,
                     std::vector<char>& selected, std::vector<char>& done) {
  const Index n = static_cast<Index>(loop.size());
  auto choose = [&](Index v) {
    selected[v] = 1;
    partners.for_each(v, [&](Index w) { selected[w] = 1; });
  };
  auto finish = [&](Index v) {
    done[v] = 1;
    partners.for_each(v, [&](Index w) { done[w] = 1; });
  };
  if (n <= 4) {
    for (Index v : loop) choose(v), finish(v);
    return;
  }
  std::vector<Index> forced;  // positions in the loop
  for (Index k = 0; k < n; ++k) {
    const Index v = loop[k], prev = loop[(k + n - 1) % n], next = loop[(k + 1) % n];
    const double turn = turning_angle(m.u.col(prev), m.u.col(v), m.u.col(next));
    // Seam ends: where stitching starts, stops or changes partner panel (is_adjacent_seam[k] says whether the
    // loop edge k -> k+1 is stitched to one partner edge).
    const bool seam_end = partners.stitched(v) && (!is_adjacent_seam[k] || !is_adjacent_seam[(k + n - 1) % n]);
    if (forced_in[v] || selected[v] || turn > corner_angle || seam_end) forced.push_back(k);
  }
  if (forced.empty()) {
    Index k0 = 0;
    for (Index k = 1; k < n; ++k)
      if (loop[k] < loop[k0]) k0 = k;
    forced.push_back(k0);
  }
  const Index nf = static_cast<Index>(forced.size());
  for (Index f = 0; f < nf; ++f) {
    const Index start = forced[f];
    const Index end = f + 1 < nf ? forced[f + 1] : forced[0] + n;  // loop position, may wrap
    choose(loop[start]);
    bool partner_done = end > start + 1;
    for (Index k = start + 1; k < end && partner_done; ++k) {
      bool any = false;
      partners.for_each(loop[k % n], [&](Index w) { any = any || done[w]; });
      partner_done = any;
    }
    if (!partner_done) {
      std::vector<double> arc{0.0};
      for (Index k = start + 1; k <= end; ++k)
        arc.push_back(arc.back() + (m.u.col(loop[k % n]) - m.u.col(loop[(k - 1) % n])).norm());
      const double length = arc.back();
      Index pieces = std::max<Index>(1, static_cast<Index>(std::lround(length / r)));
      if (nf == 1) pieces = std::max<Index>(pieces, 4);
      else if (nf == 2) pieces = std::max<Index>(pieces, 2);
      Index k = 0;
      for (Index p = 1; p < pieces; ++p) {
        const double s = length * p / pieces;
        while (k + 1 < static_cast<Index>(arc.size()) && std::abs(arc[k + 1] - s) <= std::abs(arc[k] - s)) ++k;
        choose(loop[(start + k) % n]);
      }
    }
    for (Index k = start; k < end; ++k) finish(loop[k % n]);
  }
}

/// Greedy Poisson-disk pass over the interior vertices in a seeded random order: a vertex is taken when no
/// already selected vertex (boundary ones included) lies within r.
void select_interior(const mesh::TriMesh& m, const std::vector<bool>& is_boundary, double r, std::uint64_t seed,
                     std::vector<char>& selected) {
  const Index n = m.num_vertices();
  const Vec2 lo = m.u.rowwise().minCoeff(), hi = m.u.rowwise().maxCoeff();
  BucketGrid grid(lo, hi, r);
  for (Index i = 0; i < n; ++i)
    if (selected[i]) grid.add_point(m.u.col(i), i);
  std::vector<Index> order;
  for (Index i = 0; i < n; ++i)
    if (!is_boundary[i] && !selected[i]) order.push_back(i);
  std::mt19937_64 rng(seed);
  for (std::size_t k = order.size(); k > 1; --k) {
    const std::size_t j = std::min(k - 1, static_cast<std::size_t>(uniform01(rng) * static_cast<double>(k)));
    std::swap(order[k - 1], order[j]);
  }
  const double r2 = r * r;
  for (Index i : order) {
    const Vec2 p = m.u.col(i);
    const Index cx = grid.cx(p.x()), cy = grid.cy(p.y());
    bool free = true;
    for (Index y = std::max<Index>(0, cy - 1); y <= std::min(grid.ny() - 1, cy + 1) && free; ++y)
      for (Index x = std::max<Index>(0, cx - 1); x <= std::min(grid.nx() - 1, cx + 1) && free; ++x)
        for (Index j : grid.at(x, y))
          if ((m.u.col(j) - p).squaredNorm() < r2) {
            free = false;
            break;
          }
    if (!free) continue;
    selected[i] = 1;
    grid.add_point(p, i);
  }
}

// ------------------------------------------------------------------------------------------- triangulation ---

struct FaceInfo {
  int nesting = -1;
  bool in_domain() const { return nesting % 2 == 1; }
};
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<Index, Kernel>;
using FaceBase =
    CGAL::Triangulation_face_base_with_info_2<FaceInfo, Kernel, CGAL::Constrained_triangulation_face_base_2<Kernel>>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<
    Kernel, CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>, CGAL::Exact_predicates_tag>;

/// Nesting level of every face: 0 outside, 1 inside the outer loop, 2 in a hole...; odd levels are the domain.
/// Flood fill from the infinite face, crossing a constrained edge raises the level (CGAL's polygon example).
void mark_domains(Cdt& cdt) {
  for (auto f = cdt.all_faces_begin(); f != cdt.all_faces_end(); ++f) f->info().nesting = -1;
  std::deque<Cdt::Edge> border;
  auto flood = [&](Cdt::Face_handle start, int level) {
    if (start->info().nesting != -1) return;
    std::deque<Cdt::Face_handle> queue{start};
    while (!queue.empty()) {
      const Cdt::Face_handle f = queue.front();
      queue.pop_front();
      if (f->info().nesting != -1) continue;
      f->info().nesting = level;
      for (int i = 0; i < 3; ++i) {
        const Cdt::Face_handle g = f->neighbor(i);
        if (g->info().nesting != -1) continue;
        if (cdt.is_constrained({f, i})) border.push_back({f, i});
        else queue.push_back(g);
      }
    }
  };
  flood(cdt.infinite_face(), 0);
  while (!border.empty()) {
    const Cdt::Edge e = border.front();
    border.pop_front();
    const Cdt::Face_handle g = e.first->neighbor(e.second);
    if (g->info().nesting == -1) flood(g, e.first->info().nesting + 1);
  }
}

/// Constrained Delaunay triangulation of one panel's selected vertices with its coarse loops as constraints;
/// appends the domain triangles (as fine-level vertex indices) to `tris`.
void triangulate_panel(const mesh::TriMesh& m, const std::vector<Index>& candidates,
                       const std::vector<const std::vector<Index>*>& loops, Index panel, std::vector<Tri>& tris) {
  const Index nc = static_cast<Index>(candidates.size());
  std::vector<std::pair<Kernel::Point_2, Index>> points(nc);
  for (Index k = 0; k < nc; ++k) points[k] = {{m.u(0, candidates[k]), m.u(1, candidates[k])}, k};
  Cdt cdt;
  cdt.insert(points.begin(), points.end());
  if (static_cast<Index>(cdt.number_of_vertices()) != nc)
    throw_error("hierarchy: coincident material points in panel {}", panel);
  std::vector<Cdt::Vertex_handle> handle(nc);
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) handle[v->info()] = v;
  std::unordered_map<Index, Index> local;
  for (Index k = 0; k < nc; ++k) local[candidates[k]] = k;
  for (const auto* loop : loops)
    for (std::size_t k = 0; k < loop->size(); ++k)
      cdt.insert_constraint(handle[local.at((*loop)[k])], handle[local.at((*loop)[(k + 1) % loop->size()])]);
  if (static_cast<Index>(cdt.number_of_vertices()) != nc)
    throw_error("hierarchy: coarse boundary loops of panel {} intersect (the coarsening is too aggressive for this shape)",
                panel);
  mark_domains(cdt);
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f)
    if (f->info().in_domain())
      tris.push_back({candidates[f->vertex(0)->info()], candidates[f->vertex(1)->info()], candidates[f->vertex(2)->info()]});
}

/// Triangulates the selected vertices of `fine` panel by panel (panels may overlap in material space) with the
/// coarse loops as constraints. Returns the coarse level: only selected vertices some domain triangle uses (a
/// selected vertex outside the coarse domain is dropped).
Level triangulate(const Level& fine, const mesh::Topology& topo, const std::vector<Index>& candidates,
                  const std::vector<std::vector<Index>>& coarse_loops) {
  const mesh::TriMesh& m = fine.mesh;
  std::vector<std::vector<Index>> panel_vertices(topo.num_components);
  std::vector<std::vector<const std::vector<Index>*>> panel_loops(topo.num_components);
  for (Index v : candidates) panel_vertices[topo.component[v]].push_back(v);
  for (const auto& loop : coarse_loops)
    if (!loop.empty()) panel_loops[topo.component[loop[0]]].push_back(&loop);
  std::vector<Tri> fine_tris;
  for (Index c = 0; c < topo.num_components; ++c)
    if (panel_vertices[c].size() >= 3) triangulate_panel(m, panel_vertices[c], panel_loops[c], c, fine_tris);

  std::vector<Index> new_index(m.num_vertices(), -1);
  std::vector<Index> used;
  for (const Tri& t : fine_tris)
    for (Index v : t)
      if (new_index[v] == -1) new_index[v] = 0, used.push_back(v);
  std::sort(used.begin(), used.end());  // keeps the fine level's vertex order
  Level coarse;
  const Index n = static_cast<Index>(used.size());
  coarse.mesh.x.resize(3, n);
  coarse.mesh.u.resize(2, n);
  coarse.fine_index.resize(n);
  coarse.to_finest.resize(n);
  for (Index c = 0; c < n; ++c) {
    const Index i = used[c];
    new_index[i] = c;
    coarse.mesh.x.col(c) = m.x.col(i);
    coarse.mesh.u.col(c) = m.u.col(i);
    coarse.fine_index[c] = i;
    coarse.to_finest[c] = fine.to_finest[i];
  }
  if (!m.source_vertex.empty())
    for (Index c = 0; c < n; ++c) coarse.mesh.source_vertex.push_back(m.source_vertex[coarse.fine_index[c]]);
  for (const Tri& t : fine_tris) coarse.mesh.tris.push_back({new_index[t[0]], new_index[t[1]], new_index[t[2]]});
  std::sort(coarse.mesh.tris.begin(), coarse.mesh.tris.end());  // CGAL's face order is not part of its contract
  return coarse;
}

// ----------------------------------------------------------------------------------------------- transfer ---

Vec3 barycentric(const Vec2& p, const Vec2& a, const Vec2& b, const Vec2& c) {
  const Vec2 e1 = b - a, e2 = c - a, d = p - a;
  const double det = e1.x() * e2.y() - e1.y() * e2.x();
  const double l1 = (d.x() * e2.y() - d.y() * e2.x()) / det;
  const double l2 = (e1.x() * d.y() - e1.y() * d.x()) / det;
  return {1.0 - l1 - l2, l1, l2};
}

double segment_distance2(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 e = b - a;
  const double t = std::clamp((p - a).dot(e) / e.squaredNorm(), 0.0, 1.0);
  return (a + t * e - p).squaredNorm();
}

/// Locates fine points in a set of coarse triangles (one panel's; uniform grid over the triangles' boxes).
class TriangleLocator {
 public:
  TriangleLocator(const mesh::TriMesh& coarse, const std::vector<Index>& triangles)
      : m_mesh(coarse),
        m_grid(coarse.u.rowwise().minCoeff(), coarse.u.rowwise().maxCoeff(),
               std::max(mesh::mean_material_edge_length(coarse), 1e-300)) {
    for (Index t : triangles) {
      const auto& tri = coarse.tris[t];
      Vec2 lo = coarse.u.col(tri[0]), hi = lo;
      for (int k = 1; k < 3; ++k) lo = lo.cwiseMin(coarse.u.col(tri[k])), hi = hi.cwiseMax(coarse.u.col(tri[k]));
      m_grid.add_box(lo, hi, t);
    }
  }

  /// Triangle and barycentric weights for p: the containing triangle (largest smallest weight) or else the
  /// closest triangle with negative weights clamped to zero and the rest renormalized.
  std::pair<Index, Vec3> locate(const Vec2& p) const {
    const Index cx = m_grid.cx(p.x()), cy = m_grid.cy(p.y());
    Index best = -1;
    Vec3 best_w;
    double best_min = -kInf;
    for (Index t : m_grid.at(cx, cy)) {
      const Vec3 w = weights(t, p);
      if (w.minCoeff() > best_min) best_min = w.minCoeff(), best = t, best_w = w;
    }
    if (best >= 0 && best_min >= -1e-12) return {best, best_w};
    // Closest triangle: search rings of cells until the ring is farther than the best distance found.
    best = -1;
    double best_d2 = kInf;
    const Index max_ring = std::max(m_grid.nx(), m_grid.ny());
    for (Index ring = 0; ring <= max_ring; ++ring) {
      for (Index y = cy - ring; y <= cy + ring; ++y)
        for (Index x = cx - ring; x <= cx + ring; ++x) {
          if (std::max(std::abs(x - cx), std::abs(y - cy)) != ring) continue;
          if (x < 0 || y < 0 || x >= m_grid.nx() || y >= m_grid.ny()) continue;
          for (Index t : m_grid.at(x, y)) {
            const double d2 = distance2(t, p);
            if (d2 < best_d2 || (d2 == best_d2 && t < best)) best_d2 = d2, best = t;
          }
        }
      const double reach = ring * m_grid.cell();
      if (best >= 0 && best_d2 <= reach * reach) break;
    }
    Vec3 w = weights(best, p).cwiseMax(0.0);
    w /= w.sum();
    return {best, w};
  }

 private:
  Vec3 weights(Index t, const Vec2& p) const {
    const auto& tri = m_mesh.tris[t];
    return barycentric(p, m_mesh.u.col(tri[0]), m_mesh.u.col(tri[1]), m_mesh.u.col(tri[2]));
  }
  double distance2(Index t, const Vec2& p) const {
    if (weights(t, p).minCoeff() >= 0.0) return 0.0;
    const auto& tri = m_mesh.tris[t];
    double d2 = kInf;
    for (int k = 0; k < 3; ++k)
      d2 = std::min(d2, segment_distance2(p, m_mesh.u.col(tri[k]), m_mesh.u.col(tri[(k + 1) % 3])));
    return d2;
  }

  const mesh::TriMesh& m_mesh;
  BucketGrid m_grid;
};

/// Prolongation from `coarse` to `fine` (Wang 2018, eq. 1); see build_triangle_hierarchy for the rules.
linalg::StencilTable build_prolongation(const Level& fine, const Level& coarse, const mesh::Topology& fine_topo) {
  const Index nf = fine.mesh.num_vertices(), ncoarse = coarse.mesh.num_vertices();
  std::vector<Index> coarse_of(nf, -1);
  for (Index c = 0; c < ncoarse; ++c) coarse_of[coarse.fine_index[c]] = c;

  std::vector<std::vector<std::pair<Index, double>>> rows(nf);
  for (Index i = 0; i < nf; ++i)
    if (coarse_of[i] >= 0) rows[i] = {{coarse_of[i], 1.0}};
  // Boundary vertices: linear along the chord between the neighbouring coarse vertices of their loop.
  for (const auto& loop : fine_topo.boundary_loops) {
    const Index n = static_cast<Index>(loop.size());
    Index first = -1;
    for (Index k = 0; k < n && first < 0; ++k)
      if (coarse_of[loop[k]] >= 0) first = k;
    if (first < 0) continue;  // a loop the coarse level lost; its vertices fall back to point location
    Index a = first;
    for (Index step = 1; step <= n; ++step) {
      const Index k = (first + step) % n;
      if (coarse_of[loop[k]] < 0) continue;
      const Vec2 ua = fine.mesh.u.col(loop[a]), ub = fine.mesh.u.col(loop[k]);
      const Vec2 e = ub - ua;
      for (Index j = (a + 1) % n; j != k; j = (j + 1) % n) {
        const double t = std::clamp((fine.mesh.u.col(loop[j]) - ua).dot(e) / e.squaredNorm(), 0.0, 1.0);
        rows[loop[j]] = {{coarse_of[loop[a]], 1.0 - t}, {coarse_of[loop[k]], t}};
      }
      a = k;
    }
  }
  // Interior vertices: located among the coarse triangles of their own panel only (panels may overlap in
  // material space, and a seam must not leak into the neighbouring panel).
  std::vector<std::vector<Index>> panel_tris(fine_topo.num_components);
  for (Index t = 0; t < coarse.mesh.num_triangles(); ++t)
    panel_tris[fine_topo.component[coarse.fine_index[coarse.mesh.tris[t][0]]]].push_back(t);
  std::vector<std::unique_ptr<TriangleLocator>> locators(fine_topo.num_components);
  for (Index i = 0; i < nf; ++i) {
    if (!rows[i].empty()) continue;
    const Index panel = fine_topo.component[i];
    if (panel_tris[panel].empty())
      throw_error("hierarchy: panel {} (with vertex {}) has no coarse triangle; it is too small to coarsen", panel, i);
    if (!locators[panel]) locators[panel] = std::make_unique<TriangleLocator>(coarse.mesh, panel_tris[panel]);
    const auto [t, w] = locators[panel]->locate(fine.mesh.u.col(i));
    for (int k = 0; k < 3; ++k)
      if (w[k] != 0.0) rows[i].push_back({coarse.mesh.tris[t][k], w[k]});
  }

  linalg::StencilTable table;
  table.num_rows = nf;
  table.num_cols = ncoarse;
  table.offsets.assign(1, 0);
  for (auto& row : rows) {
    std::sort(row.begin(), row.end());
    for (const auto& [j, w] : row) {
      if (w == 0.0) continue;
      table.indices.push_back(j);
      table.weights.push_back(w);
    }
    table.offsets.push_back(static_cast<Index>(table.indices.size()));
  }
  table.build_transpose();
  return table;
}

// ----------------------------------------------------------------------------------------------- coarsen ---

struct Selection {
  std::vector<Index> vertices;                 ///< selected fine vertices, increasing
  std::vector<std::vector<Index>> loops;       ///< selected vertices of each boundary loop, in loop order
};

Selection select(const Level& fine, const mesh::Topology& topo, const Partners& partners, const std::vector<char>& forced,
                 double r, const HierarchyParams& params, std::uint64_t seed) {
  const mesh::TriMesh& m = fine.mesh;
  const Index n = m.num_vertices();
  std::vector<char> selected(forced.begin(), forced.end()), done(n, 0);
  const double corner = params.corner_angle_deg * std::numbers::pi / 180.0;
  const auto adjacent = [&](Index a, Index b) {
    const auto first = topo.adjacency.begin() + topo.adjacency_offsets[a];
    const auto last = topo.adjacency.begin() + topo.adjacency_offsets[a + 1];
    return std::binary_search(first, last, b);
  };
  for (const auto& loop : topo.boundary_loops) {
    const Index len = static_cast<Index>(loop.size());
    std::vector<char> seam_edge(len, 0);
    for (Index k = 0; k < len; ++k) {
      const Index v = loop[k], w = loop[(k + 1) % len];
      partners.for_each(v, [&](Index p) { partners.for_each(w, [&](Index q) { seam_edge[k] |= adjacent(p, q); }); });
    }
    select_boundary(m, loop, r, corner, forced, partners, seam_edge, selected, done);
  }
  select_interior(m, topo.is_boundary_vertex, r, seed, selected);
  for (const auto& g : topo.stitch_groups) {  // an interior stitched vertex takes its partners along
    bool any = false;
    for (Index v : g) any = any || selected[v];
    if (any)
      for (Index v : g) selected[v] = 1;
  }
  Selection s;
  for (Index i = 0; i < n; ++i)
    if (selected[i]) s.vertices.push_back(i);
  for (const auto& loop : topo.boundary_loops) {
    s.loops.emplace_back();
    for (Index v : loop)
      if (selected[v]) s.loops.back().push_back(v);
  }
  return s;
}

void check_params(const mesh::TriMesh& finest, const HierarchyParams& p) {
  if (!(p.ratio > 1.0) || !std::isfinite(p.ratio)) throw_input_error("hierarchy: ratio must exceed 1 (got {})", p.ratio);
  if (p.min_coarse_vertices < 3 || p.max_coarse_vertices < p.min_coarse_vertices)
    throw_input_error("hierarchy: need 3 <= min_coarse_vertices <= max_coarse_vertices (got {} and {})",
                      p.min_coarse_vertices, p.max_coarse_vertices);
  for (Index v : p.keep)
    if (v < 0 || v >= finest.num_vertices())
      throw_input_error("hierarchy: keep vertex {} is out of range (mesh has {} vertices)", v, finest.num_vertices());
}

}  // namespace

TriangleHierarchy build_triangle_hierarchy(const mesh::TriMesh& finest, const HierarchyParams& params) {
  check_params(finest, params);
  std::vector<Level> levels(1);
  levels[0].mesh = finest;
  const Index n0 = finest.num_vertices();
  levels[0].fine_index.resize(n0);
  for (Index i = 0; i < n0; ++i) levels[0].fine_index[i] = i;
  levels[0].to_finest = levels[0].fine_index;
  std::vector<linalg::StencilTable> prolongations;

  while (levels.back().mesh.num_vertices() > params.max_coarse_vertices) {
    const Level& fine = levels.back();
    const Index n = fine.mesh.num_vertices();
    const mesh::Topology topo = mesh::build_topology(fine.mesh, "hierarchy level");
    std::vector<char> forced(n, 0);
    {
      std::vector<Index> local(n0, -1);
      for (Index i = 0; i < n; ++i) local[fine.to_finest[i]] = i;
      for (Index v : params.keep)
        if (local[v] >= 0) forced[local[v]] = 1;
    }
    const Partners partners(n, topo.stitch_groups);
    for (const auto& g : topo.stitch_groups) {  // a kept vertex keeps the whole stitched point
      bool any = false;
      for (Index v : g) any = any || forced[v];
      if (any)
        for (Index v : g) forced[v] = 1;
    }
    const double target = std::max(static_cast<double>(n) / params.ratio,
                                   static_cast<double>(params.min_coarse_vertices));
    const std::uint64_t seed = params.seed + 0x9E3779B97F4A7C15ull * levels.size();
    // A maximal Poisson-disk sample of radius r has ~0.7 / r^2 points per area against ~1.15 / h^2 for a mesh
    // of mean edge h, hence the 0.8; the radius is then rescaled until the count is within 10% of the target.
    double r = 0.8 * std::sqrt(static_cast<double>(n) / target) * mesh::mean_material_edge_length(fine.mesh);
    // Once a too-small and a too-large radius are known, bisect between them (on a regular grid the count jumps).
    Selection best;
    double best_error = kInf, r_small = 0.0, r_large = kInf;
    for (int iter = 0; iter < 8; ++iter) {
      Selection s = select(fine, topo, partners, forced, r, params, seed);
      const double count = static_cast<double>(s.vertices.size());
      const double error = std::abs(std::log(count / target));
      if (error < best_error) best_error = error, best = std::move(s);
      if (best_error < std::log(1.1)) break;
      (count > target ? r_small : r_large) = r;
      r *= std::sqrt(count / target);
      if (r_small > 0.0 && r_large < kInf && !(r > r_small && r < r_large)) r = 0.5 * (r_small + r_large);
    }
    if (static_cast<double>(best.vertices.size()) > 0.9 * n) break;  // no longer coarsening
    Level coarse = triangulate(fine, topo, best.vertices, best.loops);
    prolongations.push_back(build_prolongation(fine, coarse, topo));
    levels.push_back(std::move(coarse));
  }
  return TriangleHierarchy(std::move(levels), std::move(prolongations));
}

Hierarchy TriangleHierarchy::levels_for_solvers() const {
  Hierarchy h;
  for (Index l = 0; l < num_levels(); ++l) {
    Hierarchy::Level level;
    level.num_points = m_levels[l].mesh.num_vertices();
    if (l + 1 < num_levels()) {
      level.prolongation = &m_prolongations[l];
      const std::vector<Index>* inj = &m_levels[l + 1].fine_index;
      level.project = [inj](const VecX& fine, VecX& coarse) {
        coarse.resize(3 * static_cast<Index>(inj->size()));
        for (size_t i = 0; i < inj->size(); ++i) coarse.segment<3>(3 * static_cast<Index>(i)) = fine.segment<3>(3 * (*inj)[i]);
      };
    }
    h.levels.push_back(std::move(level));
  }
  return h;
}

}  // namespace mgcloth::hierarchy
