// Baseline measurement: a scene simulated with its solver (Newton + CHOLMOD by default) at a chosen cloth
// resolution; reports wall time per step and per Newton iteration, and iteration counts, over a window of frames.
//   mgcloth_bench_newton SCENE.json --vertices N --frames F [--from K] [--csv FILE]
// The last column splits one iteration's cost: assembly / factorization / solve, in ms (--frames 0 measures only
// that, on the first step).
#include <mgcloth/core/timer.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>

using namespace mgcloth;

int main(int argc, char** argv) {
  CLI::App app{"Newton + direct solver baseline on a scene"};
  std::string scene_path, csv;
  int vertices = 0, frames = 10, from = 1;
  app.add_option("scene", scene_path)->required()->check(CLI::ExistingFile);
  app.add_option("--vertices", vertices, "Override the first cloth's generated vertex count");
  app.add_option("--frames", frames, "Frames to simulate");
  app.add_option("--from", from, "First frame counted in the averages (earlier frames only set up the state)");
  app.add_option("--csv", csv, "Per-step rows to this file");
  CLI11_PARSE(app, argc, argv);
  try {
    Json j = load_json(scene_path);
    if (vertices > 0) j["cloths"][0]["mesh"]["vertices"] = vertices;
    j["frames"] = frames;
    sim::Simulator s(sim::parse_scene(j, scene_path, std::filesystem::path(scene_path).parent_path()));
    Index n = 0;
    for (const auto& c : s.cloths()) n += c->mesh().num_vertices();
    std::ofstream rows;
    if (!csv.empty()) {
      rows.open(csv);
      rows << "frame,iterations,step_ms,solve_ms,rel_grad,status\n";
    }
    long steps = 0, iterations = 0;
    double step_ms = 0.0, solve_ms = 0.0;
    while (s.frame() < frames) {
      for (const auto& st : s.advance_frame()) {
        if (rows.is_open())
          rows << st.frame << ',' << st.report.iterations << ',' << st.wall_ms << ',' << st.report.wall_ms << ','
               << st.report.grad_norm / st.report.initial_grad_norm << ',' << st.report.status << '\n';
        if (st.frame < from) continue;
        ++steps;
        iterations += st.report.iterations;
        step_ms += st.wall_ms;
        solve_ms += st.report.wall_ms;
      }
      std::fprintf(stderr, "frame %d/%d\n", s.frame(), frames);
    }
    // Where an iteration's time goes, on the objective of one more step: Hessian assembly (with projection),
    // CHOLMOD numeric factorization (analysis excluded: it happens once per mesh), and one solve.
    auto& body = *s.cloths()[0];
    const VecX y = body.prepare_step(s.time(), s.scene().step_size());
    linalg::BlockMatrix3 H;
    linalg::CholmodSolver chol;
    body.objective().hessian(y, H, true);
    chol.factorize(H);
    Timer t;
    body.objective().hessian(y, H, true);
    const double assembly_ms = t.ms();
    t.reset();
    chol.factorize(H);
    const double factor_ms = t.ms();
    VecX g, d;
    body.objective().gradient(y, g);
    t.reset();
    chol.solve(g, d);
    const double solve_once_ms = t.ms();
    std::printf("| %s | %d | %s | frames %d-%d | %ld | %.1f | %.0f | %.1f | %.0f / %.0f / %.1f |\n", s.scene().file.c_str(),
                n, s.scene().solver.name.c_str(), from, frames, steps, static_cast<double>(iterations) / std::max(1L, steps),
                step_ms / std::max(1L, steps), solve_ms / std::max(1L, iterations), assembly_ms, factor_ms, solve_once_ms);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
