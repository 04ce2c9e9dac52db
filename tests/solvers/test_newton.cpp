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

namespace {
struct Hanging {
  mesh::TriMesh mesh;
  mesh::Topology topo;
  physics::Objective objective{0};
  VecX x0;
};

/// A 0.4 m square hanging from its two top corners: gravity, StVK, hinge bending, pins; static when `h` is 0.
std::unique_ptr<Hanging> hanging(Index vertices, double h) {
  auto p = std::make_unique<Hanging>();
  mesh::RectangleSpec spec;
  spec.width = spec.height = 0.4;
  spec.target_vertices = vertices;
  p->mesh = mesh::make_rectangle(spec);
  p->topo = mesh::build_topology(p->mesh);
  physics::Material mat;
  const Index n = p->mesh.num_vertices();
  VecX mass = VecX::Zero(n);
  for (Index t = 0; t < p->mesh.num_triangles(); ++t)
    for (Index v : p->mesh.tris[t]) mass[v] += p->mesh.material_area(t) / 3.0 * mat.areal_density();
  // The cloth hangs in the x-z plane: u along x, v along −z.
  p->x0.resize(3 * n);
  for (Index i = 0; i < n; ++i) p->x0.segment<3>(3 * i) = Vec3(p->mesh.u(0, i), 0.0, -p->mesh.u(1, i));
  p->objective = physics::Objective(n);
  if (h > 0) {
    auto& inertia = p->objective.add(std::make_unique<physics::InertiaTerm>(mass));
    inertia.set_prediction(p->x0, h);
  }
  p->objective.add(std::make_unique<physics::GravityTerm>(mass, Vec3(0, 0, -9.81)));
  p->objective.add(std::make_unique<physics::StVKMembrane>(p->mesh, mat));
  p->objective.add(std::make_unique<physics::HingeBending>(p->mesh, p->topo, mat));
  Index a = 0, b = 0;
  (p->mesh.u.colwise() - Vec2(0, 0)).colwise().squaredNorm().minCoeff(&a);
  (p->mesh.u.colwise() - Vec2(0.4, 0)).colwise().squaredNorm().minCoeff(&b);
  auto& pins = p->objective.add(std::make_unique<physics::AttachmentTerm>(std::vector<Index>{a, b}, std::vector<double>{1e4, 1e4}, n));
  pins.set_targets({p->x0.segment<3>(3 * a), p->x0.segment<3>(3 * b)});
  p->objective.finalize();
  return p;
}
}  // namespace

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
  std::vector<const hierarchy::TransferTable*> tables;
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
    if (newton.needs_hierarchy()) problem.prolongations = tables;
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
