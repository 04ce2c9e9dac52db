#include <mgcloth/core/error.hpp>
#include <mgcloth/core/out_of_memory.hpp>
#include <mgcloth/mesh/cdt.hpp>
#include <mgcloth/mesh/generators.hpp>

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_mesh_criteria_2.h>
#include <CGAL/Delaunay_mesh_face_base_2.h>
#include <CGAL/Delaunay_mesh_vertex_base_2.h>
#include <CGAL/Delaunay_mesher_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace mgcloth::mesh {

namespace {

// ---------------------------------------------------------------------------------------------- spec checks ---

void check_spec(const RectangleSpec& spec) {
  if (!(spec.width > 0.0) || !std::isfinite(spec.width) || !(spec.height > 0.0) || !std::isfinite(spec.height))
    throw_input_error("rectangle: width and height must be positive and finite (got {} x {})", spec.width,
                      spec.height);
  if (spec.target_vertices < 4 || spec.target_vertices > kMaxGeneratedVertices)
    throw_input_error("rectangle: target_vertices must be at least 4 and at most {} (got {})", kMaxGeneratedVertices,
                      spec.target_vertices);
  if (!spec.unstructured && !spec.holes.empty())
    throw_input_error("rectangle: holes need an unstructured mesh (set unstructured = true)");
  for (std::size_t i = 0; i < spec.holes.size(); ++i) {
    const CircleHole& h = spec.holes[i];
    if (!(h.radius > 0.0) || !std::isfinite(h.radius) || !h.center.allFinite())
      throw_input_error("rectangle: hole {} needs a finite center and a positive radius (got ({}, {}), r = {})", i,
                        h.center.x(), h.center.y(), h.radius);
    const double gap = std::min({h.center.x(), h.center.y(), spec.width - h.center.x(), spec.height - h.center.y()}) -
                       h.radius;
    if (!(gap > 0.0))
      throw_input_error("rectangle: hole {} (center ({}, {}), radius {}) is not strictly inside the {} x {} rectangle",
                        i, h.center.x(), h.center.y(), h.radius, spec.width, spec.height);
    for (std::size_t j = 0; j < i; ++j) {
      const CircleHole& g = spec.holes[j];
      if (!((h.center - g.center).norm() > h.radius + g.radius))
        throw_input_error("rectangle: holes {} and {} overlap", j, i);
    }
  }
}

// ------------------------------------------------------------------------------------------------- regular ---

/// Grid size: the vertex count close to the target first, square cells second.
std::array<Index, 2> grid_size(const RectangleSpec& spec) {
  const double a = spec.width / spec.height, n = static_cast<double>(spec.target_vertices);
  // (a*ny + 1)(ny + 1) = n, solved for ny.
  const double ny_est = (-(a + 1.0) + std::sqrt((a + 1.0) * (a + 1.0) + 4.0 * a * (n - 1.0))) / (2.0 * a);
  std::array<Index, 2> best{1, 1};
  double best_score = kInf;
  const Index lo = std::max<Index>(1, static_cast<Index>(std::floor(ny_est)) - 2);
  for (Index ny = lo; ny <= lo + 5; ++ny) {
    const double nx_fit = n / (ny + 1.0) - 1.0;
    for (double nx_d : {std::floor(a * ny), std::ceil(a * ny), std::floor(nx_fit), std::ceil(nx_fit)}) {
      const Index nx = std::max<Index>(1, static_cast<Index>(nx_d));
      const double count = (nx + 1.0) * (ny + 1.0);
      const double cell_aspect = (spec.width / nx) / (spec.height / ny);
      const double score = std::abs(std::log(count / n)) + 0.1 * std::abs(std::log(cell_aspect));
      if (score < best_score) best_score = score, best = {nx, ny};
    }
  }
  return best;
}

TriMesh make_regular(const RectangleSpec& spec) {
  const auto [nx, ny] = grid_size(spec);
  TriMesh mesh;
  mesh.u.resize(2, (nx + 1) * (ny + 1));
  for (Index j = 0; j <= ny; ++j)
    for (Index i = 0; i <= nx; ++i)
      mesh.u.col(j * (nx + 1) + i) = Vec2(spec.width * i / nx, spec.height * j / ny);
  mesh.tris.reserve(2 * static_cast<std::size_t>(nx) * ny);
  for (Index j = 0; j < ny; ++j)
    for (Index i = 0; i < nx; ++i) {
      const Index v00 = j * (nx + 1) + i, v10 = v00 + 1, v01 = v00 + nx + 1, v11 = v01 + 1;
      // Checkerboard diagonals: a single diagonal direction makes the grid stiffer in shear one way than the other.
      if ((i + j) % 2 == 0) {
        mesh.tris.push_back({v00, v10, v11});
        mesh.tris.push_back({v00, v11, v01});
      } else {
        mesh.tris.push_back({v00, v10, v01});
        mesh.tris.push_back({v10, v11, v01});
      }
    }
  return mesh;
}

// -------------------------------------------------------------------------------------------- unstructured ---

/// Uniform in [0, 1) from the top 53 bits. std::uniform_real_distribution is not used because its output differs
/// between standard libraries, and a seed should give the same mesh everywhere.
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// Even a hole smaller than the spacing stays recognisably round; refinement then grades the mesh around it.
constexpr Index kMinHoleSides = 8;
/// Candidates tried around an active point before it retires: more packs denser (fewer gaps, better angles) but
/// costs time; 20 gives a minimum angle of ~27.5 degrees where 30 gives ~28.5 at 1.4 times the sampling time.
constexpr int kCandidates = 20;
/// Points per r^2 of area and per r of boundary length of the sample (fitted, see sample_to_target).
constexpr double kDensity = 0.857;
constexpr double kBoundaryDensity = 0.465;
/// CGAL's shape criterion B = sin^2 of the smallest angle allowed: 0.125 is 20.7 degrees, the bound for which
/// Delaunay refinement provably terminates.
constexpr double kShapeBound = 0.125;

struct Sample {
  std::vector<Vec2> points;                       ///< boundary loops first, then interior points
  std::vector<std::array<Index, 2>> constraints;  ///< boundary segments
  Index num_boundary = 0;
};

void add_loop(Sample& s, const std::vector<Vec2>& loop) {
  const Index first = static_cast<Index>(s.points.size());
  const Index n = static_cast<Index>(loop.size());
  for (Index i = 0; i < n; ++i) {
    s.points.push_back(loop[i]);
    s.constraints.push_back({first + i, first + (i + 1) % n});
  }
}

/// The outer boundary (counter-clockwise) and the holes (clockwise inscribed polygons), every segment at most r
/// long, so that a point r away from all boundary points is at least sqrt(3)/2 r away from every segment.
void add_boundaries(const RectangleSpec& spec, double r, Sample& sample) {
  const double w = spec.width, h = spec.height;
  const Index nx = std::max<Index>(1, static_cast<Index>(std::ceil(w / r)));
  const Index ny = std::max<Index>(1, static_cast<Index>(std::ceil(h / r)));
  std::vector<Vec2> outer;
  for (Index i = 0; i < nx; ++i) outer.emplace_back(w * i / nx, 0.0);
  for (Index j = 0; j < ny; ++j) outer.emplace_back(w, h * j / ny);
  for (Index i = nx; i > 0; --i) outer.emplace_back(w * i / nx, h);
  for (Index j = ny; j > 0; --j) outer.emplace_back(0.0, h * j / ny);
  add_loop(sample, outer);
  for (const CircleHole& hole : spec.holes) {
    const Index n =
        std::max<Index>(kMinHoleSides, static_cast<Index>(std::ceil(2.0 * std::numbers::pi * hole.radius / r)));
    std::vector<Vec2> loop;
    for (Index k = 0; k < n; ++k) {
      const double t = -2.0 * std::numbers::pi * k / n;
      loop.push_back(hole.center + hole.radius * Vec2(std::cos(t), std::sin(t)));
    }
    add_loop(sample, loop);
  }
  sample.num_boundary = static_cast<Index>(sample.points.size());
}

/// Uniform background grid over the rectangle for "is any point within r" queries. Cells are r / sqrt(2) wide,
/// so a cell holds at most one point of a Poisson-disk sample; boundary points, which may be closer than r to
/// each other, go to a separate list per cell.
class DiskGrid {
 public:
  DiskGrid(double width, double height, double r) : m_r2(r * r), m_cell(r / std::numbers::sqrt2) {
    m_nx = static_cast<Index>(width / m_cell) + 1;
    m_ny = static_cast<Index>(height / m_cell) + 1;
    m_interior.assign(static_cast<std::size_t>(m_nx) * m_ny, -1);
  }

