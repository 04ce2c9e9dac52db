#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/mesh/tri_mesh.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace mgcloth::mesh {

namespace {

double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

bool in_range(const Tri& t, Index n) {
  return t[0] >= 0 && t[0] < n && t[1] >= 0 && t[1] < n && t[2] >= 0 && t[2] < n;
}

void check_sizes(const TriMesh& mesh, const std::string& source) {
  if (mesh.u.cols() != mesh.x.cols())
    throw_input_error("{}: has {} world positions but {} material coordinates", source, mesh.x.cols(),
                      mesh.u.cols());
  if (!mesh.source_vertex.empty() && static_cast<Index>(mesh.source_vertex.size()) != mesh.num_vertices())
    throw_input_error("{}: has {} vertices but {} source-vertex entries", source, mesh.num_vertices(),
                      mesh.source_vertex.size());
  if (mesh.tris.empty()) throw_input_error("{}: has no triangles", source);
}

void check_finite(const TriMesh& mesh, const std::string& source) {
  for (Index i = 0; i < mesh.num_vertices(); ++i) {
    if (!mesh.x.col(i).allFinite())
      throw_input_error("{}: vertex {} has a non-finite world position ({}, {}, {})", source, i, mesh.x(0, i),
                        mesh.x(1, i), mesh.x(2, i));
    if (!mesh.u.col(i).allFinite())
      throw_input_error("{}: vertex {} has a non-finite material coordinate ({}, {})", source, i, mesh.u(0, i),
                        mesh.u(1, i));
  }
}

void check_indices(const TriMesh& mesh, const std::string& source) {
  const Index n = mesh.num_vertices();
  std::vector<char> used(n, 0);
  for (Index t = 0; t < mesh.num_triangles(); ++t) {
    const Tri& f = mesh.tris[t];
    if (!in_range(f, n))
      throw_input_error("{}: triangle {} (vertices {}, {}, {}) refers to a vertex outside [0, {})", source, t, f[0],
                        f[1], f[2], n);
    if (f[0] == f[1] || f[1] == f[2] || f[2] == f[0])
      throw_input_error("{}: triangle {} (vertices {}, {}, {}) repeats a vertex", source, t, f[0], f[1], f[2]);
    used[f[0]] = used[f[1]] = used[f[2]] = 1;
  }
  for (Index i = 0; i < n; ++i)
    if (!used[i]) throw_input_error("{}: vertex {} is not used by any triangle (it would have no mass)", source, i);
}

void check_areas_and_flip(TriMesh& mesh, const std::string& source) {
  const double mean_edge = mean_material_edge_length(mesh);
  for (Index t = 0; t < mesh.num_triangles(); ++t) {
    Tri& f = mesh.tris[t];
    if (is_degenerate(mesh, t, mean_edge))
      throw_input_error("{}: triangle {} (vertices {}, {}, {}) has near-zero area in material space (area {:.3g} m^2; "
                        "longest edge {:.3g} m, mean edge {:.3g} m)",
                        source, t, f[0], f[1], f[2], std::abs(mesh.material_area(t)), longest_material_edge(mesh, t),
                        mean_edge);
    if (const double l = longest_material_edge(mesh, t); l < kMinMaterialEdge)
      throw_input_error("{}: triangle {} (vertices {}, {}, {}) is {:.3g} m across in material space; a cloth element "
                        "needs at least {:g} m (check the mesh's units or material_scale)",
                        source, t, f[0], f[1], f[2], l, kMinMaterialEdge);
    if (mesh.material_area(t) < 0.0) std::swap(f[1], f[2]);
  }
}

/// After the flips every triangle is CCW in material space, so two triangles that agree about the direction of
/// their shared edge lie on the same side of it: they overlap.
void check_manifold_and_orientation(const TriMesh& mesh, const std::string& source) {
  const EdgeGroups groups = group_triangle_sides(mesh.tris, mesh.num_vertices());
  for (Index e = 0; e < groups.num_edges(); ++e) {
    const Index* s = groups.sides.data() + groups.offsets[e];
    const Index c = groups.count(e);
    if (c > 2) {
      std::string tris;
      for (Index i = 0; i < c; ++i) tris += fmt::format("{}{}", i ? ", " : "", s[i] / 3);
      throw_input_error("{}: edge ({}, {}) is shared by {} triangles ({}); at most two may share an edge", source,
                        groups.edges[e][0], groups.edges[e][1], c, tris);
    }
    if (c == 2 && mesh.tris[s[0] / 3][s[0] % 3] == mesh.tris[s[1] / 3][s[1] % 3])
      throw_input_error(
          "{}: triangles {} and {} share edge ({}, {}) but overlap in material space (inconsistent orientation)",
          source, s[0] / 3, s[1] / 3, groups.edges[e][0], groups.edges[e][1]);
  }
}

}  // namespace

double TriMesh::material_area(Index t) const {
  const Tri& f = tris[t];
  const Vec2 u0 = u.col(f[0]);
  return 0.5 * cross2(u.col(f[1]) - u0, u.col(f[2]) - u0);
}

double TriMesh::world_area(Index t) const {
  const Tri& f = tris[t];
  const Vec3 x0 = x.col(f[0]);
  return 0.5 * (x.col(f[1]) - x0).cross(x.col(f[2]) - x0).norm();
}

double TriMesh::total_material_area() const {
  double a = 0.0;
  for (Index t = 0; t < num_triangles(); ++t) a += material_area(t);
  return a;
}

double mean_material_edge_length(const TriMesh& mesh) {
  const Index n = std::min<Index>(mesh.num_vertices(), static_cast<Index>(mesh.u.cols()));
  double sum = 0.0;
  std::size_t count = 0;
  for (const Tri& f : mesh.tris) {
    if (!in_range(f, n)) continue;
    for (int k = 0; k < 3; ++k) sum += (mesh.u.col(f[(k + 1) % 3]) - mesh.u.col(f[k])).norm();
    count += 3;
  }
  return count ? sum / static_cast<double>(count) : 0.0;
}

double longest_material_edge(const TriMesh& mesh, Index t) {
  const Tri& f = mesh.tris[t];
  double m = 0.0;
  for (int k = 0; k < 3; ++k) m = std::max(m, (mesh.u.col(f[(k + 1) % 3]) - mesh.u.col(f[k])).squaredNorm());
  return std::sqrt(m);
}

bool is_degenerate(const TriMesh& mesh, Index t, double mean_edge) {
  const double l = longest_material_edge(mesh, t);
  const double tolerance = std::max(kSliverAreaRatio * l * l, kDegenerateAreaRatio * mean_edge * mean_edge);
  // `!(a > b)` rather than `a <= b` so that a NaN area counts as degenerate.
  return !(std::abs(mesh.material_area(t)) > tolerance);
}

void validate(TriMesh& mesh, const std::string& source) {
  check_sizes(mesh, source);
  check_finite(mesh, source);
  check_indices(mesh, source);
  check_areas_and_flip(mesh, source);
  check_manifold_and_orientation(mesh, source);
}

}  // namespace mgcloth::mesh
