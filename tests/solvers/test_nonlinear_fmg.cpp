#include "solvers/hanging_fixture.hpp"

#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>
#include <mgcloth/solvers/factory.hpp>
#include <mgcloth/solvers/newton.hpp>
#include <mgcloth/solvers/nonlinear_fmg.hpp>

#include <gtest/gtest.h>

using namespace mgcloth;
using test::hanging;

namespace {

/// One implicit step of the hanging cloth with its hierarchy (pins kept on every level).
struct Step {
  std::unique_ptr<test::Hanging> cloth;
  hierarchy::TriangleHierarchy h;
  std::vector<const linalg::StencilTable*> tables;
};

Step make_step(Index vertices) {
  Step s;
  s.cloth = hanging(vertices, 1.0 / 30.0);
  s.h = test::small_hierarchy(*s.cloth);
  for (Index l = 0; l + 1 < s.h.num_levels(); ++l) s.tables.push_back(&s.h.prolongation(l));
  return s;
}

VecX reference_minimizer(const Step& s) {
  solvers::Newton newton;
  solvers::Problem problem;
  problem.objective = &s.cloth->objective;
  VecX x = s.cloth->x0;
  solvers::Stop stop;
  stop.rel_grad = 1e-11;
  newton.minimize(problem, x, stop, nullptr);
  return x;
}

solvers::SolveReport run(solvers::NonlinearSolver& solver, const Step& s, VecX& x, double rel_grad, int max_iters,
                         solvers::Trace* trace = nullptr) {
  solvers::Problem problem;
  problem.objective = &s.cloth->objective;
  if (solver.needs_hierarchy()) problem.hierarchy = hierarchy::from_prolongations(s.tables);
  x = s.cloth->x0;
  solvers::Stop stop;
  stop.rel_grad = rel_grad;
  stop.max_iters = max_iters;
  return solver.minimize(problem, x, stop, trace);
}

std::unique_ptr<solvers::NonlinearSolver> by_name(const std::string& name, const Json& params = Json::object()) {
  solvers::SolverConfig c;
  c.name = name;
  c.params = params;
  return solvers::make_solver(c, "test", "solver.params");
}

}  // namespace

TEST(NonlinearFmg, ScheduleInterleavesSmallAndLargeVCycles) {
  // With 3 levels and the nonlinear residual on the 2 finest, an FMG cycle is: coarse solve; V-cycle from level 1
  // (smooth 1, coarse, smooth 1); V-cycle from level 0 (smooth 0, smooth 1, coarse, smooth 1, smooth 0) — 9
  // directions. Counted through the solver's statistics on a 3-level hierarchy.
  auto s = make_step(900);
  ASSERT_EQ(s.h.num_levels(), 3);
  solvers::FmgParams p;
  p.interleave = true;
  p.residual_levels = 2;
  solvers::NonlinearFMG fmg(p);
  VecX x;
  run(fmg, s, x, 0.0, 1);
  EXPECT_EQ(fmg.stats().cycles, 1);
  EXPECT_EQ(fmg.stats().directions, 9);
  p.residual_levels = 0;  // every V-cycle one linear direction: one per level
  solvers::NonlinearFMG linear(p);
  run(linear, s, x, 0.0, 1);
  EXPECT_EQ(linear.stats().directions, 3);
  // Not interleaved (the default): only the V-cycle from the finest level, 5 directions with the nonlinear residual
  // on the 2 finest levels (smooth 0, smooth 1, coarse, smooth 1, smooth 0), 1 without.
  p.interleave = false;
  solvers::NonlinearFMG plain(p);
  run(plain, s, x, 0.0, 1);
  EXPECT_EQ(plain.stats().directions, 1);
  p.residual_levels = 2;
  solvers::NonlinearFMG plain_nonlinear(p);
  run(plain_nonlinear, s, x, 0.0, 1);
  EXPECT_EQ(plain_nonlinear.stats().directions, 5);
}

