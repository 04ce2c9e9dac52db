// Linear solvers on the Newton systems of a cloth scene (issue 3 benchmark): the scene is simulated for a few frames
// (so that the cloth has touched its obstacle), then the PSD-projected Hessian H and the gradient g of the next
// step's objective at the current state are frozen, and H d = -g is solved to a relative residual --rel by
//   cholmod      sparse Cholesky (numeric factorization + solve; the symbolic analysis, once per mesh, excluded)
//   pcg-amg      CG preconditioned by one hypre BoomerAMG V-cycle (setup per matrix: BoomerAMG has no reuse)
//   pcg-jacobi   CG preconditioned by block Jacobi
//   mg           multigrid V(2,2)-cycles as the solver
//   pcg-mg       CG preconditioned by one V(2,2)-cycle; pcg-mg11 the same with V(1,1)
// Setup is everything that depends on the matrix values (for multigrid: Galerkin products, smoother diagonals,
// coarsest factorization); what depends only on the mesh (hierarchy, coloring, symbolic Galerkin map, CHOLMOD
// analysis) is built before the clock starts and reported on its own. Also reported: the hierarchy build time, the
// Galerkin update (ours against Eigen's generic triple product), and the measured V-cycle contraction.
//   mgcloth_bench_linear SCENE.json --vertices N [--frames K] [--rel 1e-6] [--threads T] [--methods LIST]
//                        [--state FILE] [--csv FILE]
// --state caches the simulated state (x, v after K frames) so that repeated runs skip the simulation.
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/linalg/block_jacobi.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/linalg/hypre_amg.hpp>
#include <mgcloth/linalg/pcg.hpp>
#include <mgcloth/studies/convergence.hpp>
#include <mgcloth/sim/simulator.hpp>
#include <mgcloth/solvers/linear_multigrid.hpp>

#include <CLI/CLI.hpp>
#include <Eigen/SparseCore>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

using namespace mgcloth;

