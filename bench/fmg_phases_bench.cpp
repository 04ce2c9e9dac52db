// The machine's memory bandwidth (STREAM-style kernels) and, against it, what each phase of an FMG cycle achieves
// on a scene's frozen step: the smoother's sweeps and the residual products per level, the whole linear V-cycle,
// the transfers, Hessian assembly, the Galerkin update, gradient and energy. Every kernel's bytes are the
// compulsory traffic of its arrays (each value, index and vector entry read or written once per pass, no cache
// reuse counted), so "fraction of limit" is a lower bound of what the memory system carried.
//   mgcloth_bench_phases [--scene scenes/drape_sphere.json] --vertices 40000,120000 --threads 1,2 [--step 5]
//                        [--repeat 5] [--stream-mb 1024] [--json FILE]
#include "best_ms.hpp"

#include <algorithm>
#include <mgcloth/core/json.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/linalg/chebyshev.hpp>
#include <mgcloth/linalg/coloring.hpp>
#include <mgcloth/linalg/galerkin.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/sim/simulator.hpp>
#include <mgcloth/solvers/linear_multigrid.hpp>
#include <mgcloth/solvers/nonlinear_fmg.hpp>
#include <mgcloth/studies/convergence.hpp>

#include <CLI/CLI.hpp>
#include <omp.h>

#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>

using namespace mgcloth;

namespace {

std::vector<int> int_list(const std::string& s) {
  std::vector<int> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ',')) out.push_back(std::stoi(item));
  return out;
}

/// STREAM's four kernels plus a read-only sum (the smoother's traffic is almost all reads), on `threads` threads,
/// arrays of `mb` MB each (first-touched by the threads that use them). GB/s by STREAM's byte counts (copy 16,
/// scale 16, add 24, triad 24 per element; write-allocate traffic not counted), best of `repeat`.
Json stream_bandwidth(int threads, double mb, int repeat) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(mb * 1e6 / 8.0);
  std::unique_ptr<double[]> a(new double[n]), b(new double[n]), c(new double[n]);
  omp_set_num_threads(threads);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    a[i] = 1.0;
    b[i] = 2.0;
    c[i] = 0.0;
  }
  double* A = a.get();
  double* B = b.get();
  double* C = c.get();
  const double s = 3.0;
  double sink = 0.0;
  const auto gbs = [&](double bytes_per, const std::function<void()>& f) {
    return bytes_per * static_cast<double>(n) / (bench::best_ms(repeat, f) * 1e6);
  };
  Json out{{"threads", threads}, {"array_mb", mb}};
  out["copy"] = gbs(16, [&] {
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < n; ++i) C[i] = A[i];
  });
  out["scale"] = gbs(16, [&] {
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < n; ++i) B[i] = s * C[i];
  });
  out["add"] = gbs(24, [&] {
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < n; ++i) C[i] = A[i] + B[i];
  });
  out["triad"] = gbs(24, [&] {
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < n; ++i) A[i] = B[i] + s * C[i];
  });
  // Eight partial sums: one accumulator would be bound by the add's latency, not by memory.
  out["read"] = gbs(8, [&] {
    double t = 0.0;
#pragma omp parallel for schedule(static) reduction(+ : t)
    for (std::ptrdiff_t i = 0; i < n / 8; ++i) {
      const double* p = A + 8 * i;
      t += ((p[0] + p[1]) + (p[2] + p[3])) + ((p[4] + p[5]) + (p[6] + p[7]));
    }
    sink += t;
  });
  if (sink == 42.0) std::printf(" ");  // keeps the sum alive
  return out;
}

