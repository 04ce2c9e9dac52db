// Element assembly costs per term: value, gradient, exact Hessian, and the PSD-projected Hessian two ways — the
// generic per-element eigendecomposition with negative eigenvalues clamped (ElementTerm's default) against the
// term's closed-form PSD Hessian (StVK with clamped stress, Gauss-Newton hinge). Backs the choice in
// physics/element_term.hpp to override element_psd_hessian in every term whose projection dominates assembly.
//   mgcloth_bench_assembly [--vertices N] [--repeat R] [--threads T]
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/objective.hpp>

#include "best_ms.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <functional>

using namespace mgcloth;

using bench::best_ms;

namespace {

/// The element Hessians of `term` computed by `hessian(e, xe, He)` for every element, without the scatter (the
/// element work of ElementTerm::add_hessian); returns a checksum so that the work is not optimized away.
template <int K, class H>
double element_hessians(const physics::ElementTerm<K>& term, const VecX& x, H&& hessian) {
  return parallel_sum(term.num_elements(), [&](Index e) {
    typename physics::ElementTerm<K>::LocalHessian He;
    hessian(e, term.gather(x, e), He);
    return He(0, 0);
  });
}

template <int K>
void row(const char* name, const physics::ElementTerm<K>& term, const VecX& x, int repeat) {
  double sink = 0.0;
  VecX g(x.size());
  const double value = best_ms(repeat, [&] { (void)term.value(x); });
  const double grad = best_ms(repeat, [&] {
    g.setZero();
    term.add_gradient(x, g);
  });
  const double fused = best_ms(repeat, [&] {
    g.setZero();
    sink += term.value_and_gradient(x, g);
  });
  using Term = physics::ElementTerm<K>;
  const double exact = best_ms(repeat, [&] {
    sink += element_hessians(term, x, [&](Index e, const auto& xe, auto& He) {
      typename Term::Local ge;
      term.element(e, xe, &ge, &He);
    });
  });
  // Qualified call: the base class's generic eigen projection, bypassing the term's closed-form override.
  const double eig = best_ms(repeat, [&] {
    sink += element_hessians(term, x, [&](Index e, const auto& xe, auto& He) { term.Term::element_psd_hessian(e, xe, He); });
  });
  const double closed = best_ms(repeat, [&] {
    sink += element_hessians(term, x, [&](Index e, const auto& xe, auto& He) { term.element_psd_hessian(e, xe, He); });
  });
  if (!std::isfinite(sink)) std::printf("non-finite Hessian\n");
  std::printf("| %s | %d | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.1f× |\n", name, term.num_elements(), value, grad,
              fused, exact, eig, closed, eig / closed);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Element assembly costs: exact, eigen-projected and closed-form PSD Hessians per term"};
  int vertices = 10000, repeat = 5, threads = 1;
  app.add_option("--vertices", vertices, "target vertex count of the unstructured sheet")->check(CLI::PositiveNumber);
  app.add_option("--repeat", repeat, "timed repetitions (best is reported)")->check(CLI::PositiveNumber);
  app.add_option("--threads", threads, "threads")->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);
  set_num_threads(threads);

  mesh::RectangleSpec spec;
  spec.target_vertices = vertices;
  spec.unstructured = true;
  const auto m = mesh::make_rectangle(spec);
  const auto topo = mesh::build_topology(m);
  physics::Material mat;
  // A stretched, compressed and curved state, so that the projections have negative eigenvalues to clamp.
  VecX x = as_stacked(m.x);
  for (Index i = 0; i < m.num_vertices(); ++i) {
    x[3 * i] *= 1.0 + 0.05 * std::sin(9.0 * x[3 * i + 1]);
    x[3 * i + 2] = 0.05 * std::sin(6.0 * x[3 * i]) * std::cos(4.0 * x[3 * i + 1]);
  }
  const physics::StVKMembrane stvk(m, mat);
  const physics::HingeBending hinge(m, topo, mat);
  std::printf("%d vertices, %d thread(s), best of %d (ms)\n\n", m.num_vertices(), threads, repeat);
  std::printf("| term | elements | value | gradient | value and gradient, one pass | exact Hessian | eigen-projected | "
              "closed-form PSD | eigen / closed |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  row("StVK membrane", stvk, x, repeat);
  row("hinge bending", hinge, x, repeat);

  // The same elements assembled into the block matrix, as the solvers do it (closed-form PSD, colored scatter).
  physics::Objective obj(m.num_vertices());
  obj.add(std::make_unique<physics::StVKMembrane>(m, mat));
  obj.add(std::make_unique<physics::HingeBending>(m, topo, mat));
  obj.finalize();
  linalg::BlockMatrix3 H;
  const double zero = best_ms(repeat, [&] {
    H = obj.hessian_pattern();
    H.set_zero();
  });
  const double full = best_ms(repeat, [&] { obj.hessian(x, H, true); });
  VecX g;
  double sink = 0.0;
  const double separate = best_ms(repeat, [&] {
    sink += obj.value(x);
    obj.gradient(x, g);
  });
  const double one_pass = best_ms(repeat, [&] { sink += obj.value_and_gradient(x, g); });
  std::printf("\nObjective::hessian (StVK + hinge, PSD, into %d blocks): %.2f ms (of which copying and zeroing the "
              "pattern: %.2f ms); assembly colors: StVK %d (chunks of %d), hinge %d (chunks of %d)\n",
              H.num_blocks(), full, zero, stvk.colors().num_colors(), stvk.colors().chunk_size,
              hinge.colors().num_colors(), hinge.colors().chunk_size);
  std::printf("Objective value and gradient (StVK + hinge): %.2f ms as two passes, %.2f ms as one (%.2fx)%s\n", separate,
              one_pass, separate / one_pass, std::isfinite(sink) ? "" : " (non-finite)");
  return 0;
}