  void set_boundary(const std::vector<Vec2>& points, Index count) {
    m_boundary_start.assign(m_interior.size() + 1, 0);
    for (Index i = 0; i < count; ++i) ++m_boundary_start[cell(points[i]) + 1];
    for (std::size_t c = 0; c < m_interior.size(); ++c) m_boundary_start[c + 1] += m_boundary_start[c];
    m_boundary.resize(count);
    std::vector<Index> fill(m_boundary_start.begin(), m_boundary_start.end() - 1);
    for (Index i = 0; i < count; ++i) m_boundary[fill[cell(points[i])]++] = i;
  }
  void add(const Vec2& p, Index i) { m_interior[cell(p)] = i; }

  bool is_free(const Vec2& p, const std::vector<Vec2>& points) const {
    const Index cx = static_cast<Index>(p.x() / m_cell), cy = static_cast<Index>(p.y() / m_cell);
    for (Index y = std::max<Index>(0, cy - 2); y <= std::min(m_ny - 1, cy + 2); ++y)
      for (Index x = std::max<Index>(0, cx - 2); x <= std::min(m_nx - 1, cx + 2); ++x) {
        const std::size_t c = static_cast<std::size_t>(y) * m_nx + x;
        const Index i = m_interior[c];
        if (i >= 0 && (points[i] - p).squaredNorm() < m_r2) return false;
        for (Index k = m_boundary_start[c]; k < m_boundary_start[c + 1]; ++k)
          if ((points[m_boundary[k]] - p).squaredNorm() < m_r2) return false;
      }
    return true;
  }