/// Compulsory bytes of one pass of a block-row kernel over A: every block (72 B) and its column index (4 B), the row
/// offsets, and `vector_bytes_per_row` of vector traffic per row.
double pass_bytes(const linalg::BlockMatrix3& A, double extra_per_row) {
  return 76.0 * A.num_blocks() + (4.0 + extra_per_row) * A.rows();
}
/// A Gauss-Seidel pass over A where it lies (before issue 30): also the inverted diagonal (72 B) and the color's
/// row list (4 B), b read (24 B), x read and written (48 B).
double gs_pass_bytes(const linalg::BlockMatrix3& A) { return pass_bytes(A, 72.0 + 4.0 + 24.0 + 48.0); }
/// y = A x: x read (24 B), y written (24 B).
double matvec_bytes(const linalg::BlockMatrix3& A) { return pass_bytes(A, 48.0); }

/// The smoother as it was before issue 30: each color's rows relaxed where they lie in A (jumping between rows),
/// kept here as the same-run baseline of the color-ordered copy.
struct InPlaceGaussSeidel {
  explicit InPlaceGaussSeidel(const linalg::BlockMatrix3& A) : A(A), colors(linalg::color_rows(A)), inv(A.rows()) {
    for (Index r = 0; r < A.rows(); ++r) inv[r] = A.block(A.diagonal(r)).inverse();
  }
  void symmetric_sweep(const VecX& b, VecX& x) const {
    const Index nc = static_cast<Index>(colors.size());
    for (Index i = 0; i < 2 * nc; ++i) {
      const auto& rows = colors[i < nc ? i : 2 * nc - 1 - i];
      parallel_for(static_cast<Index>(rows.size()), [&](Index k) {
        const Index r = rows[k];
        Vec3 s = b.segment<3>(3 * r);
        for (Index j = A.row_offsets()[r]; j < A.row_offsets()[r + 1]; ++j) {
          const Index c = A.col_indices()[j];
          if (c != r) s.noalias() -= A.block(j) * x.segment<3>(3 * c);
        }
        x.segment<3>(3 * r) = inv[r] * s;
      });
    }
  }
  const linalg::BlockMatrix3& A;
  std::vector<std::vector<Index>> colors;
  std::vector<Mat3> inv;
};