TEST(NonlinearFmg, EverySolverReachesNewtonsMinimizer) {
  auto s = make_step(900);
  ASSERT_GE(s.h.num_levels(), 3);
  const VecX xstar = reference_minimizer(s);
  struct Case {
    std::string name;
    Json params;
    int max_iters;
  };
  const std::vector<Case> cases = {
      {"fmg", Json::object(), 200},
      {"fmg", {{"momentum", false}}, 400},
      {"fmg", {{"interleave", true}}, 200},
      {"fmg", {{"residual_levels", 0}}, 400},
      {"fmg", {{"residual_levels", 10}, {"matrix_update", "step"}}, 1000},
      {"fmg", {{"matrix_update", "direction"}}, 200},
      {"fmg", {{"smoother_precision", "single"}}, 200},
      {"fmg", {{"chebyshev_smoothing", true}, {"adaptive_threshold", 0.2}}, 400},
      {"newton-direct", Json::object(), 100},
      {"newton-amg", Json::object(), 100},
      {"newton-mg", Json::object(), 100},
  };
  for (const auto& c : cases) {
    auto solver = by_name(c.name, c.params);
    VecX x;
    const auto rep = run(*solver, s, x, 1e-10, c.max_iters);
    EXPECT_LT((x - xstar).norm(), 1e-6 * xstar.norm()) << c.name << " " << c.params.dump() << ": " << rep.status;
    std::printf("%-14s %-60s %4d iterations, %s\n", c.name.c_str(), c.params.dump().c_str(), rep.iterations, rep.status.c_str());
  }
}

TEST(NonlinearFmg, GaussSeidelChebyshevReachesNewtonsMinimizer) {
  // Without multigrid, the smooth error of even a small cloth takes thousands of sweeps: the reason for FMG.
  auto s = make_step(100);
  const VecX xstar = reference_minimizer(s);
  auto gs = by_name("gs-chebyshev");
  EXPECT_FALSE(gs->needs_hierarchy());
  VecX x;
  const auto rep = run(*gs, s, x, 1e-10, 20000);
  EXPECT_LT((x - xstar).norm(), 1e-6 * xstar.norm()) << rep.status << " after " << rep.iterations;
}

TEST(NonlinearFmg, EnergyNeverIncreasesAcrossLineSearchSteps) {
  auto s = make_step(900);
  for (const Json& params : {Json::object(), Json{{"momentum", false}}, Json{{"matrix_update", "step"}}}) {
    auto fmg = by_name("fmg", params);
    VecX x;
    solvers::Trace trace;
    run(*fmg, s, x, 1e-9, 100, &trace);
    ASSERT_GE(trace.size(), 3u);
    for (size_t k = 1; k < trace.size(); ++k)
      EXPECT_LE(trace[k].energy, trace[k - 1].energy + 1e-14 * std::abs(trace[k - 1].energy))
          << params.dump() << " cycle " << k;
  }
}

TEST(NonlinearFmg, AdaptiveSmootherWithThresholdZeroIsThePlainSmoother) {
  // A threshold that masks nothing goes through the masked code path; it must reproduce the unmasked solve bit for
  // bit. A real threshold skips rows and still converges.
  auto s = make_step(900);
  solvers::FmgParams plain;
  solvers::FmgParams masked;
  masked.adaptive_threshold = 1e-300;
  solvers::NonlinearFMG a(plain), b(masked);
  VecX xa, xb;
  run(a, s, xa, 0.0, 3);
  run(b, s, xb, 0.0, 3);
  EXPECT_EQ(b.stats().rows_skipped, 0.0);
  EXPECT_GT(b.stats().rows_relaxed, 0.0);
  EXPECT_TRUE(xa == xb) << "max difference " << (xa - xb).cwiseAbs().maxCoeff();

  solvers::FmgParams adaptive;
  adaptive.adaptive_threshold = 0.5;
  solvers::NonlinearFMG c(adaptive);
  VecX xc;
  const auto rep = run(c, s, xc, 1e-10, 300);
  const VecX xstar = reference_minimizer(s);
  EXPECT_LT((xc - xstar).norm(), 1e-6 * xstar.norm()) << rep.status;
  EXPECT_GT(c.stats().rows_skipped, 0.0);
  std::printf("adaptive threshold 0.5: %.1f%% of row relaxations skipped, %d cycles\n",
              100.0 * c.stats().rows_skipped / (c.stats().rows_skipped + c.stats().rows_relaxed), rep.iterations);
}

