// Assembly costs of a subdivision-shell time step (Kopaničáková 2019, eq. 3.9): energy, gradient and exact Hessian
// of the whole objective (Catmull-Clark Kirchhoff-Love elements, inertia, boundary penalties) at the first step's
// start perturbed by a smooth displacement, per level. The element Hessian is most of an RMTR V-cycle with Newton
// smoothing (bench/RESULTS.md), hence this program.
//   mgcloth_bench_shell_assembly [--scene FILE] [--levels 4,5,6] [--repeat R] [--threads T]
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/sim/simulator.hpp>

#include "best_ms.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <functional>

using namespace mgcloth;

using bench::best_ms;

int main(int argc, char** argv) {
  CLI::App app{"mgcloth shell assembly benchmark"};
  std::string scene_file = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_drape.json";
  std::vector<int> levels{4, 5, 6};
  int repeat = 3, threads = 1;
  app.add_option("--scene", scene_file, "shell scene");
  app.add_option("--levels", levels, "levels")->delimiter(',');
  app.add_option("--repeat", repeat, "timed runs per measurement (best is reported)");
  app.add_option("--threads", threads, "threads");
  CLI11_PARSE(app, argc, argv);
  set_num_threads(threads);
  std::printf("level,dofs,value_ms,gradient_ms,hessian_ms,projected_hessian_ms,checksum\n");
  for (int level : levels) {
    sim::Scene scene = sim::load_scene(scene_file);
    scene.shells[0].level = level;
    sim::Simulator sim(scene);
    VecX x;
    const solvers::Problem problem = sim.prepare_problem(0, x);
    const physics::Objective& f = *problem.objective;
    for (Index i = 0; i < x.size(); ++i) x[i] += 1e-3 * std::sin(0.37 * static_cast<double>(i));
    VecX g;
    linalg::BlockMatrix3 H = f.hessian_pattern();
    double sum = 0.0;
    const double tv = best_ms(repeat, [&] { sum += f.value(x); });
    const double tg = best_ms(repeat, [&] {
      f.gradient(x, g);
      sum += g[0];
    });
    const double th = best_ms(repeat, [&] {
      f.hessian(x, H, false);
      sum += H.blocks()[0](0, 0);
    });
    const double tp = best_ms(repeat, [&] {
      f.hessian(x, H, true);
      sum += H.blocks()[0](0, 0);
    });
    std::printf("%d,%lld,%.2f,%.2f,%.2f,%.2f,%.6e\n", level, static_cast<long long>(x.size()), tv, tg, th, tp, sum);
  }
  return 0;
}
