#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/topology.hpp>

#include <algorithm>

namespace mgcloth::mesh {

namespace {

Index side_start(const std::vector<Tri>& tris, Index s) { return tris[s / 3][s % 3]; }
Index side_end(const std::vector<Tri>& tris, Index s) { return tris[s / 3][(s % 3 + 1) % 3]; }

void check_triangles(const TriMesh& mesh, const std::string& source) {
  const Index n = mesh.num_vertices();
  for (Index t = 0; t < mesh.num_triangles(); ++t) {
    const Tri& f = mesh.tris[t];
    for (Index v : f)
      if (v < 0 || v >= n)
        throw_input_error("{}: triangle {} (vertices {}, {}, {}) refers to a vertex outside [0, {})", source, t,
                          f[0], f[1], f[2], n);
    if (f[0] == f[1] || f[1] == f[2] || f[2] == f[0])
      throw_input_error("{}: triangle {} (vertices {}, {}, {}) repeats a vertex", source, t, f[0], f[1], f[2]);
  }
}

[[noreturn]] void throw_non_manifold(const EdgeGroups& groups, Index e, const std::string& source) {
  std::string tris;
  for (Index i = groups.offsets[e]; i < groups.offsets[e + 1]; ++i)
    tris += fmt::format("{}{}", i > groups.offsets[e] ? ", " : "", groups.sides[i] / 3);
  throw_input_error("{}: edge ({}, {}) is shared by {} triangles ({}); at most two may share an edge", source,
                    groups.edges[e][0], groups.edges[e][1], groups.count(e), tris);
}

Hinge make_hinge(const std::vector<Tri>& tris, Index s0, Index s1) {
  const Tri& f0 = tris[s0 / 3];
  const Tri& f1 = tris[s1 / 3];
  const Index k0 = s0 % 3, k1 = s1 % 3;
  return Hinge{{f0[k0], f0[(k0 + 1) % 3], f0[(k0 + 2) % 3], f1[(k1 + 2) % 3]}, {s0 / 3, s1 / 3}};
}

/// CSR adjacency from edges sorted by (v0, v1): vertex a first receives its smaller neighbours (from edges (c, a),
/// visited in increasing c) and then its larger ones (edges (a, b), increasing b), so every list comes out sorted.
void build_adjacency(const std::vector<std::array<Index, 2>>& edges, Index num_vertices, Topology& topo) {
  topo.adjacency_offsets.assign(num_vertices + 1, 0);
  for (const auto& e : edges) {
    ++topo.adjacency_offsets[e[0] + 1];
    ++topo.adjacency_offsets[e[1] + 1];
  }
  for (Index v = 0; v < num_vertices; ++v) topo.adjacency_offsets[v + 1] += topo.adjacency_offsets[v];
  topo.adjacency.resize(topo.adjacency_offsets[num_vertices]);
  std::vector<Index> pos(topo.adjacency_offsets.begin(), topo.adjacency_offsets.end() - 1);
  for (const auto& e : edges) {
    topo.adjacency[pos[e[0]]++] = e[1];
    topo.adjacency[pos[e[1]]++] = e[0];
  }
}

}  // namespace

EdgeGroups group_triangle_sides(const std::vector<Tri>& tris, Index num_vertices) {
  const Index num_tris = static_cast<Index>(tris.size());
  auto valid = [&](const Tri& f) {
    for (Index v : f)
      if (v < 0 || v >= num_vertices) return false;
    return true;
  };

  // Bucket every side by its smaller vertex (a counting sort), then order each small bucket by the larger vertex.
  std::vector<Index> bucket_start(static_cast<std::size_t>(num_vertices) + 1, 0);
  for (const Tri& f : tris) {
    if (!valid(f)) continue;
    for (int k = 0; k < 3; ++k) {
      const Index a = f[k], b = f[(k + 1) % 3];
      if (a != b) ++bucket_start[std::min(a, b) + 1];
    }
  }
  for (Index v = 0; v < num_vertices; ++v) bucket_start[v + 1] += bucket_start[v];

  struct Entry {
    Index other;
    Index side;
  };
  std::vector<Entry> entries(bucket_start[num_vertices]);
  std::vector<Index> fill(bucket_start.begin(), bucket_start.end() - 1);
  for (Index t = 0; t < num_tris; ++t) {
    const Tri& f = tris[t];
    if (!valid(f)) continue;
    for (int k = 0; k < 3; ++k) {
      const Index a = f[k], b = f[(k + 1) % 3];
      if (a != b) entries[fill[std::min(a, b)]++] = {std::max(a, b), 3 * t + k};
    }
  }

  EdgeGroups groups;
  groups.edges.reserve(entries.size() / 2 + 1);
  groups.offsets.reserve(entries.size() / 2 + 2);
  groups.sides.reserve(entries.size());
  for (Index v = 0; v < num_vertices; ++v) {
    const auto first = entries.begin() + bucket_start[v];
    const auto last = entries.begin() + bucket_start[v + 1];
    // Stable, so sides of one edge stay in increasing order (they were filled in that order).
    std::stable_sort(first, last, [](const Entry& p, const Entry& q) { return p.other < q.other; });
    for (auto it = first; it != last; ++it) {
      if (it == first || it->other != (it - 1)->other) {
        groups.edges.push_back({v, it->other});
        groups.offsets.push_back(static_cast<Index>(groups.sides.size()));
      }
      groups.sides.push_back(it->side);
    }
  }
  groups.offsets.push_back(static_cast<Index>(groups.sides.size()));
  return groups;
}

std::vector<std::vector<Index>> find_boundary_loops(const std::vector<Tri>& tris, const EdgeGroups& groups) {
  std::vector<Index> boundary_sides;
  Index num_vertices = 0;
  std::vector<Index> side_edge(3 * tris.size(), -1);
  for (Index e = 0; e < groups.num_edges(); ++e) {
    if (groups.count(e) == 1) boundary_sides.push_back(groups.sides[groups.offsets[e]]);
    for (Index i = groups.offsets[e]; i < groups.offsets[e + 1]; ++i) side_edge[groups.sides[i]] = e;
    num_vertices = std::max(num_vertices, groups.edges[e][1] + 1);
  }
  std::sort(boundary_sides.begin(), boundary_sides.end());
  auto boundary_index = [&](Index side) {
    return static_cast<Index>(std::lower_bound(boundary_sides.begin(), boundary_sides.end(), side) -
                              boundary_sides.begin());
  };

  // Outgoing boundary sides of every vertex (CSR); a vertex has more than one only where boundaries touch.
  std::vector<Index> out_start(static_cast<std::size_t>(num_vertices) + 1, 0);
  for (Index s : boundary_sides) ++out_start[side_start(tris, s) + 1];
  for (Index v = 0; v < num_vertices; ++v) out_start[v + 1] += out_start[v];
  std::vector<Index> out(boundary_sides.size());
  std::vector<Index> fill(out_start.begin(), out_start.end() - 1);
  for (std::size_t i = 0; i < boundary_sides.size(); ++i)
    out[fill[side_start(tris, boundary_sides[i])]++] = static_cast<Index>(i);
  std::vector<char> used(boundary_sides.size(), 0);

  // Where boundaries touch at a vertex, the loop must leave through the same fan of triangles it arrived in:
  // rotate about the vertex from the arriving side across interior edges until a boundary side leaves it.
  auto leave_same_fan = [&](Index arriving) -> Index {
    Index s = 3 * (arriving / 3) + (arriving % 3 + 1) % 3;
    for (std::size_t guard = 0; guard < tris.size(); ++guard) {
      const Index e = side_edge[s];
      if (e < 0) return -1;
      if (groups.count(e) == 1) {
        const Index i = boundary_index(s);
        return used[i] ? -1 : i;
      }
      if (groups.count(e) != 2) return -1;
      const Index* pair = groups.sides.data() + groups.offsets[e];
      const Index other = pair[0] == s ? pair[1] : pair[0];
      if (side_start(tris, other) != side_end(tris, s)) return -1;  // inconsistent orientation
      s = 3 * (other / 3) + (other % 3 + 1) % 3;
    }
    return -1;
  };
  auto next_unused = [&](Index arriving, Index v) -> Index {
    if (out_start[v + 1] - out_start[v] > 1) {
      const Index i = leave_same_fan(arriving);
      if (i >= 0) return i;
    }
    for (Index j = out_start[v]; j < out_start[v + 1]; ++j)
      if (!used[out[j]]) return out[j];
    return -1;
  };

  std::vector<std::vector<Index>> loops;
  for (std::size_t first = 0; first < boundary_sides.size(); ++first) {
    if (used[first]) continue;
    std::vector<Index> loop;
    const Index start = side_start(tris, boundary_sides[first]);
    Index i = static_cast<Index>(first);
    while (i >= 0) {
      used[i] = 1;
      loop.push_back(side_start(tris, boundary_sides[i]));
      const Index v = side_end(tris, boundary_sides[i]);
      if (v == start) break;
      i = next_unused(boundary_sides[i], v);
    }
    loops.push_back(std::move(loop));
  }
  return loops;
}

Topology build_topology(const TriMesh& mesh, const std::string& source) {
  check_triangles(mesh, source);
  const Index num_vertices = mesh.num_vertices();
  EdgeGroups groups = group_triangle_sides(mesh.tris, num_vertices);

  Topology topo;
  const Index num_edges = groups.num_edges();
  topo.edge_tris.resize(num_edges);
  topo.tri_edges.resize(mesh.tris.size());
  topo.is_boundary_vertex.assign(num_vertices, false);
  for (Index e = 0; e < num_edges; ++e) {
    const Index c = groups.count(e);
    if (c > 2) throw_non_manifold(groups, e, source);
    const Index* s = groups.sides.data() + groups.offsets[e];
    for (Index i = 0; i < c; ++i) topo.tri_edges[s[i] / 3][s[i] % 3] = e;
    if (c == 2) {
      topo.edge_tris[e] = {s[0] / 3, s[1] / 3};
      topo.hinges.push_back(make_hinge(mesh.tris, s[0], s[1]));
    } else {
      topo.edge_tris[e] = {s[0] / 3, -1};
      topo.is_boundary_vertex[groups.edges[e][0]] = true;
      topo.is_boundary_vertex[groups.edges[e][1]] = true;
    }
  }
  topo.boundary_loops = find_boundary_loops(mesh.tris, groups);
  topo.edges = std::move(groups.edges);
  build_adjacency(topo.edges, num_vertices, topo);
  topo.component.assign(num_vertices, -1);
  std::vector<Index> stack;
  for (Index seed = 0; seed < num_vertices; ++seed) {
    if (topo.component[seed] >= 0) continue;
    const Index c = topo.num_components++;
    topo.component[seed] = c;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const Index v = stack.back();
      stack.pop_back();
      for (Index k = topo.adjacency_offsets[v]; k < topo.adjacency_offsets[v + 1]; ++k)
        if (const Index w = topo.adjacency[k]; topo.component[w] < 0) topo.component[w] = c, stack.push_back(w);
    }
  }
  topo.stitch_groups = find_stitch_groups(mesh);
  return topo;
}

std::vector<std::vector<Index>> find_stitch_groups(const TriMesh& mesh) {
  std::vector<std::vector<Index>> groups;
  if (mesh.source_vertex.empty()) return groups;
  std::vector<std::pair<Index, Index>> by_source;
  for (Index i = 0; i < mesh.num_vertices(); ++i) by_source.push_back({mesh.source_vertex[i], i});
  std::sort(by_source.begin(), by_source.end());
  for (std::size_t a = 0; a < by_source.size();) {
    std::size_t b = a + 1;
    while (b < by_source.size() && by_source[b].first == by_source[a].first) ++b;
    if (b - a > 1) {
      groups.emplace_back();
      for (std::size_t k = a; k < b; ++k) groups.back().push_back(by_source[k].second);
    }
    a = b;
  }
  std::sort(groups.begin(), groups.end());
  return groups;
}

}  // namespace mgcloth::mesh