TEST(NonlinearFmg, MaskedSweepsWithAllRowsActiveEqualPlainSweeps) {
  auto s = make_step(400);
  linalg::BlockMatrix3 H;
  s.cloth->objective.hessian(s.cloth->x0, H, true);
  linalg::MultiColorGaussSeidel gs(H);
  gs.set_matrix(H);
  VecX g;
  s.cloth->objective.gradient(s.cloth->x0, g);
  std::vector<char> mask;
  EXPECT_EQ(linalg::adaptive_mask(g, 0.0, mask), H.rows());
  VecX a = VecX::Zero(g.size()), b = a;
  gs.symmetric_sweeps(-g, a, 3);
  gs.symmetric_sweeps(-g, b, 3, &mask);
  EXPECT_TRUE(a == b);
}

TEST(NonlinearFmg, ConstantMatrixIsFactoredOnceAcrossSolves) {
  // Projective Dynamics' prefactored matrix: with an objective whose Hessian does not depend on x (inertia,
  // gravity, quadratic bending, pins), the first solve sets the matrix up once and a later solve (another step:
  // a new inertial prediction) reuses it.
  auto s = make_step(400);
  const Index n = s.cloth->mesh.num_vertices();
  const VecX mass = VecX::Constant(n, 1e-4);
  physics::Objective quadratic(n);
  auto& inertia = quadratic.add(std::make_unique<physics::InertiaTerm>(mass));
  quadratic.add(std::make_unique<physics::GravityTerm>(mass, Vec3(0, 0, -9.81)));
  quadratic.add(std::make_unique<physics::QuadraticBending>(s.cloth->mesh, s.cloth->topo, physics::Material{}));
  auto& pins = quadratic.add(std::make_unique<physics::AttachmentTerm>(s.cloth->pins, std::vector<double>{1e4, 1e4}, n));
  pins.set_targets({s.cloth->x0.segment<3>(3 * s.cloth->pins[0]), s.cloth->x0.segment<3>(3 * s.cloth->pins[1])});
  quadratic.finalize();
  solvers::FmgParams p;
  p.matrix_update = solvers::MatrixUpdate::Constant;
  solvers::NonlinearFMG fmg(p);
  solvers::Problem problem;
  problem.objective = &quadratic;
  problem.hierarchy = hierarchy::from_prolongations(s.tables);
  solvers::Stop stop;
  stop.rel_grad = 1e-8;
  for (int step = 0; step < 2; ++step) {
    inertia.set_prediction(s.cloth->x0 + VecX::Constant(3 * n, 0.01 * step), 1.0 / 30.0);
    VecX x = s.cloth->x0;
    const auto rep = fmg.minimize(problem, x, stop, nullptr);
    EXPECT_TRUE(rep.converged) << rep.status;
    EXPECT_EQ(fmg.stats().matrix_updates, step == 0 ? 1 : 0) << "step " << step;
  }
}

