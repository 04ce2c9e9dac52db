#include "solvers/hanging_fixture.hpp"

#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/attachment.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/inertia.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/solvers/factory.hpp>
#include <mgcloth/solvers/newton.hpp>

#include <gtest/gtest.h>

using namespace mgcloth;
using test::hanging;


TEST(Newton, EnergyDecreasesMonotonically) {
  auto p = hanging(400, 1.0 / 30.0);
  solvers::Newton newton;
  solvers::Problem problem;
  problem.objective = &p->objective;
  VecX x = p->x0;
  solvers::Trace trace;
  solvers::Stop stop;
  stop.rel_grad = 1e-8;
  const auto rep = newton.minimize(problem, x, stop, &trace);
  ASSERT_GE(trace.size(), 2u);
  // Monotone up to the round-off of the energy sum itself (the last steps are taken on the gradient norm).
  for (size_t k = 1; k < trace.size(); ++k)
    EXPECT_LE(trace[k].energy, trace[k - 1].energy + 1e-14 * std::abs(trace[k - 1].energy)) << "iteration " << k;
  EXPECT_LT(trace.back().energy, trace.front().energy);
  EXPECT_TRUE(rep.converged) << rep.status << " after " << rep.iterations << " iterations, relative gradient " << rep.grad_norm / rep.initial_grad_norm;
}

TEST(Newton, HangingClothReachesStaticEquilibrium) {
  // No inertia: the minimizer is the static equilibrium, where gravity, elasticity and pins balance.
  auto p = hanging(225, 0.0);
  solvers::Newton newton;
  solvers::Problem problem;
  problem.objective = &p->objective;
  VecX x = p->x0;
  solvers::Stop stop;
  stop.rel_grad = 1e-8;
  stop.max_iters = 500;
  const auto rep = newton.minimize(problem, x, stop, nullptr);
  EXPECT_TRUE(rep.converged) << rep.status << " after " << rep.iterations << " iterations, relative gradient "
                             << rep.grad_norm / rep.initial_grad_norm;
  VecX g;
  p->objective.gradient(x, g);
  EXPECT_LT(g.norm() / rep.initial_grad_norm, 1e-8);
  // Physically: the cloth sags below its pins, and the free bottom hangs lower than the top.
  EXPECT_LT(x.reshaped(3, x.size() / 3).row(2).minCoeff(), -0.4);
}

TEST(Newton, EveryLinearSolverReachesTheSameMinimizer) {
  // One implicit step of a hanging 2,500-vertex cloth; the iterative linear solvers run inexact Newton (forcing
  // terms), yet every one must land on the direct solver's minimizer.
  auto p = hanging(2500, 1.0 / 30.0);
  const auto h = hierarchy::build_triangle_hierarchy(p->mesh, {});
  ASSERT_GE(h.num_levels(), 3);
  std::vector<const linalg::StencilTable*> tables;
  for (Index l = 0; l + 1 < h.num_levels(); ++l) tables.push_back(&h.prolongation(l));
  solvers::Stop stop;
  stop.rel_grad = 1e-7;
  VecX reference;
  for (const std::string method : {"cholmod", "pcg-mg", "mg", "pcg-amg"}) {
    solvers::NewtonParams params;
    params.linear.method = method;
    solvers::Newton newton(params);
    EXPECT_EQ(newton.needs_hierarchy(), method == "pcg-mg" || method == "mg");
    solvers::Problem problem;
    problem.objective = &p->objective;
    if (newton.needs_hierarchy()) problem.hierarchy = hierarchy::from_prolongations(tables);
    VecX x = p->x0;
    const auto rep = newton.minimize(problem, x, stop, nullptr);
    EXPECT_TRUE(rep.converged) << method << ": " << rep.status;
    EXPECT_GE(newton.linear_iterations(), rep.iterations) << method;
    if (method == "cholmod") reference = x;
    else EXPECT_LT((x - reference).norm(), 1e-6 * reference.norm()) << method;
    std::printf("%-10s: %3d Newton iterations, %5ld linear iterations, %s\n", method.c_str(), rep.iterations,
                newton.linear_iterations(), rep.status.c_str());
  }
}

TEST(Newton, NonFiniteStateIsASolveError) {
  auto p = hanging(100, 1.0 / 30.0);
  solvers::Newton newton;
  solvers::Problem problem;
  problem.objective = &p->objective;
  VecX x = p->x0;
  x[4] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(newton.minimize(problem, x, {}, nullptr), SolveError);
}

TEST(SolverFactory, RejectsUnknownNamesAndParameters) {
  solvers::SolverConfig c;
  c.name = "bogus";
  EXPECT_THROW(solvers::make_solver(c, "s.json", "solver"), InputError);
  c.name = "newton";
  c.params = {{"linear_solvr", "cholmod"}};
  try {
    solvers::make_solver(c, "s.json", "solver.params");
    FAIL() << "unknown parameter accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("solver.params.linear_solvr"), std::string::npos) << e.what();
  }
}

TEST(SolverFactory, MultigridPreconditionedCgDefaultsToAVCycleOfOneSweepEachWay) {
  // bench/RESULTS.md, "Solver defaults": V(1,1) takes 0.71x / 0.87x the time of V(2,2) in newton-mg runs of the
  // shipped drape and hanging scenes; stand-alone `mg` V-cycles keep V(2,2).
  const auto resolved = [](const std::string& name, const Json& params) {
    solvers::SolverConfig c;
    c.name = name;
    c.params = params;
    return solvers::resolved_params(c, "s.json", "solver.params");
  };
  for (const auto& [name, params] : {std::pair<std::string, Json>{"newton-mg", Json::object()},
                                     {"newton", {{"linear_solver", "pcg-mg"}}}}) {
    const Json j = resolved(name, params);
    EXPECT_EQ(j.at("pre_smooth"), 1) << name;
    EXPECT_EQ(j.at("post_smooth"), 1) << name;
  }
  const Json mg = resolved("newton", {{"linear_solver", "mg"}});
  EXPECT_EQ(mg.at("pre_smooth"), 2);
  const Json set = resolved("newton-mg", {{"pre_smooth", 3}, {"post_smooth", 3}});  // a scene's own value wins
  EXPECT_EQ(set.at("pre_smooth"), 3);
  EXPECT_EQ(set.at("post_smooth"), 3);
}
