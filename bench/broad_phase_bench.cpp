// The contact broad phase (issue 28, deliverable 3): BroadPhase::find on a 1 m sheet folded into four layers 2 mm
// apart and crumpled by ±0.5 mm, boxes grown by 1 mm, against CGAL's box_intersection_d on the same boxes (the
// vertex boxes against the triangle boxes, the edge boxes against themselves, the same shared-point filter: the same
// candidates, checked) and, at the smallest size, against the O(n²) reference.
//   "rebuild": a fresh BroadPhase each time (both trees built); "refit": one BroadPhase that follows the sheet
//   moving by ±0.5 mm between calls (its trees refit; the rebuilds column counts any it did).
//
// With --sweep, the rebuild threshold (BroadPhase::kRebuildGrowth) against others over a sheet folding from flat and
// unfolding back.
//
//   build/bin/mgcloth_bench_broad_phase --vertices 10000,40000,120000 [--threads 1,2] [--reps 5] [--brute-below 20000]
//                                      [--sweep 10000 [--frames 20]]
#include <mgcloth/collision/broad_phase.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/mesh/generators.hpp>

#include "best_ms.hpp"

#include <CGAL/box_intersection_d.h>
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <random>
#include <sstream>

using namespace mgcloth;
using namespace mgcloth::collision;

