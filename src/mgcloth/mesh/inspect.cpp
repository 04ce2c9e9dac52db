#include <mgcloth/mesh/inspect.hpp>
#include <mgcloth/mesh/topology.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <numbers>

namespace mgcloth::mesh {

namespace {

constexpr std::size_t kListedIndices = 5;

double smallest_angle(const TriMesh& mesh, const Tri& f) {
  double m = kInf;
  for (int k = 0; k < 3; ++k) {
    const Vec2 a = mesh.u.col(f[(k + 1) % 3]) - mesh.u.col(f[k]);
    const Vec2 b = mesh.u.col(f[(k + 2) % 3]) - mesh.u.col(f[k]);
    m = std::min(m, std::atan2(std::abs(a.x() * b.y() - a.y() * b.x()), a.dot(b)));
  }
  return m;
}

std::string first_indices(const std::vector<Index>& v) {
  std::string s;
  for (std::size_t i = 0; i < std::min(v.size(), kListedIndices); ++i) s += fmt::format("{}{}", i ? ", " : "", v[i]);
  if (v.size() > kListedIndices) s += ", ...";
  return s;
}

}  // namespace

MeshReport inspect(const TriMesh& mesh) {
  MeshReport r;
  try {
    r.vertices = mesh.num_vertices();
    r.triangles = mesh.num_triangles();
    r.sizes_match = mesh.u.cols() == mesh.x.cols();
    const Index n = std::min<Index>(r.vertices, static_cast<Index>(mesh.u.cols()));
    for (Index i = 0; i < r.vertices; ++i)
      if (!mesh.x.col(i).allFinite() || (i < n && !mesh.u.col(i).allFinite())) ++r.non_finite_vertices;

    // Statistics below look only at triangles whose indices are in range, oriented CCW in material space as
    // validate() would orient them, so that a mirrored chart does not show up as broken boundaries.
    const double mean_edge = mean_material_edge_length(mesh);
    std::vector<Tri> oriented;
    std::vector<char> degenerate;
    oriented.reserve(mesh.tris.size());
    std::vector<char> referenced(r.vertices, 0);
    double min_angle = kInf;
    for (Index t = 0; t < r.triangles; ++t) {
      Tri f = mesh.tris[t];
      const bool valid = std::all_of(f.begin(), f.end(), [&](Index v) { return v >= 0 && v < n; });
      if (!valid) {
        r.invalid_triangles.push_back(t);
        oriented.push_back({-1, -1, -1});  // keeps side numbering; group_triangle_sides skips it
        degenerate.push_back(1);
        continue;
      }
      for (Index v : f) referenced[v] = 1;
      const double area = mesh.material_area(t);
      r.world_area += mesh.world_area(t);
      const bool is_zero = is_degenerate(mesh, t, mean_edge);
      degenerate.push_back(is_zero);
      if (is_zero) {
        r.degenerate_triangles.push_back(t);
      } else {
        if (longest_material_edge(mesh, t) < kMinMaterialEdge) r.tiny_triangles.push_back(t);
        r.material_area += std::abs(area);
        min_angle = std::min(min_angle, smallest_angle(mesh, f));
        if (area < 0.0) {
          ++r.negative_area_triangles;
          std::swap(f[1], f[2]);
        }
      }
      oriented.push_back(f);
    }
    r.min_angle_deg = std::isfinite(min_angle) ? min_angle * 180.0 / std::numbers::pi : 0.0;
    r.unreferenced_vertices = static_cast<Index>(std::count(referenced.begin(), referenced.end(), 0));

    const EdgeGroups groups = group_triangle_sides(oriented, n);
    r.edges = groups.num_edges();
    double sum = 0.0;
    r.min_edge = kInf;
    for (Index e = 0; e < groups.num_edges(); ++e) {
      const double len = (mesh.u.col(groups.edges[e][1]) - mesh.u.col(groups.edges[e][0])).norm();
      r.min_edge = std::min(r.min_edge, len);
      r.max_edge = std::max(r.max_edge, len);
      sum += len;
      const Index* s = groups.sides.data() + groups.offsets[e];
      if (groups.count(e) > 2) r.non_manifold_edges_first_tri.push_back(s[0] / 3);
      if (groups.count(e) == 2 && !degenerate[s[0] / 3] && !degenerate[s[1] / 3] &&
          oriented[s[0] / 3][s[0] % 3] == oriented[s[1] / 3][s[1] % 3])
        ++r.inconsistent_edges;
    }
    if (r.edges == 0) r.min_edge = 0.0;
    r.mean_edge = r.edges ? sum / r.edges : 0.0;
    r.boundary_loops = static_cast<Index>(find_boundary_loops(oriented, groups).size());
  } catch (...) {
    // Only allocation can fail here; a partial report beats an exception from a diagnostic tool.
  }
  return r;
}

std::string format_report(const MeshReport& r, const std::string& name) {
  fmt::memory_buffer b;
  auto out = std::back_inserter(b);
  fmt::format_to(out, "{}\n", name);
  fmt::format_to(out, "  vertices             {}\n", r.vertices);
  fmt::format_to(out, "  triangles            {}\n", r.triangles);
  fmt::format_to(out, "  edges                {}\n", r.edges);
  fmt::format_to(out, "  boundary loops       {}\n", r.boundary_loops);
  fmt::format_to(out, "  material area        {:.6g} m^2\n", r.material_area);
  fmt::format_to(out, "  world area           {:.6g} m^2\n", r.world_area);
  fmt::format_to(out, "  edge length          min {:.4g}  mean {:.4g}  max {:.4g} m (material space)\n", r.min_edge,
                 r.mean_edge, r.max_edge);
  fmt::format_to(out, "  smallest angle       {:.3g} deg (material space)\n", r.min_angle_deg);

  int problems = 0;
  auto problem = [&](const std::string& what) {
    fmt::format_to(out, "  problem: {}\n", what);
    ++problems;
  };
  if (r.triangles == 0) problem("no triangles");
  if (!r.sizes_match) problem("world positions and material coordinates differ in number");
  if (!r.invalid_triangles.empty())
    problem(fmt::format("{} triangles refer to missing vertices (triangles {})", r.invalid_triangles.size(),
                        first_indices(r.invalid_triangles)));
  if (r.non_finite_vertices > 0) problem(fmt::format("{} vertices have non-finite coordinates", r.non_finite_vertices));
  if (!r.degenerate_triangles.empty())
    problem(fmt::format("{} degenerate (zero material area) triangles ({})", r.degenerate_triangles.size(),
                        first_indices(r.degenerate_triangles)));
  if (!r.tiny_triangles.empty())
    problem(fmt::format("{} triangles smaller than {:g} m in material space ({}); check the units or material scale",
                        r.tiny_triangles.size(), kMinMaterialEdge, first_indices(r.tiny_triangles)));
  if (!r.non_manifold_edges_first_tri.empty())
    problem(fmt::format("{} non-manifold edges (more than two triangles; at triangles {})",
                        r.non_manifold_edges_first_tri.size(), first_indices(r.non_manifold_edges_first_tri)));
  if (r.inconsistent_edges > 0)
    problem(fmt::format("{} edges whose triangles overlap in material space (inconsistent orientation)",
                        r.inconsistent_edges));
  if (r.unreferenced_vertices > 0)
    problem(fmt::format("{} vertices are not used by any triangle", r.unreferenced_vertices));
  if (r.negative_area_triangles > 0)
    fmt::format_to(out, "  note: {} triangles are clockwise in material space (mirrored chart; they will be flipped)\n",
                   r.negative_area_triangles);
  if (problems == 0) fmt::format_to(out, "  no problems found\n");
  return fmt::to_string(b);
}

}  // namespace mgcloth::mesh