 private:
  std::size_t cell(const Vec2& p) const {
    const Index cx = std::clamp<Index>(static_cast<Index>(p.x() / m_cell), 0, m_nx - 1);
    const Index cy = std::clamp<Index>(static_cast<Index>(p.y() / m_cell), 0, m_ny - 1);
    return static_cast<std::size_t>(cy) * m_nx + cx;
  }

  double m_r2, m_cell;
  Index m_nx = 0, m_ny = 0;
  std::vector<Index> m_interior;
  std::vector<Index> m_boundary_start, m_boundary;
};

/// Poisson-disk sample of the domain with radius r (no two points closer than r), grown from the boundary
/// points by Bridson's algorithm (Bridson 2007, "Fast Poisson disk sampling in arbitrary dimensions") with
/// Roberts' candidates: kCandidates points evenly spaced on the circle of radius r around a random active point,
/// from a random start angle. Those pack more densely than Bridson's annulus samples, which leaves fewer gaps and
/// so fewer small Delaunay angles (smallest angle measured 27 to 33 degrees, against 25 to 28 with Bridson's
/// annulus candidates), while interior valences still range from 4 to 9.
Sample sample_domain(const RectangleSpec& spec, double r) {
  Sample sample;
  add_boundaries(spec, r, sample);
  DiskGrid grid(spec.width, spec.height, r);
  grid.set_boundary(sample.points, sample.num_boundary);
  auto inside = [&](const Vec2& q) {
    if (!(q.x() > 0.0 && q.x() < spec.width && q.y() > 0.0 && q.y() < spec.height)) return false;
    for (const CircleHole& hole : spec.holes)
      if ((q - hole.center).squaredNorm() <= hole.radius * hole.radius) return false;
    return true;
  };

  const double step = 2.0 * std::numbers::pi / kCandidates;
  const Vec2 rotation(std::cos(step), std::sin(step));
  const double radius = r * (1.0 + 1e-9);  // just outside the disk of the point it grows from
  std::mt19937_64 rng(spec.seed);
  std::vector<Index> active(sample.num_boundary);
  for (Index i = 0; i < sample.num_boundary; ++i) active[i] = i;
  while (!active.empty()) {
    const std::size_t a = std::min(active.size() - 1,
                                   static_cast<std::size_t>(uniform01(rng) * static_cast<double>(active.size())));
    const Vec2 p = sample.points[active[a]];
    const double start = 2.0 * std::numbers::pi * uniform01(rng);
    Vec2 dir(std::cos(start), std::sin(start));
    bool placed = false;
    for (int k = 0; k < kCandidates && !placed; ++k) {
      const Vec2 q = p + radius * dir;
      dir = Vec2(dir.x() * rotation.x() - dir.y() * rotation.y(), dir.x() * rotation.y() + dir.y() * rotation.x());
      if (!inside(q) || !grid.is_free(q, sample.points)) continue;
      const Index i = static_cast<Index>(sample.points.size());
      sample.points.push_back(q);
      grid.add(q, i);
      active.push_back(i);
      placed = true;
    }
    if (!placed) {
      active[a] = active.back();
      active.pop_back();
    }
  }
  return sample;
}

/// The radius whose sample has about the target number of points. The count follows
/// kDensity * area / r^2 + kBoundaryDensity * perimeter / r (fitted over 300 to 100K points, aspect 1 to 3, with
/// and without holes: within 2%), so the first sample is usually close enough; otherwise the radius is rescaled
/// by sqrt(count / target) and the domain sampled again.
Sample sample_to_target(const RectangleSpec& spec, double target) {
  double area = spec.width * spec.height, perimeter = 2.0 * (spec.width + spec.height);
  for (const CircleHole& h : spec.holes) {
    area -= std::numbers::pi * h.radius * h.radius;
    perimeter += 2.0 * std::numbers::pi * h.radius;
  }
  // kDensity * area * x^2 + kBoundaryDensity * perimeter * x = target, for x = 1 / r.
  const double qa = kDensity * area, qb = kBoundaryDensity * perimeter;
  double r = 2.0 * qa / (-qb + std::sqrt(qb * qb + 4.0 * qa * target));
  Sample best;
  double best_error = kInf;
  for (int iter = 0; iter < 4; ++iter) {
    Sample sample = sample_domain(spec, r);
    const double count = static_cast<double>(sample.points.size());
    const double error = std::abs(count / target - 1.0);
    if (error < best_error) best_error = error, best = std::move(sample);
    if (best_error < 0.01) break;
    r *= std::sqrt(count / target);
  }
  return best;
}

using cdt::Cdt;
using cdt::FaceBase;
using cdt::Kernel;
using cdt::VertexBase;

/// Constrained Delaunay triangulation of the sample, then Delaunay refinement with a shape bound only (no size
/// bound): it inserts points only where a triangle's smallest angle is below ~20.7 degrees or a boundary segment
/// is encroached. A well-resolved domain needs none; a hole only a few spacings around gets a graded ring.
/// CGAL marks the domain from seeds: the hole centres are outside, as is everything reachable from infinity.
void triangulate(const RectangleSpec& spec, const Sample& sample, Cdt& cdt) {
  const Index n = static_cast<Index>(sample.points.size());
  std::vector<std::pair<Kernel::Point_2, Index>> points(n);
  for (Index i = 0; i < n; ++i) points[i] = {{sample.points[i].x(), sample.points[i].y()}, i};
  cdt.insert(points.begin(), points.end());  // spatially sorted inside
  std::vector<Cdt::Vertex_handle> handle(n);
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) handle[v->info()] = v;
  for (const auto& c : sample.constraints) {
    if (handle[c[0]] == Cdt::Vertex_handle() || handle[c[1]] == Cdt::Vertex_handle())
      throw_error("rectangle: a boundary point coincides with another point (seed {})", spec.seed);
    cdt.insert_constraint(handle[c[0]], handle[c[1]]);
  }
  std::vector<Kernel::Point_2> seeds;
  for (const CircleHole& h : spec.holes) seeds.emplace_back(h.center.x(), h.center.y());
  CGAL::refine_Delaunay_mesh_2(cdt, seeds.begin(), seeds.end(), CGAL::Delaunay_mesh_criteria_2<Cdt>(kShapeBound),
                               /*mark=*/false);
}

