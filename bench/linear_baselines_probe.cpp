// Linear-solver baselines on one projected cloth Hessian (inertia at Δt = 1/30 s, StVK membrane, hinge bending, at
// a stretched and curved state of an unstructured 1 m sheet; the system of tests/solvers/test_linear_multigrid):
// CHOLMOD, PCG with block-Jacobi, and PCG with BoomerAMG over every combination of the given AMG options, each
// solving H d = −g to a relative residual --tol. Setup (copy + AMG setup, or factorization) and solve are timed
// separately.
//   mgcloth_bench_linear_baselines --vertices N [--tol 1e-6] [--nodal 0,1] [--theta 0.25,0.5] [--coarsen hmis,pmis]
//       [--agg 0,1] [--pmax 4] [--interp 6] [--smoother fbgs,sgs,l1sgs,l1jacobi] [--sweeps 1] [--repeat R]
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/linalg/block_jacobi.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/linalg/hypre_amg.hpp>
#include <mgcloth/linalg/pcg.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/inertia.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/objective.hpp>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <ctime>
#include <map>

using namespace mgcloth;
namespace {
/// Wall and process CPU time. With OMP_NUM_THREADS=1 the CPU time is what the wall time would be on an idle
/// machine; on a shared one it is the steadier number for comparing configurations.
struct Clock {
  Timer wall;
  std::clock_t cpu = std::clock();
  double cpu_seconds() const { return static_cast<double>(std::clock() - cpu) / CLOCKS_PER_SEC; }
};
struct Best {
  double wall = kInf, cpu = kInf;
  void add(const Clock& c) {
    cpu = std::min(cpu, c.cpu_seconds());
    wall = std::min(wall, c.wall.seconds());
  }
};
}  // namespace
using Smoother = linalg::HypreAmgParams::Smoother;
using Coarsening = linalg::HypreAmgParams::Coarsening;

