// fmg-cuda as a solver: its parameters, its message without a GPU, and (through the host backend, which runs the
// device kernels on the CPU) the same minimizer as the CPU FMG and Newton.
#include "solvers/hanging_fixture.hpp"

#include <mgcloth/core/error.hpp>
#include <mgcloth/cuda/device_fmg.hpp>
#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/solvers/factory.hpp>
#include <mgcloth/solvers/newton.hpp>

#include <gtest/gtest.h>

#include <random>

using namespace mgcloth;

namespace {
std::unique_ptr<solvers::NonlinearSolver> make(const Json& params) {
  solvers::SolverConfig c;
  c.name = "fmg-cuda";
  c.params = params;
  return solvers::make_solver(c, "scene.json", "solver.params");
}

/// The cloth's problem with its hierarchy's prolongations (the hierarchy must outlive it).
solvers::Problem problem_of(test::Hanging& cloth, const hierarchy::TriangleHierarchy& h) {
  solvers::Problem problem;
  problem.objective = &cloth.objective;
  problem.hierarchy = h.levels_for_solvers();
  return problem;
}
}  // namespace

TEST(FmgCuda, RejectsBadParametersByName) {
  for (const Json& bad : {Json{{"coarse_solve", "gpu"}}, Json{{"backend", "metal"}}, Json{{"pre_smooth", -1}},
                          Json{{"interleave", true}}, Json{{"matrix_update", "constant"}}}) {
    try {
      make(bad);
      FAIL() << bad.dump() << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("solver.params." + bad.begin().key()), std::string::npos) << e.what();
    }
  }
  solvers::SolverConfig c;
  c.name = "fmg-cuda";
  c.params = {{"backend", "host"}};
  const Json resolved = solvers::resolved_params(c, "scene.json", "solver.params");
  EXPECT_EQ(resolved.at("pre_smooth"), 3);
  EXPECT_EQ(resolved.at("matrix_update"), "cycle");
  EXPECT_EQ(resolved.at("coarse_solve"), "auto");
}

TEST(FmgCuda, WithoutAGpuTheSolverCannotBeMadeAndTheMessageSaysWhy) {
  std::string why;
  if (cuda::cuda_available(&why)) GTEST_SKIP() << "a GPU is present; this checks the message where there is none";
  try {
    make(Json::object());
    FAIL() << "fmg-cuda was made without a GPU";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("fmg-cuda"), std::string::npos) << msg;
    EXPECT_NE(msg.find(why), std::string::npos) << msg;
  }
}

TEST(FmgCuda, TheDevicePipelineReachesTheSameMinimizerAsNewtonAndTheCpuFmg) {
  auto cloth = test::hanging(900, 1.0 / 30.0);
  const hierarchy::TriangleHierarchy h = test::small_hierarchy(*cloth);
  solvers::Problem problem = problem_of(*cloth, h);
  solvers::Stop stop;
  stop.rel_grad = 1e-10;
  stop.max_iters = 400;
  VecX ref = cloth->x0;
  solvers::Newton newton;
  solvers::Problem flat;
  flat.objective = &cloth->objective;
  ASSERT_TRUE(newton.minimize(flat, ref, stop, nullptr).converged);
  for (const std::string coarse : {"device", "host"}) {
    auto solver = make({{"backend", "host"}, {"coarse_solve", coarse}});
    VecX x = cloth->x0;
    solvers::Trace trace;
    const auto rep = solver->minimize(problem, x, stop, &trace);
    EXPECT_TRUE(rep.converged) << rep.status << " after " << rep.iterations;
    EXPECT_LT((x - ref).norm(), 1e-6 * ref.norm()) << coarse;
    ASSERT_GE(trace.size(), 2u);
    // Energies fall, up to the round-off where the line search lets the gradient norm decide (as in "fmg").
    for (size_t k = 1; k < trace.size(); ++k)
      EXPECT_LE(trace[k].energy, trace[k - 1].energy + 1e-12 * std::abs(trace[k - 1].energy)) << "cycle " << k;
    // The paper's configuration converges in a few tens of cycles here, as the CPU FMG does.
    solvers::SolverConfig cpu;
    cpu.name = "fmg";
    auto fmg = solvers::make_solver(cpu, "scene.json", "solver.params");
    VecX y = cloth->x0;
    const auto cpu_rep = fmg->minimize(problem, y, stop, nullptr);
    EXPECT_LE(rep.iterations, 2 * cpu_rep.iterations + 5) << "device " << rep.iterations << ", CPU " << cpu_rep.iterations;
    double total = 0.0;
    for (const auto& [key, value] : rep.counters)
      if (key == "directions") total = value;
    EXPECT_GE(total, rep.iterations);
  }
}

TEST(FmgCuda, WhenTheModelStepFailsEverywhereASteepestDescentStepMovesAndTheSolveConverges) {
  // A crumpled start, and a line search allowed only the model step (max_line_search_steps 1): where the model
  // overshoots, every direction fails, also after a fresh matrix, far above the round-off floor. The fallback steps
  // carry the solve on to its target; it used to end at the first such cycle, "stalled" after 12 cycles at a
  // relative gradient of 4.9e-5 (above 1e-3 of the start's gradient it would have thrown "no search direction
  // decreased the energy").
  auto cloth = test::hanging(400, 1.0 / 30.0);
  const hierarchy::TriangleHierarchy h = test::small_hierarchy(*cloth);
  solvers::Problem problem = problem_of(*cloth, h);
  VecX x = cloth->x0;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.003, 0.003);
  for (Index i = 0; i < x.size(); ++i) x[i] += u(rng);
  const double e0 = cloth->objective.value(x);
  solvers::Stop stop;
  stop.rel_grad = 1e-5;
  stop.max_iters = 100;
  auto solver = make({{"backend", "host"}, {"max_line_search_steps", 1}});
  solvers::SolveReport rep;
  ASSERT_NO_THROW(rep = solver->minimize(problem, x, stop, nullptr));
  EXPECT_EQ(rep.status, "converged") << "after " << rep.iterations << ", relative |g| "
                                     << rep.grad_norm / rep.initial_grad_norm;
  double fallbacks = 0.0;
  for (const auto& [key, value] : rep.counters)
    if (key == "fallbacks") fallbacks = value;
  EXPECT_GT(fallbacks, 0.0) << "no fallback step was needed: the case no longer tests them";
  EXPECT_LT(cloth->objective.value(x), e0);
}