TEST(NonlinearFmg, FactoryNamesAndParameters) {
  for (const auto& name : solvers::solver_names()) {
    // fmg-cuda on its host backend: the CUDA one is refused where there is no GPU (FmgCuda.* tests).
    auto s = name == "fmg-cuda" ? by_name(name, {{"backend", "host"}}) : by_name(name);
    EXPECT_EQ(s->name(), name);
    // The PD presets need the PD form's constant matrix; the device pipeline has kernels for the elastic terms.
    EXPECT_EQ(s->can_minimize(physics::EnergyForm::Elastic), !name.starts_with("pd-")) << name;
    EXPECT_EQ(s->can_minimize(physics::EnergyForm::Projective), name != "fmg-cuda") << name;
    EXPECT_EQ(s->energy_forms().front() == physics::EnergyForm::Projective, name.starts_with("pd-")) << name;
  }
  EXPECT_TRUE(by_name("fmg")->needs_hierarchy());
  EXPECT_FALSE(by_name("newton-direct")->needs_hierarchy());
  EXPECT_TRUE(by_name("fas")->needs_level_objectives());
  EXPECT_THROW(by_name("fmg", {{"matrix_update", "sometimes"}}), InputError);
  EXPECT_THROW(by_name("fmg", {{"residual_levels", -1}}), InputError);
  EXPECT_THROW(by_name("gs-chebyshev", {{"pre_smooth", 2}}), InputError);  // single level: "sweeps"
  EXPECT_THROW(by_name("fmg", {{"chebyshev_rho", 1.0}}), InputError);
  EXPECT_THROW(by_name("fmg", {{"smoother_precision", "half"}}), InputError);
}

TEST(NonlinearFmg, SinglePrecisionSmootherLeavesTheMinimizerUnchanged) {
  // Float blocks change only the V-cycle's operator; gradients, energies and line searches stay double, so a solve
  // to a tight tolerance lands on the same minimizer, with the same energy to far below 1e-6 relative.
  auto s = make_step(900);
  const VecX xstar = reference_minimizer(s);
  const double estar = s.cloth->objective.value(xstar);
  for (const char* precision : {"double", "single"}) {
    auto solver = by_name("fmg", {{"smoother_precision", precision}});
    VecX x;
    const auto rep = run(*solver, s, x, 1e-10, 200);
    EXPECT_EQ(rep.status, "converged") << precision;
    EXPECT_LT((x - xstar).norm(), 1e-7 * xstar.norm()) << precision;
    EXPECT_LE(std::abs(s.cloth->objective.value(x) - estar), 1e-10 * std::abs(estar)) << precision;
  }
}

TEST(NonlinearFmg, AClothAtRestIsNotAnErrorForAnySolver) {
  // The cloth hangs at rest: the step's prediction is its static equilibrium, so the gradient at the start is
  // round-off, and rel_grad 1e-7 of it is out of reach. Every solver must end converged or stagnated there, not
  // throw (fmg used to: "no search direction decreased the energy in cycle 1 (relative 1.0)").
  auto s = make_step(400);
  VecX rest;
  {
    auto statics = hanging(400, 0.0);
    solvers::Newton newton;
    solvers::Problem problem;
    problem.objective = &statics->objective;
    rest = statics->x0;
    solvers::Stop stop;
    stop.rel_grad = 1e-13;
    stop.max_iters = 500;
    newton.minimize(problem, rest, stop, nullptr);
  }
  for (const auto& term : s.cloth->objective.terms())
    if (auto* inertia = dynamic_cast<physics::InertiaTerm*>(term.get())) inertia->set_prediction(rest, 1.0 / 30.0);
  s.cloth->x0 = rest;
  VecX g;
  s.cloth->objective.gradient(rest, g);
  const double floor = physics::gradient_roundoff(s.cloth->objective, rest, 4).back().change_max;
  ASSERT_LT(g.norm(), 100 * floor) << "the start is not at rest";
  // fmg-cuda through the host backend, which runs the device pipeline's kernels on the CPU.
  const std::vector<std::pair<std::string, Json>> cases = {
      {"fmg", Json::object()}, {"newton-direct", Json::object()}, {"newton-mg", Json::object()},
      {"fmg-cuda", {{"backend", "host"}}}};
  for (const auto& [name, params] : cases) {
    auto solver = by_name(name, params);
    VecX x;
    solvers::SolveReport rep;
    ASSERT_NO_THROW(rep = run(*solver, s, x, 1e-7, 50)) << name;
    EXPECT_TRUE(rep.status == "converged" || rep.status == "stagnated") << name << ": " << rep.status;
    EXPECT_LT((x - rest).norm(), 1e-9 * rest.norm()) << name;
  }
}
