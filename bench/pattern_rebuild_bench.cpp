// The cost of a Hessian pattern that changes (issue 27, deliverable 3): when a term's stencils appear or disappear
// (contact pairs), the objective's BSR pattern and scatter slots, the multigrid's colorings, Galerkin maps and coarse
// patterns, and the coarsest CHOLMOD analysis are rebuilt. Measured on the shipped drape (scenes/drape_sphere.json)
// at the given sizes, its step-1 objective at the prediction, against the numeric work that is done every cycle
// anyway (one Hessian assembly and one numeric Galerkin + factorization update of the hierarchy).
//
//   build/bin/mgcloth_bench_pattern_rebuild --vertices 10000,40000,120000 [--threads 1] [--reps 5]
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/sim/simulator.hpp>
#include <mgcloth/solvers/linear_multigrid.hpp>

#include "best_ms.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>

using namespace mgcloth;

int main(int argc, char** argv) {
  CLI::App app("Cost of rebuilding what depends on the Hessian pattern");
  std::string sizes = "10000,40000,120000", scene_path = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/drape_sphere.json";
  int threads = 1, reps = 5;
  app.add_option("--vertices", sizes, "Comma-separated cloth sizes");
  app.add_option("--scene", scene_path, "Scene (its first cloth is resized)");
  app.add_option("--threads", threads, "Worker threads");
  app.add_option("--reps", reps, "Repetitions (the best is reported)");
  CLI11_PARSE(app, argc, argv);
  set_num_threads(threads);
  std::printf("| vertices | pattern blocks | levels | objective pattern + scatter slots | multigrid symbolic (colorings, Galerkin maps) | coarsest CHOLMOD analysis | rebuild in all | Hessian assembly | numeric hierarchy update | rebuild / (assembly + update) |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  std::stringstream ss(sizes);
  for (std::string item; std::getline(ss, item, ',');) {
    Json j = load_json(scene_path);
    j["cloths"][0]["mesh"]["vertices"] = std::stoi(item);
    j["threads"] = threads;
    sim::Simulator s(sim::parse_scene(j, scene_path, std::filesystem::path(scene_path).parent_path()));
    VecX x;
    const solvers::Problem p = s.prepare_problem(0, x);
    auto& E = const_cast<physics::Objective&>(*p.objective);
    const auto P = p.hierarchy.prolongations().empty() ? s.cloths()[0]->hierarchy().levels_for_solvers().prolongations()
                                                       : p.hierarchy.prolongations();
    linalg::BlockMatrix3 H;
    E.hessian(x, H, true);
    // What a rebuild redoes, piece by piece (finalize() is the objective's whole pattern rebuild).
    const double pattern_ms = bench::best_ms(reps, [&] { E.finalize(); });
    const double symbolic_ms = bench::best_ms(reps, [&] { solvers::LinearMultigrid mg(P, H); (void)mg; });
    solvers::LinearMultigrid mg(P, H);
    mg.set_matrix(H);
    const double numeric_ms = bench::best_ms(reps, [&] { mg.set_matrix(H); });
    // The coarsest analysis: a fresh hierarchy's first set_matrix analyses, later ones only factor.
    double first_ms = 1e300;
    for (int r = 0; r < reps; ++r) {
      solvers::LinearMultigrid fresh(P, H);
      Timer t;
      fresh.set_matrix(H);
      first_ms = std::min(first_ms, t.ms());
    }
    const double analysis_ms = std::max(0.0, first_ms - numeric_ms);
    const double assembly_ms = bench::best_ms(reps, [&] { E.hessian(x, H, true); });
    const double rebuild = pattern_ms + symbolic_ms + analysis_ms;
    std::printf("| %ld | %ld | %ld | %.1f ms | %.1f ms | %.1f ms | %.1f ms | %.1f ms | %.1f ms | %.2f |\n",
                static_cast<long>(H.rows()), static_cast<long>(H.num_blocks()), static_cast<long>(mg.num_levels()),
                pattern_ms, symbolic_ms, analysis_ms, rebuild, assembly_ms, numeric_ms,
                rebuild / (assembly_ms + numeric_ms));
    std::fflush(stdout);
  }
  return 0;
}