Json phase(const std::string& name, double ms, double bytes, double limit_gbs) {
  const double gbs = bytes / (ms * 1e6);
  return Json{{"phase", name}, {"ms", ms}, {"mb", bytes / 1e6}, {"gbs", gbs}, {"fraction", gbs / limit_gbs}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Memory bandwidth and the FMG cycle's phases against it"};
  std::string scene_file = "scenes/drape_sphere.json", vertices_s = "40000,120000", threads_s = "1,2", json_file;
  int step = 5, repeat = 5, cycles = 5;
  double stream_mb = 1024.0;
  app.add_option("--scene", scene_file);
  app.add_option("--vertices", vertices_s);
  app.add_option("--threads", threads_s);
  app.add_option("--step", step, "simulated steps before the frozen one");
  app.add_option("--repeat", repeat);
  app.add_option("--cycles", cycles, "FMG cycles timed on the frozen step");
  app.add_option("--stream-mb", stream_mb, "size of each STREAM array, MB");
  app.add_option("--json", json_file);
  CLI11_PARSE(app, argc, argv);
  const auto thread_counts = int_list(threads_s);

  Json out{{"command", [&] {
              std::string c;
              for (int i = 0; i < argc; ++i) c += (i ? " " : "") + std::string(argv[i]);
              return c;
            }()}};
  std::map<int, double> triad;
  std::printf("## Memory bandwidth (GB/s, arrays of %.0f MB, best of %d)\n\n| threads | copy | scale | add | triad | read |\n|---:|---:|---:|---:|---:|---:|\n",
              stream_mb, repeat);
  for (int t : thread_counts) {
    Json s = stream_bandwidth(t, stream_mb, repeat);
    triad[t] = s["triad"];
    std::printf("| %d | %.1f | %.1f | %.1f | %.1f | %.1f |\n", t, double(s["copy"]), double(s["scale"]), double(s["add"]),
                double(s["triad"]), double(s["read"]));
    out["stream"].push_back(s);
  }

  const sim::Scene base = sim::load_scene(scene_file);
  for (int nv : int_list(vertices_s)) {
    set_num_threads(thread_counts.back());
    sim::Simulator simulator(studies::with_vertex_count(base, nv));
    for (int s = 0; s < step; ++s) simulator.step();
    VecX x;
    solvers::Problem problem = simulator.prepare_problem(0, x);
    const physics::Objective& obj = *problem.objective;
    const auto prolongations = problem.hierarchy.prolongations();
    const solvers::FmgParams fmg_defaults;
    solvers::LinearMultigrid mg(prolongations, obj.hessian_pattern(), fmg_defaults.multigrid);
    linalg::BlockMatrix3 A;
    obj.hessian(x, A, true);
    mg.set_matrix(A);
    const Index L = mg.num_levels();
    std::printf("\n## %d vertices (%s, step %d), %d levels\n\n| level | rows | blocks | colors | matrix MB |\n|---:|---:|---:|---:|---:|\n",
                A.rows(), scene_file.c_str(), step, L);
    Json size{{"vertices", A.rows()}, {"levels", L}};
    double vcycle_bytes = 0.0;
    const auto& mp = fmg_defaults.multigrid;
    for (Index l = 0; l < L; ++l) {
      const auto& Al = mg.matrix(l);
      const size_t colors = linalg::color_rows(Al).size();
      std::printf("| %d | %d | %d | %zu | %.1f |\n", l, Al.rows(), Al.num_blocks(), colors, 76e-6 * Al.num_blocks());
      size["level_rows"].push_back(Al.rows());
      size["level_blocks"].push_back(Al.num_blocks());
      size["level_colors"].push_back(colors);
      // Per smoothed level of a V-cycle: pre + post symmetric sweeps (two passes each) and the residual product.
      if (l + 1 < L) {
        linalg::MultiColorGaussSeidel gs(Al);
        gs.set_matrix(Al);
        vcycle_bytes += 2.0 * (mp.pre_smooth + mp.post_smooth) * gs.pass_bytes() + matvec_bytes(Al);
      }
    }

    for (int t : thread_counts) {
      set_num_threads(t);
      const double limit = triad[t];
      Json rows = Json::array();
      std::printf("\n### %d vertices, %d thread%s (triad %.1f GB/s)\n\n| phase | ms | MB (compulsory) | GB/s | of triad |\n|---|---:|---:|---:|---:|\n",
                  A.rows(), t, t > 1 ? "s" : "", limit);
      const auto add = [&](const std::string& name, double ms, double bytes) {
        rows.push_back(phase(name, ms, bytes, limit));
        if (bytes > 0.0)
          std::printf("| %s | %.2f | %.1f | %.1f | %.0f%% |\n", name.c_str(), ms, bytes / 1e6, bytes / (ms * 1e6),
                      100.0 * bytes / (ms * 1e6) / limit);
        else
          std::printf("| %s | %.2f | – | – | – |\n", name.c_str(), ms);
      };
      const VecX b = VecX::Random(3 * A.rows());
      for (Index l = 0; l + 1 < L; ++l) {
        const auto& Al = mg.matrix(l);
        VecX bl = VecX::Random(3 * Al.rows()), xl = VecX::Zero(3 * Al.rows()), yl;
        if (l == 0) {
          const InPlaceGaussSeidel before(Al);
          add("level 0 symmetric Gauss-Seidel sweep, rows in place (before)",
              bench::best_ms(repeat, [&] { before.symmetric_sweep(bl, xl); }), 2.0 * gs_pass_bytes(Al));
        }
        for (const auto precision : {linalg::MultiColorGaussSeidel::Precision::Double, linalg::MultiColorGaussSeidel::Precision::Single}) {
          const bool single = precision == linalg::MultiColorGaussSeidel::Precision::Single;
          linalg::MultiColorGaussSeidel gs(Al, precision);
          gs.set_matrix(Al);
          add(fmt::format("level {} symmetric Gauss-Seidel sweep{}", l, single ? ", float blocks" : ""),
              bench::best_ms(repeat, [&] { gs.symmetric_sweeps(bl, xl, 1); }), 2.0 * gs.pass_bytes());
          if (l == 0) {  // reads A, writes the copy and the inverted diagonal
            add(fmt::format("level 0 smoother set_matrix (color-ordered copy{})", single ? ", float" : ""),
                bench::best_ms(repeat, [&] { gs.set_matrix(Al); }), pass_bytes(Al, 0.0) + gs.pass_bytes() - 72.0 * Al.rows());
          }
        }
        add(fmt::format("level {} product A x", l), bench::best_ms(repeat, [&] { Al.multiply(bl, yl); }), matvec_bytes(Al));
        {
          linalg::MultiColorGaussSeidel gs(Al);
          gs.set_matrix(Al);
          add(fmt::format("level {} product A x from the smoother's copy", l), bench::best_ms(repeat, [&] { gs.multiply(bl, yl); }),
              gs.pass_bytes() + 72.0 * Al.rows());
        }
      }
      VecX xv;
      add("V-cycle (linear, from zero)", bench::best_ms(repeat, [&] { xv.setZero(b.size()); mg.vcycle(0, b, xv); }), vcycle_bytes);
      VecX rc, pf;
      add("restrict + prolong, level 0-1", bench::best_ms(repeat, [&] {
            mg.restrict_to(0, b, rc);
            mg.prolong(0, rc, pf);
          }),
          0.0);
      linalg::BlockMatrix3 H = A;
      add("Hessian assembly (PSD-projected)", bench::best_ms(repeat, [&] { obj.hessian(x, H, true); }), 76.0 * H.num_blocks());
      add("  of which: zeroing the matrix", bench::best_ms(repeat, [&] { H.set_zero(); }), 76.0 * H.num_blocks());
      for (const auto& term : obj.terms())
        add(fmt::format("  of which: {} Hessian", term->name()), bench::best_ms(repeat, [&] { term->add_hessian(x, H, true); }), 0.0);
      {
        linalg::BlockMatrix3 Hc;
        physics::Objective::ConstantHessian cache;
        obj.hessian_reusing_constant(x, Hc, true, cache);
        add("Hessian assembly reusing the constant blocks", bench::best_ms(repeat, [&] { obj.hessian_reusing_constant(x, Hc, true, cache); }),
            76.0 * static_cast<double>(obj.variable_blocks().size()));
      }
      add("Galerkin update, smoother diagonals, coarsest factorization", bench::best_ms(repeat, [&] { mg.set_matrix(A); }), 0.0);
      {
        solvers::LinearMultigrid split(prolongations, obj.hessian_pattern(), fmg_defaults.multigrid);
        split.set_matrix(A, &obj.constant_blocks(), obj.pattern_stamp());
        split.set_matrix(A, &obj.constant_blocks(), obj.pattern_stamp());
        add("the same with the constant blocks summed once", bench::best_ms(repeat, [&] {
              split.set_matrix(A, &obj.constant_blocks(), obj.pattern_stamp());
            }),
            0.0);
      }
      double galerkin_bytes = 0.0;
      for (Index l = 0; l + 1 < L; ++l)
        galerkin_bytes += 76.0 * (mg.matrix(l).num_blocks() + mg.matrix(l + 1).num_blocks());
      {
        // The RAP products alone, per level, reading A_l and writing A_{l+1}.
        std::vector<linalg::GalerkinProduct> raps;
        std::vector<linalg::BlockMatrix3> coarse(static_cast<size_t>(L));
        for (Index l = 0; l + 1 < L; ++l) raps.emplace_back(mg.matrix(l), *prolongations[static_cast<size_t>(l)]);
        add("Galerkin RAP products (all levels)", bench::best_ms(repeat, [&] {
              for (Index l = 0; l + 1 < L; ++l) raps[static_cast<size_t>(l)].compute(mg.matrix(l), coarse[static_cast<size_t>(l + 1)]);
            }),
            galerkin_bytes);
        add("  of which level 0 to 1", bench::best_ms(repeat, [&] { raps[0].compute(A, coarse[1]); }),
            76.0 * (A.num_blocks() + mg.matrix(1).num_blocks()));
        raps[0].set_constant_blocks(obj.constant_blocks());
        raps[0].compute_constant(A);
        add("  level 0 to 1 with the constant blocks summed once", bench::best_ms(repeat, [&] { raps[0].compute(A, coarse[1]); }),
            76.0 * (static_cast<double>(obj.variable_blocks().size()) + 2.0 * mg.matrix(1).num_blocks()));
      }
      {
        // Plain against constant blocks apart, alternated call by call so that the machine's drift (other jobs on
        // its memory) hits both alike: the median of 9 pairs.
        solvers::LinearMultigrid split(prolongations, obj.hessian_pattern(), fmg_defaults.multigrid);
        split.set_matrix(A, &obj.constant_blocks(), obj.pattern_stamp());
        linalg::BlockMatrix3 Hp = A, Hs;
        physics::Objective::ConstantHessian cache;
        obj.hessian_reusing_constant(x, Hs, true, cache);
        std::vector<double> tp[2], ts[2];
        for (int k = 0; k < 9; ++k) {
          Timer a;
          obj.hessian(x, Hp, true);
          tp[0].push_back(a.ms());
          Timer b2;
          obj.hessian_reusing_constant(x, Hs, true, cache);
          ts[0].push_back(b2.ms());
          Timer c;
          mg.set_matrix(A);
          tp[1].push_back(c.ms());
          Timer d;
          split.set_matrix(A, &obj.constant_blocks(), obj.pattern_stamp());
          ts[1].push_back(d.ms());
        }
        const auto median = [](std::vector<double> v) {
          std::sort(v.begin(), v.end());
          return v[v.size() / 2];
        };
        add("A/B, median of 9 alternated: Hessian assembly", median(tp[0]), 0.0);
        add("A/B: Hessian assembly reusing the constant blocks", median(ts[0]), 0.0);
        add("A/B: Galerkin update (all levels, smoother copies, coarsest factorization)", median(tp[1]), 0.0);
        add("A/B: the same with the constant blocks summed once", median(ts[1]), 0.0);
      }
      VecX g;
      add("gradient", bench::best_ms(repeat, [&] { obj.gradient(x, g); }), 0.0);
      double e = 0.0;
      add("energy", bench::best_ms(repeat, [&] { e += obj.value(x); }), 0.0);

      // The cycle as the solver runs it, for the per-cycle total and its own phase counters.
      solvers::NonlinearFMG fmg;
      solvers::Stop stop;
      stop.rel_grad = 0.0;
      stop.max_iters = 1;
      VecX xw = x;
      (void)fmg.minimize(problem, xw, stop, nullptr);  // warm-up: hierarchy, colorings, Chebyshev radii
      stop.max_iters = cycles;
      xw = x;
      Timer tc;
      const auto report = fmg.minimize(problem, xw, stop, nullptr);
      const double per = tc.ms() / std::max(1, report.iterations);
      const auto& st = fmg.stats();
      const double it = std::max(1, report.iterations);
      std::printf("\nFMG cycle as run (%d cycles): %.1f ms per cycle; assembly %.1f, Galerkin %.1f, V-cycle %.1f, transfers %.1f ms\n",
                  report.iterations, per, st.assembly_ms / it, st.galerkin_ms / it, st.linear_ms / it, st.transfer_ms / it);
      out["sizes"].push_back(Json{{"threads", t},
                                  {"size", size},
                                  {"phases", rows},
                                  {"fmg_cycle_ms", per},
                                  {"fmg_cycles", report.iterations},
                                  {"fmg_assembly_ms", st.assembly_ms / it},
                                  {"fmg_galerkin_ms", st.galerkin_ms / it},
                                  {"fmg_vcycle_ms", st.linear_ms / it},
                                  {"fmg_transfer_ms", st.transfer_ms / it}});
    }
  }
  if (!json_file.empty()) {
    std::ofstream f(json_file);
    f << out.dump(2) << "\n";
  }
}