/// The triangles of the domain, with the vertices they use numbered in row-major order (rows about one spacing
/// high), so that mesh neighbours are mostly near in memory.
TriMesh extract_mesh(const RectangleSpec& spec, Cdt& cdt) {
  std::vector<Cdt::Vertex_handle> used;
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) v->info() = -1;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f)
    if (f->is_in_domain())
      for (int k = 0; k < 3; ++k)
        if (f->vertex(k)->info() == -1) {
          f->vertex(k)->info() = 0;
          used.push_back(f->vertex(k));
        }
  const double row = std::sqrt(spec.width * spec.height / std::max<double>(1.0, static_cast<double>(used.size())));
  auto key = [&](const Cdt::Vertex_handle& v) {
    return std::make_pair(std::floor(v->point().y() / row), v->point().x());
  };
  std::stable_sort(used.begin(), used.end(), [&](const auto& a, const auto& b) { return key(a) < key(b); });

  TriMesh mesh;
  mesh.u.resize(2, static_cast<Index>(used.size()));
  for (std::size_t k = 0; k < used.size(); ++k) {
    used[k]->info() = static_cast<Index>(k);
    mesh.u.col(static_cast<Index>(k)) = Vec2(used[k]->point().x(), used[k]->point().y());
  }
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f)
    if (f->is_in_domain()) mesh.tris.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
  std::stable_sort(mesh.tris.begin(), mesh.tris.end(), [](const Tri& a, const Tri& b) {
    return std::min({a[0], a[1], a[2]}) < std::min({b[0], b[1], b[2]});
  });
  return mesh;
}