namespace {

struct Row {
  std::string method;
  double setup_ms = 0.0, solve_ms = 0.0;
  int iterations = 0;
  double residual = 0.0;
};

double relative_residual(const linalg::BlockMatrix3& A, const VecX& b, const VecX& x) { return (b - A * x).norm() / b.norm(); }

Eigen::SparseMatrix<double> scalar_prolongation(const linalg::StencilTable& P) {
  std::vector<Eigen::Triplet<double>> trip;
  for (Index i = 0; i < P.num_rows; ++i)
    for (Index k = P.offsets[i]; k < P.offsets[i + 1]; ++k)
      for (int d = 0; d < 3; ++d) trip.emplace_back(3 * i + d, 3 * P.indices[k] + d, P.weights[k]);
  Eigen::SparseMatrix<double> S(3 * P.num_rows, 3 * P.num_cols);
  S.setFromTriplets(trip.begin(), trip.end());
  return S;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Linear solvers on a cloth Newton system"};
  std::string scene_path, csv, state, drop_term, methods_arg = "cholmod,pcg-amg,pcg-jacobi,mg,pcg-mg,pcg-mg11";
  int vertices = 0, frames = 3, threads = 2, max_iters = 2000;
  double rel = 1e-6;
  app.add_option("scene", scene_path)->required()->check(CLI::ExistingFile);
  app.add_option("--vertices", vertices, "Override the first cloth's generated vertex count");
  app.add_option("--frames", frames, "Frames simulated before the system is frozen");
  app.add_option("--rel", rel, "Relative residual to reach");
  app.add_option("--threads", threads, "Threads (CHOLMOD always runs on one; see bench/RESULTS.md)");
  app.add_option("--methods", methods_arg, "Comma-separated methods");
  app.add_option("--max-iters", max_iters, "Iteration cap of the iterative methods");
  app.add_option("--state", state, "Cache file for the simulated state");
  app.add_option("--csv", csv, "Append the rows to this CSV file");
  app.add_option("--drop-term", drop_term, "Diagnostics: leave this term (e.g. contact) out of the Hessian");
  CLI11_PARSE(app, argc, argv);
  try {
    set_num_threads(threads);
    Json j = load_json(scene_path);
    if (vertices > 0) j["cloths"][0]["mesh"]["vertices"] = vertices;
    // The frames before the measurement only bring the cloth onto the sphere: Newton + multigrid-PCG (the fastest
    // here) to a loose tolerance (1e-2 relative gradient, at most 20 iterations per step).
    j["solver"]["params"] = {{"linear_solver", "pcg-mg"}};
    j["solver"]["rel_grad"] = 1e-2;
    j["solver"]["max_iters"] = 20;
    j["threads"] = threads;
    sim::Simulator s(sim::parse_scene(j, scene_path, std::filesystem::path(scene_path).parent_path()));
    auto& body = *s.cloths()[0];
    const Index n = body.mesh().num_vertices();
    // The cached state depends on the scene as run here (vertex count, loose solver) and on the frame count.
    const Json state_key = {{"bench", "linear"}, {"scene", studies::state_cache_key(s.scene())}, {"frames", frames}};
    std::optional<studies::SimState> cached;
    if (!state.empty()) cached = studies::load_state_cache(state, state_key);
    if (cached) {
      s.set_state(cached->frame, cached->step, cached->x, cached->v);
    } else {
      Timer t;
      while (s.frame() < frames) {
        for (const auto& st : s.advance_frame())
          std::fprintf(stderr, "frame %d: %d Newton iterations, %.1f s\n", st.frame, st.report.iterations, st.wall_ms / 1e3);
      }
      if (!state.empty()) studies::save_state_cache(state, state_key, studies::simulator_state(s));
    }
    const double t = static_cast<double>(frames) * s.scene().frame_time;  // also right for a cached state
    body.prepare_step(t, s.scene().step_size());
    const VecX x = body.x();  // Newton's systems around the draped state, contact active
    linalg::BlockMatrix3 H;
    body.objective().hessian(x, H, true);
    if (!drop_term.empty()) {
      for (Index k = 0; k < H.num_blocks(); ++k) H.block(k).setZero();
      for (const auto& term : body.objective().terms())
        if (term->name() != drop_term) term->add_hessian(x, H, true);
    }
    VecX b;
    body.objective().gradient(x, b);
    b = -b;

    Timer timer;
    {
      hierarchy::HierarchyParams hp = s.scene().hierarchy;
      hp.keep = body.pinned_vertices();
      (void)hierarchy::build_triangle_hierarchy(body.mesh(), hp);  // timed on its own: the body's may be built already
    }
    const double hierarchy_ms = timer.ms();
    const auto& h = body.hierarchy();
    const auto P = h.levels_for_solvers().prolongations();

    std::vector<std::string> methods;
    std::stringstream ss(methods_arg);
    for (std::string m; std::getline(ss, m, ',');) methods.push_back(m);

    std::vector<Row> rows;
    std::string mg_info;
    for (const auto& m : methods) {
      Row r;
      r.method = m;
      VecX d = VecX::Zero(b.size());
      if (m == "cholmod") {
        linalg::CholmodSolver chol;
        chol.factorize(H);  // symbolic analysis (once per mesh) + a first factorization, not timed
        timer.reset();
        chol.factorize(H);
        r.setup_ms = timer.ms();
        timer.reset();
        chol.solve(b, d);
        r.solve_ms = timer.ms();
        r.iterations = 1;
      } else if (m == "pcg-amg") {
        linalg::HypreAmg amg;
        timer.reset();
        amg.set_matrix(H);
        r.setup_ms = timer.ms();
        timer.reset();
        r.iterations = linalg::pcg(H, b, d, [&](const VecX& q, VecX& z) { amg.apply(q, z); }, rel, max_iters);
        r.solve_ms = timer.ms();
      } else if (m == "pcg-jacobi") {
        linalg::BlockJacobi jac;
        timer.reset();
        jac.set_matrix(H);
        r.setup_ms = timer.ms();
        timer.reset();
        r.iterations = linalg::pcg(H, b, d, [&](const VecX& q, VecX& z) { jac.apply(q, z); }, rel, max_iters);
        r.solve_ms = timer.ms();
      } else if (m == "mg" || m == "pcg-mg" || m == "pcg-mg11") {
        solvers::MultigridParams p;
        if (m == "pcg-mg11") p.pre_smooth = p.post_smooth = 1;
        solvers::LinearMultigrid mg(P, H, p);
        mg.set_matrix(H);  // warm-up
        timer.reset();
        mg.set_matrix(H);
        r.setup_ms = timer.ms();
        timer.reset();
        if (m == "mg") {
          const double target = rel * b.norm();
          for (r.iterations = 1; r.iterations <= max_iters; ++r.iterations) {
            mg.vcycle(b, d);
            if ((b - H * d).norm() <= target) break;
          }
        } else {
          r.iterations = linalg::pcg(H, b, d, [&](const VecX& q, VecX& z) { mg.precondition(q, z); }, rel, max_iters);
        }
        r.solve_ms = timer.ms();
        if (mg_info.empty() || m == "pcg-mg11") {
          char buf[128];
          std::snprintf(buf, sizeof buf, "%sV(%d,%d) contraction %.3f", mg_info.empty() ? "" : ", ", p.pre_smooth,
                        p.post_smooth, mg.contraction(b));
          mg_info += buf;
        }
      } else {
        throw InputError("unknown method " + m);
      }
      r.residual = relative_residual(H, b, d);
      rows.push_back(r);
      std::fprintf(stderr, "%-10s setup %9.1f ms  solve %9.1f ms  iterations %5d  residual %.1e\n", m.c_str(), r.setup_ms,
                   r.solve_ms, r.iterations, r.residual);
    }

    // Galerkin update: ours (all levels) against Eigen's generic Pᵀ A P on the same scalar matrices.
    double ours_ms = 0.0, eigen_ms = 0.0;
    {
      linalg::BlockMatrix3 current = H;
      for (size_t l = 0; l < P.size(); ++l) {
        linalg::GalerkinProduct rap(current, *P[l]);
        linalg::BlockMatrix3 coarse;
        rap.compute(current, coarse);
        timer.reset();
        rap.compute(current, coarse);
        ours_ms += timer.ms();
        const Eigen::SparseMatrix<double> Ps = scalar_prolongation(*P[l]), Pt = Ps.transpose();
        const Eigen::SparseMatrix<double> As = current.to_sparse();
        timer.reset();
        Eigen::SparseMatrix<double> Ac = Pt * As * Ps;
        eigen_ms += timer.ms();
        current = coarse;
      }
    }
    std::string levels;
    for (Index l = 0; l < h.num_levels(); ++l) levels += (l ? "/" : "") + std::to_string(h.level(l).mesh.num_vertices());
    std::printf("\n%s, %d vertices, %d threads, relative residual %.0e; hierarchy %s vertices built in %.0f ms; Galerkin "
                "update %.1f ms (Eigen PᵀAP %.1f ms, %.0f×); %s\n",
                scene_path.c_str(), n, threads, rel, levels.c_str(), hierarchy_ms, ours_ms, eigen_ms, eigen_ms / ours_ms,
                mg_info.c_str());
    double chol_total = 0.0;
    for (const auto& r : rows)
      if (r.method == "cholmod") chol_total = r.setup_ms + r.solve_ms;
    std::printf("| method | setup (ms) | iterations | solve (ms) | total (ms) | rel. residual | vs CHOLMOD |\n");
    std::printf("|---|---:|---:|---:|---:|---:|---:|\n");
    for (const auto& r : rows)
      std::printf("| %s | %.1f | %d | %.1f | %.1f | %.1e | %s |\n", r.method.c_str(), r.setup_ms, r.iterations, r.solve_ms,
                  r.setup_ms + r.solve_ms, r.residual,
                  chol_total > 0 ? fmt::format("{:.2f}×", chol_total / (r.setup_ms + r.solve_ms)).c_str() : "–");
    if (!csv.empty()) {
      const bool fresh = !std::filesystem::exists(csv);
      std::ofstream out(csv, std::ios::app);
      if (fresh) out << "vertices,threads,method,setup_ms,iterations,solve_ms,total_ms,residual\n";
      for (const auto& r : rows)
        out << n << ',' << threads << ',' << r.method << ',' << r.setup_ms << ',' << r.iterations << ',' << r.solve_ms << ','
            << r.setup_ms + r.solve_ms << ',' << r.residual << '\n';
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
