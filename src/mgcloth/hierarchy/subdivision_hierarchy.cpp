#include <mgcloth/core/error.hpp>
#include <mgcloth/core/out_of_memory.hpp>
#include <mgcloth/hierarchy/subdivision_hierarchy.hpp>

#include <algorithm>
#include <map>
#include <set>

namespace mgcloth::hierarchy {

namespace {

/// A row of S under construction: coarse point -> weight.
using Row = std::map<Index, double>;

struct Connectivity {
  std::vector<std::array<Index, 2>> edges;          // end points, smaller first
  std::vector<std::vector<Index>> edge_faces;        // 1 (boundary) or 2 faces
  std::vector<std::array<Index, 4>> face_edges;      // edge of (q[k], q[k+1])
  std::vector<std::vector<Index>> vertex_edges;
  std::vector<std::vector<Index>> vertex_faces;
};

Connectivity connect(const mesh::QuadMesh& m) {
  Connectivity c;
  std::map<std::pair<Index, Index>, Index> id;
  std::set<std::pair<Index, Index>> directed;
  c.face_edges.resize(m.quads.size());
  c.vertex_edges.resize(static_cast<size_t>(m.num_vertices()));
  c.vertex_faces.resize(static_cast<size_t>(m.num_vertices()));
  for (Index f = 0; f < m.num_faces(); ++f) {
    const mesh::Quad& q = m.quads[f];
    for (int k = 0; k < 4; ++k) {
      const Index a = q[k], b = q[(k + 1) % 4];
      if (a < 0 || b < 0 || a >= m.num_vertices() || b >= m.num_vertices())
        throw_input_error("quad {} refers to point {}, but the mesh has {} points", f, a < 0 || a >= m.num_vertices() ? a : b,
                          m.num_vertices());
      if (a == b) throw_input_error("quad {} is degenerate: point {} repeats", f, a);
      if (!directed.insert({a, b}).second)
        throw_input_error("edge ({}, {}) of quad {} is used twice in the same direction (a duplicate quad or "
                          "inconsistent orientation)", a, b, f);
      const auto key = std::minmax(a, b);
      auto [it, fresh] = id.try_emplace({key.first, key.second}, static_cast<Index>(c.edges.size()));
      if (fresh) {
        c.edges.push_back({key.first, key.second});
        c.edge_faces.emplace_back();
        c.vertex_edges[a].push_back(it->second);
        c.vertex_edges[b].push_back(it->second);
      }
      auto& faces = c.edge_faces[it->second];
      faces.push_back(f);
      if (faces.size() > 2) throw_input_error("edge ({}, {}) is shared by more than two quads (non-manifold)", a, b);
      c.face_edges[f][k] = it->second;
      c.vertex_faces[q[k]].push_back(f);
    }
  }
  return c;
}

void add_face_point(Row& row, const mesh::QuadMesh& m, Index f, double w) {
  for (Index v : m.quads[f]) row[v] += 0.25 * w;  // eq. (5.12), N = 4
}

}  // namespace

SubdivisionStep subdivide(const mesh::QuadMesh& coarse) {
  const Connectivity c = connect(coarse);
  const Index nv = coarse.num_vertices(), ne = static_cast<Index>(c.edges.size()), nf = coarse.num_faces();
  std::vector<Row> rows(static_cast<size_t>(nv + ne + nf));
  std::vector<char> kind(rows.size());
  std::vector<std::array<Index, 2>> parent(rows.size());

  for (Index v = 0; v < nv; ++v) {
    Row& row = rows[v];
    kind[v] = 0;
    parent[v] = {v, -1};
    std::vector<Index> boundary_nbrs;
    for (Index e : c.vertex_edges[v])
      if (c.edge_faces[e].size() == 1) boundary_nbrs.push_back(c.edges[e][0] == v ? c.edges[e][1] : c.edges[e][0]);
    if (c.vertex_faces[v].empty()) throw_input_error("control point {} belongs to no quad", v);
    if (boundary_nbrs.empty()) {
      // eq. (5.14): v' = (n-2)/n v + 1/n^2 sum e_j + 1/n^2 sum f_j, with n the valence.
      const double n = static_cast<double>(c.vertex_edges[v].size());
      row[v] += (n - 2.0) / n;
      for (Index e : c.vertex_edges[v]) row[c.edges[e][0] == v ? c.edges[e][1] : c.edges[e][0]] += 1.0 / (n * n);
      for (Index f : c.vertex_faces[v]) add_face_point(row, coarse, f, 1.0 / (n * n));
    } else if (boundary_nbrs.size() == 2) {
      // eq. (A.2): the cubic B-spline curve rule along the boundary (its neighbours are the coarse boundary points).
      row[v] += 0.75;
      row[boundary_nbrs[0]] += 0.125;
      row[boundary_nbrs[1]] += 0.125;
    } else {
      throw_input_error("control point {} lies on {} boundary edges (a non-manifold point)", v, boundary_nbrs.size());
    }
  }
  for (Index e = 0; e < ne; ++e) {
    Row& row = rows[nv + e];
    kind[nv + e] = 1;
    parent[nv + e] = c.edges[e];
    if (c.edge_faces[e].size() == 2) {
      // eq. (5.13): the end points and the two face points, a quarter each.
      row[c.edges[e][0]] += 0.25;
      row[c.edges[e][1]] += 0.25;
      for (Index f : c.edge_faces[e]) add_face_point(row, coarse, f, 0.25);
    } else {
      row[c.edges[e][0]] += 0.5;  // eq. (A.1)
      row[c.edges[e][1]] += 0.5;
    }
  }
  for (Index f = 0; f < nf; ++f) {
    kind[nv + ne + f] = 2;
    parent[nv + ne + f] = {f, -1};
    add_face_point(rows[nv + ne + f], coarse, f, 1.0);
  }

  // Children of quad (a, b, c, d) with edge points e_k on (q[k], q[k+1]) and face point p, counter-clockwise.
  std::vector<mesh::Quad> quads;
  std::vector<char> ghost;
  const bool ghosts = !coarse.ghost_face.empty();
  for (Index f = 0; f < nf; ++f) {
    const mesh::Quad& q = coarse.quads[f];
    const Index p = nv + ne + f;
    for (int k = 0; k < 4; ++k) {
      const Index ek = nv + c.face_edges[f][k], eprev = nv + c.face_edges[f][(k + 3) % 4];
      quads.push_back({q[k], ek, p, eprev});
      ghost.push_back(coarse.is_ghost_face(f) ? 1 : 0);
    }
  }
  // §5.2.1: keep real faces and the ghost faces touching them; drop the outer ghost layer.
  std::vector<char> keep_face(quads.size(), 1);
  std::vector<char> on_real(rows.size(), 0);
  if (ghosts) {
    for (size_t f = 0; f < quads.size(); ++f)
      if (!ghost[f])
        for (Index v : quads[f]) on_real[v] = 1;
    for (size_t f = 0; f < quads.size(); ++f) {
      if (!ghost[f]) continue;
      bool touches = false;
      for (Index v : quads[f]) touches = touches || on_real[v];
      keep_face[f] = touches ? 1 : 0;
    }
  }
  std::vector<Index> new_id(rows.size(), -1);
  for (size_t f = 0; f < quads.size(); ++f)
    if (keep_face[f])
      for (Index v : quads[f]) new_id[v] = 0;
  SubdivisionStep out;
  Index kept = 0;
  for (size_t i = 0; i < rows.size(); ++i)
    if (new_id[i] == 0) new_id[i] = kept++;

  linalg::StencilTable& S = out.subdivision;
  S.num_rows = kept;
  S.num_cols = nv;
  S.offsets.assign(1, 0);
  out.kind.reserve(kept);
  out.parent.reserve(kept);
  mesh::QuadMesh& fine = out.fine;
  for (size_t i = 0; i < rows.size(); ++i) {
    if (new_id[i] < 0) continue;
    for (const auto& [j, w] : rows[i]) {
      if (w == 0.0) continue;
      S.indices.push_back(j);
      S.weights.push_back(w);
    }
    S.offsets.push_back(static_cast<Index>(S.indices.size()));
    out.kind.push_back(kind[i]);
    out.parent.push_back(parent[i]);
    if (ghosts) fine.ghost_vertex.push_back(on_real[i] ? 0 : 1);
  }
  S.build_transpose();
  for (size_t f = 0; f < quads.size(); ++f) {
    if (!keep_face[f]) continue;
    fine.quads.push_back({new_id[quads[f][0]], new_id[quads[f][1]], new_id[quads[f][2]], new_id[quads[f][3]]});
    if (ghosts) fine.ghost_face.push_back(ghost[f]);
  }
  fine.x.resize(3, kept);
  fine.u.resize(2, kept);
  for (Index i = 0; i < kept; ++i) {
    Vec3 x = Vec3::Zero();
    Vec2 u = Vec2::Zero();
    for (Index k = S.offsets[i]; k < S.offsets[i + 1]; ++k) {
      x += S.weights[k] * coarse.x.col(S.indices[k]);
      u += S.weights[k] * coarse.u.col(S.indices[k]);
    }
    fine.x.col(i) = x;
    fine.u.col(i) = u;
  }
  return out;
}

SubdivisionHierarchy::SubdivisionHierarchy(const mesh::QuadMesh& coarsest, int levels) {
  if (levels < 1) throw_input_error("subdivision hierarchy: needs at least 1 level (got {})", levels);
  m_meshes.push_back(coarsest);
  for (int l = 1; l < levels; ++l)
    building([&] { return fmt::format("subdivision level {} of {} (from {} quads)", l + 1, levels, m_meshes.back().num_faces()); },
             [&] {
               m_steps.push_back(subdivide(m_meshes.back()));
               m_meshes.push_back(m_steps.back().fine);
             });
}

}  // namespace mgcloth::hierarchy