TriMesh make_unstructured(const RectangleSpec& spec) {
  Cdt cdt;
  triangulate(spec, sample_to_target(spec, static_cast<double>(spec.target_vertices)), cdt);
  return extract_mesh(spec, cdt);
}

}  // namespace

TriMesh make_rectangle(const RectangleSpec& spec) {
  check_spec(spec);
  return building([&] { return fmt::format("a rectangle mesh of about {} vertices", spec.target_vertices); }, [&] {
    TriMesh mesh = spec.unstructured ? make_unstructured(spec) : make_regular(spec);
    mesh.x.setZero(3, mesh.u.cols());
    mesh.x.topRows<2>() = mesh.u;
    return mesh;
  });
}

TriMesh make_tube(const TubeSpec& spec) {
  if (!(spec.circumference > 0.0) || !(spec.height > 0.0) || !std::isfinite(spec.circumference) || !std::isfinite(spec.height))
    throw_input_error("tube: circumference and height must be positive (got {} and {})", spec.circumference, spec.height);
  if (spec.target_vertices < 8 || spec.target_vertices > kMaxGeneratedVertices)
    throw_input_error("tube: target_vertices must be at least 8 and at most {} (got {})", kMaxGeneratedVertices,
                      spec.target_vertices);
  RectangleSpec panel;
  panel.width = 0.5 * spec.circumference;
  panel.height = spec.height;
  panel.target_vertices = spec.target_vertices / 2;
  panel.unstructured = spec.unstructured;
  panel.seed = spec.seed;
  const TriMesh front = make_rectangle(panel);
  const Index n = front.num_vertices();
  // Side vertices of a panel, ordered by v: the seams pair the front's right side with the back's left side.
  auto side = [&](double u) {
    std::vector<std::pair<double, Index>> s;
    for (Index i = 0; i < n; ++i)
      if (front.u(0, i) == u) s.push_back({front.u(1, i), i});
    std::sort(s.begin(), s.end());
    return s;
  };
  const auto left = side(0.0), right = side(panel.width);
  if (left.size() != right.size())
    throw_error("tube: the panel's sides have {} and {} vertices; they cannot be stitched", left.size(), right.size());
  for (std::size_t k = 0; k < left.size(); ++k)
    if (std::abs(left[k].first - right[k].first) > 1e-9 * spec.height)
      throw_error("tube: the panel's side vertices {} and {} are not at the same height", left[k].second, right[k].second);

  TriMesh m;
  m.u.resize(2, 2 * n);
  m.u << front.u, front.u;
  m.x.resize(3, 2 * n);
  const double radius = spec.circumference / (2.0 * std::numbers::pi);
  for (Index p = 0; p < 2; ++p)
    for (Index i = 0; i < n; ++i) {
      // Front: angle 0..π along u; back: π..2π, so front u = 0 meets back u = width and front u = width meets back u = 0.
      const double angle = std::numbers::pi * (p + front.u(0, i) / panel.width);
      m.x.col(p * n + i) = Vec3(radius * std::cos(angle), radius * std::sin(angle), front.u(1, i));
    }
  // Outward-facing normals on both panels keep the tris CCW in material space.
  for (Index p = 0; p < 2; ++p)
    for (const Tri& t : front.tris) m.tris.push_back({t[0] + p * n, t[1] + p * n, t[2] + p * n});
  m.source_vertex.resize(2 * n);
  for (Index i = 0; i < 2 * n; ++i) m.source_vertex[i] = i;
  for (std::size_t k = 0; k < left.size(); ++k) {
    m.source_vertex[n + left[k].second] = right[k].second;   // back left = front right
    m.source_vertex[left[k].second] = n + right[k].second;   // front left = back right
  }
  return m;
}

}  // namespace mgcloth::mesh