int main(int argc, char** argv) {
  CLI::App app{"PCG baselines (block-Jacobi, BoomerAMG) and CHOLMOD on a cloth Hessian"};
  int vertices = 10000, repeat = 1, max_iters = 5000;
  double tol = 1e-6;
  bool skip_jacobi = false, skip_direct = false;
  const linalg::HypreAmgParams defaults;  // every AMG option defaults to the library's default
  std::vector<int> nodal{defaults.nodal}, agg{defaults.aggressive_levels}, pmax{defaults.p_max_elements},
      interp{defaults.interp_type}, sweeps{defaults.sweeps}, print{0};
  std::vector<double> theta{defaults.strong_threshold};
  std::vector<std::string> coarsen{defaults.coarsening == Coarsening::PMIS ? "pmis" : "hmis"}, smoother{"fbgs"};
  app.add_option("--vertices", vertices);
  app.add_option("--tol", tol);
  app.add_option("--repeat", repeat, "setups and solves per configuration; the fastest are reported");
  app.add_option("--max-iters", max_iters);
  app.add_flag("--skip-jacobi", skip_jacobi);
  app.add_flag("--skip-direct", skip_direct);
  app.add_option("--nodal", nodal)->delimiter(',');
  app.add_option("--theta", theta)->delimiter(',');
  app.add_option("--coarsen", coarsen)->delimiter(',');
  app.add_option("--agg", agg)->delimiter(',');
  app.add_option("--pmax", pmax)->delimiter(',');
  app.add_option("--interp", interp)->delimiter(',');
  app.add_option("--smoother", smoother)->delimiter(',');
  app.add_option("--sweeps", sweeps)->delimiter(',');
  app.add_option("--print", print)->delimiter(',');
  CLI11_PARSE(app, argc, argv);

  mesh::RectangleSpec spec;
  spec.target_vertices = vertices;
  spec.unstructured = true;
  const auto m = mesh::make_rectangle(spec);
  const auto topo = mesh::build_topology(m);
  const Index n = m.num_vertices();
  physics::Material mat;
  VecX mass = VecX::Zero(n);
  for (Index t = 0; t < m.num_triangles(); ++t)
    for (Index v : m.tris[t]) mass[v] += m.material_area(t) / 3.0 * mat.areal_density();
  VecX x(3 * n);
  for (Index i = 0; i < n; ++i) {
    const Vec2 u = m.u.col(i);
    x.segment<3>(3 * i) = Vec3(1.05 * u.x(), u.y(), 0.1 * std::sin(3.0 * u.x()));
  }
  physics::Objective obj(n);
  auto& inertia = obj.add(std::make_unique<physics::InertiaTerm>(mass));
  inertia.set_prediction(x, 1.0 / 30.0);
  obj.add(std::make_unique<physics::StVKMembrane>(m, mat));
  obj.add(std::make_unique<physics::HingeBending>(m, topo, mat));
  obj.finalize();
  linalg::BlockMatrix3 H;
  obj.hessian(x, H, true);
  VecX g;
  obj.gradient(x, g);
  const VecX b = -g;
  std::printf("# %d vertices, %d dofs, %d blocks, %d threads, tol %.0e\n", n, 3 * n, H.num_blocks(), num_threads(), tol);
  std::printf("| solver | setup wall (cpu) s | iterations | solve wall (cpu) s | total wall (cpu) s | rel. residual |\n"
              "|---|---:|---:|---:|---:|---:|\n");
  auto residual = [&](const VecX& d) { return (b - H * d).norm() / b.norm(); };
  auto row = [&](const std::string& name, const Best& setup, int iters, const Best& solve, const VecX& d) {
    std::printf("| %s | %.3f (%.3f) | %s | %.3f (%.3f) | %.3f (%.3f) | %.1e |\n", name.c_str(), setup.wall, setup.cpu,
                iters < 0 ? "–" : std::to_string(iters).c_str(), solve.wall, solve.cpu, setup.wall + solve.wall,
                setup.cpu + solve.cpu, residual(d));
    std::fflush(stdout);
  };

  if (!skip_direct) {
    linalg::CholmodSolver chol;
    chol.factorize(H);  // the symbolic analysis is done once per pattern; time the numeric factorization
    Best setup, solve;
    VecX d;
    for (int r = 0; r < repeat; ++r) {
      Clock c;
      if (!chol.factorize(H)) std::printf("CHOLMOD: not positive definite\n");
      setup.add(c);
      Clock c2;
      chol.solve(b, d);
      solve.add(c2);
    }
    row("CHOLMOD (numeric factorization + solve)", setup, -1, solve, d);
  }
  if (!skip_jacobi) {
    Best setup, solve;
    linalg::BlockJacobi jacobi;
    VecX d;
    int iters = 0;
    for (int r = 0; r < repeat; ++r) {
      Clock c;
      jacobi.set_matrix(H);
      setup.add(c);
      d = VecX::Zero(b.size());
      Clock c2;
      iters = linalg::pcg(H, b, d, [&](const VecX& q, VecX& z) { jacobi.apply(q, z); }, tol, max_iters);
      solve.add(c2);
    }
    row("PCG block-Jacobi", setup, iters, solve, d);
  }
  const std::map<std::string, Smoother> smoothers{{"fbgs", Smoother::ForwardBackwardGS},
                                                  {"sgs", Smoother::SymmetricGS},
                                                  {"l1sgs", Smoother::L1SymmetricGS},
                                                  {"l1jacobi", Smoother::L1Jacobi}};
  for (int nod : nodal)
    for (double th : theta)
      for (const auto& co : coarsen)
        for (int ag : agg)
          for (int pm : pmax)
            for (int ip : interp)
              for (const auto& sm : smoother)
                for (int sw : sweeps)
                  for (int pr : print) {
                    linalg::HypreAmgParams p;
                    p.nodal = nod;
                    p.strong_threshold = th;
                    p.coarsening = co == "pmis" ? Coarsening::PMIS : Coarsening::HMIS;
                    p.aggressive_levels = ag;
                    p.p_max_elements = pm;
                    p.interp_type = ip;
                    p.smoother = smoothers.at(sm);
                    p.sweeps = sw;
                    p.print_level = pr;
                    linalg::HypreAmg amg(p);
                    amg.set_matrix(H);  // the first setup also allocates hypre's copy of the matrix
                    Best setup, solve;
                    double copy = kInf;
                    int iters = 0;
                    VecX d;
                    for (int r = 0; r < repeat; ++r) {
                      Clock c;
                      amg.set_matrix(H);  // as in Newton's later iterations: same pattern, new values
                      setup.add(c);
                      copy = std::min(copy, amg.copy_seconds());
                      d = VecX::Zero(b.size());
                      Clock c2;
                      iters = linalg::pcg(H, b, d, [&](const VecX& q, VecX& z) { amg.apply(q, z); }, tol, max_iters);
                      solve.add(c2);
                    }
                    row(fmt::format("BoomerAMG nodal={} θ={:.2f} {} agg={} interp={} pmax={} {}×{} (copy {:.3f} s)", nod,
                                    th, co, ag, ip, pm, sm, sw, copy),
                        setup, iters, solve, d);
                  }
  return 0;
}