namespace {

constexpr int kLayers = 4;
constexpr double kGap = 2e-3, kCrumple = 0.5e-3, kInflate = 1e-3;

std::vector<int> parse_list(const std::string& s) {
  std::vector<int> v;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');) v.push_back(std::stoi(item));
  return v;
}

/// The unit square's material coordinates folded like an accordion along x into kLayers layers kGap apart, or a
/// fraction `t` of the way there from flat.
VecX folded_sheet(const mesh::TriMesh& m, std::mt19937& rng, double t = 1.0) {
  std::uniform_real_distribution<double> noise(-kCrumple, kCrumple);
  const double width = 1.0 / kLayers;
  VecX x(3 * m.num_vertices());
  for (Index i = 0; i < m.num_vertices(); ++i) {
    const double s = m.u(0, i);
    const int layer = std::min(kLayers - 1, static_cast<int>(s / width));
    const double local = s - layer * width;
    const Vec3 flat(s, m.u(1, i), 0.0), folded(layer % 2 == 0 ? local : width - local, m.u(1, i), layer * kGap);
    vertex(x, i) = (1.0 - t) * flat + t * folded + Vec3(noise(rng), noise(rng), noise(rng));
  }
  return x;
}

// ID_EXPLICIT numbers boxes from a global counter, which is fine for this single-threaded use.
using CgalBox = CGAL::Box_intersection_d::Box_with_info_d<double, 3, Index, CGAL::Box_intersection_d::ID_EXPLICIT>;

/// The same boxes as BroadPhase's (min/max of the points, then grown), the same filter; returns the pair count.
size_t cgal_candidates(const SurfaceTopology& s, const VecX& x, std::vector<std::array<Index, 2>>& vt,
                       std::vector<std::array<Index, 2>>& ee) {
  auto box = [&](std::initializer_list<Index> points, Index info) {
    Aabb b;
    for (Index p : points) b.expand(vertex(x, p));
    b.inflate(kInflate);
    return CgalBox(CGAL::Bbox_3(b.lo.x(), b.lo.y(), b.lo.z(), b.hi.x(), b.hi.y(), b.hi.z()), info);
  };
  std::vector<CgalBox> vertices, triangles, edges;
  vertices.reserve(s.vertices.size());
  triangles.reserve(s.triangles.size());
  edges.reserve(s.edges.size());
  for (size_t v = 0; v < s.vertices.size(); ++v) vertices.push_back(box({s.vertices[v]}, static_cast<Index>(v)));
  for (size_t t = 0; t < s.triangles.size(); ++t) {
    const Tri& tri = s.triangles[t];
    triangles.push_back(box({tri[0], tri[1], tri[2]}, static_cast<Index>(t)));
  }
  for (size_t e = 0; e < s.edges.size(); ++e)
    edges.push_back(box({s.edges[e][0], s.edges[e][1]}, static_cast<Index>(e)));
  vt.clear();
  ee.clear();
  CGAL::box_intersection_d(vertices.begin(), vertices.end(), triangles.begin(), triangles.end(),
                           [&](const CgalBox& v, const CgalBox& t) {
                             const Index p = s.vertices[v.info()];
                             const Tri& tri = s.triangles[t.info()];
                             if (tri[0] != p && tri[1] != p && tri[2] != p) vt.push_back({v.info(), t.info()});
                           });
  CGAL::box_self_intersection_d(edges.begin(), edges.end(), [&](const CgalBox& a, const CgalBox& b) {
    const auto &ea = s.edges[a.info()], &eb = s.edges[b.info()];
    if (ea[0] != eb[0] && ea[0] != eb[1] && ea[1] != eb[0] && ea[1] != eb[1]) ee.push_back({a.info(), b.info()});
  });
  return vt.size() + ee.size();
}

/// The 1 m unstructured square every table of this program runs on.
mesh::TriMesh unstructured_sheet(int vertices) {
  mesh::RectangleSpec spec;
  spec.target_vertices = vertices;
  spec.unstructured = true;
  return mesh::make_rectangle(spec);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Broad phase: BVH refit/rebuild against CGAL's box intersection and brute force");
  std::string sizes = "10000,40000,120000", thread_list = "1,2";
  int reps = 5, brute_below = 20000;
  app.add_option("--vertices", sizes, "Comma-separated sheet sizes");
  app.add_option("--threads", thread_list, "Comma-separated thread counts");
  app.add_option("--reps", reps, "Repetitions (the best is reported)");
  app.add_option("--brute-below", brute_below, "Run the O(n²) reference below this many vertices");
  std::string sweep_sizes = "";
  int frames = 20;
  app.add_option("--sweep", sweep_sizes,
                 "Comma-separated sizes at which to time rebuild thresholds over a sheet folding from flat");
  app.add_option("--frames", frames, "Frames of the folding sequence of --sweep");
  CLI11_PARSE(app, argc, argv);

  std::printf("| vertices | threads | candidates (v–t + e–e) | find, rebuild | find, refit | rebuilds in refit runs | "
              "CGAL box_intersection_d (1 thread) | brute force (1 thread) |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  for (int n : parse_list(sizes)) {
    const mesh::TriMesh m = unstructured_sheet(n);
    const SurfaceTopology s = make_surface_topology(m.tris);
    std::mt19937 rng(1);
    const VecX x0 = folded_sheet(m, rng);
    VecX motion(x0.size());
    std::uniform_real_distribution<double> u(-kCrumple, kCrumple);
    for (Index k = 0; k < motion.size(); ++k) motion[k] = u(rng);
    const VecX x1 = x0 + motion;

    std::vector<std::array<Index, 2>> vt, ee;
    set_num_threads(1);
    const size_t cgal_count = cgal_candidates(s, x0, vt, ee);
    const double cgal_ms = bench::best_ms(reps, [&] { cgal_candidates(s, x0, vt, ee); });
    double brute_ms = -1.0;
    if (n < brute_below) {
      Candidates c;
      brute_ms = bench::best_ms(1, [&] { find_brute_force(s, x0, kInflate, c); });
    }
    for (int threads : parse_list(thread_list)) {
      set_num_threads(threads);
      Candidates c;
      const double rebuild_ms = bench::best_ms(reps, [&] { BroadPhase(&s).find(x0, kInflate, c); });
      const size_t count = c.vertex_triangle.size() + c.edge_edge.size();
      if (count != cgal_count) {
        std::fprintf(stderr, "candidate counts differ: BroadPhase %zu, CGAL %zu\n", count, cgal_count);
        return 1;
      }
      BroadPhase bp(&s);
      bp.find(x0, kInflate, c);
      const Index built = bp.builds();
      bool odd = false;
      const double refit_ms = bench::best_ms(reps, [&] {
        bp.find(odd ? x1 : x0, kInflate, c);
        odd = !odd;
      });
      std::printf("| %d | %d | %zu + %zu | %.2f ms | %.2f ms | %d | %.2f ms | %s |\n", m.num_vertices(), threads,
                  vt.size(), ee.size(), rebuild_ms, refit_ms, static_cast<int>(bp.builds() - built), cgal_ms,
                  brute_ms < 0 ? "–" : fmt::format("{:.0f} ms", brute_ms).c_str());
      std::fflush(stdout);
    }
  }
  // The rebuild threshold: one BroadPhase follows the sheet from flat to folded ("fold") or back ("unfold") in
  // `frames` calls; 0 rebuilds every call, infinity never. Unfolding pulls apart the layers that a tree built on the
  // folded sheet grouped together, which is what refitting cannot follow.
  if (sweep_sizes.empty()) return 0;
  std::printf("\n| vertices | threads | sequence | rebuild growth | calls | rebuilds | time of all calls | last call |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  for (int n : parse_list(sweep_sizes)) {
    const mesh::TriMesh m = unstructured_sheet(n);
    const SurfaceTopology s = make_surface_topology(m.tris);
    std::vector<VecX> fold;
    std::mt19937 rng(2);
    for (int f = 0; f <= frames; ++f) fold.push_back(folded_sheet(m, rng, static_cast<double>(f) / frames));
    std::vector<VecX> unfold(fold.rbegin(), fold.rend());
    for (int threads : parse_list(thread_list)) {
      set_num_threads(threads);
      for (const auto& [name, sequence] : {std::pair{"fold", &fold}, std::pair{"unfold", &unfold}})
        for (double growth : {0.0, 1.25, 1.5, 2.0, 4.0, kInf}) {
          double total = 1e300, last = 1e300;
          Index rebuilds = 0;
          for (int r = 0; r < reps; ++r) {
            BroadPhase bp(&s);
            bp.set_rebuild_growth(growth);
            Candidates c;
            double sum = 0.0, ms = 0.0;
            for (const VecX& x : *sequence) {
              Timer t;
              bp.find(x, kInflate, c);
              ms = t.ms();
              sum += ms;
            }
            total = std::min(total, sum);
            last = std::min(last, ms);
            rebuilds = bp.builds() - 2;
          }
          std::printf("| %d | %d | %s | %g | %zu | %d | %.1f ms | %.2f ms |\n", m.num_vertices(), threads, name, growth,
                      sequence->size(), static_cast<int>(rebuilds), total, last);
          std::fflush(stdout);
        }
    }
  }
  return 0;
}
