#pragma once
#include <mgcloth/mesh/tri_mesh.hpp>

namespace mgcloth::mesh {

/// An interior edge with its two triangles: v[0]-v[1] is the edge, v[2] the opposite vertex in tri[0], v[3] the
/// opposite vertex in tri[1]. Ordered so that (v0, v1, v2) has the orientation of tri[0] and (v1, v0, v3) the
/// orientation of tri[1].
struct Hinge {
  std::array<Index, 4> v;
  std::array<Index, 2> tri;
};

/// Connectivity derived once from a mesh.
struct Topology {
  std::vector<std::array<Index, 2>> edges;       ///< unique undirected edges, v0 < v1
  std::vector<std::array<Index, 2>> edge_tris;   ///< the one or two triangles of each edge (-1 when boundary)
  std::vector<std::array<Index, 3>> tri_edges;   ///< edge index of triangle side (v0v1, v1v2, v2v0)
  std::vector<Hinge> hinges;                     ///< every interior edge
  std::vector<std::vector<Index>> boundary_loops;///< vertex loops along boundary edges, in order
  std::vector<Index> adjacency_offsets;          ///< vertex adjacency in CSR form (neighbours sorted, self excluded)
  std::vector<Index> adjacency;
  std::vector<bool> is_boundary_vertex;
  /// Panel (connected component of the edge graph) of each vertex, numbered in order of their smallest vertex.
  std::vector<Index> component;
  Index num_components = 0;
  /// Seams: groups of two or more vertices that are one point of the garment (the same OBJ position split at UV
  /// seams, TriMesh::source_vertex), stitched together in simulation. Members sorted; groups by first member.
  std::vector<std::vector<Index>> stitch_groups;

  Index num_edges() const { return static_cast<Index>(edges.size()); }
};

/// The sides of all triangles grouped by undirected edge. Side s = 3t + k runs from tris[t][k] to
/// tris[t][(k+1)%3]. Groups are ordered by (smaller vertex, larger vertex), sides within a group by s.
struct EdgeGroups {
  std::vector<std::array<Index, 2>> edges;  ///< v0 < v1
  std::vector<Index> offsets;               ///< sides of edge e: sides[offsets[e] .. offsets[e+1])
  std::vector<Index> sides;

  Index num_edges() const { return static_cast<Index>(edges.size()); }
  Index count(Index e) const { return offsets[e + 1] - offsets[e]; }
};

/// Groups triangle sides in linear time (bucketed by smaller vertex, so no global sort). Never throws on bad
/// input: triangles with an index outside [0, num_vertices) and sides whose two ends coincide are left out.
EdgeGroups group_triangle_sides(const std::vector<Tri>& tris, Index num_vertices);

/// Vertex loops along the boundary edges (edges with exactly one triangle), each walked in the direction of its
/// triangle: with triangles CCW in material space, outer boundaries come out CCW and holes CW. Loops are ordered
/// by their smallest boundary side. Never throws: where orientation is inconsistent a walk may stop before it
/// closes, and that open chain is returned as a loop.
std::vector<std::vector<Index>> find_boundary_loops(const std::vector<Tri>& tris, const EdgeGroups& groups);

/// Stitch groups of a mesh from its source_vertex (empty when it has none); see Topology::stitch_groups.
std::vector<std::vector<Index>> find_stitch_groups(const TriMesh& mesh);

/// Throws InputError (naming `source`, the edge and its triangles) for non-manifold edges.
Topology build_topology(const TriMesh& mesh, const std::string& source = "mesh");

}  // namespace mgcloth::mesh
