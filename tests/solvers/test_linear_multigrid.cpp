#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/linalg/block_jacobi.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/linalg/pcg.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/inertia.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/solvers/linear_multigrid.hpp>

#include <gtest/gtest.h>

using namespace mgcloth;

namespace {
/// The projected Hessian of one cloth step (inertia at Δt = 1/30 s, StVK, hinge bending) at a stretched, curved
/// state of a 1 m unstructured sheet, with its mesh hierarchy.
struct System {
  mesh::TriMesh mesh;
  mesh::Topology topo;
  physics::Objective objective{0};
  linalg::BlockMatrix3 H;
  hierarchy::TriangleHierarchy hierarchy;
};

std::unique_ptr<System> cloth_system(Index vertices) {
  auto s = std::make_unique<System>();
  mesh::RectangleSpec spec;
  spec.target_vertices = vertices;
  spec.unstructured = true;
  s->mesh = mesh::make_rectangle(spec);
  s->topo = mesh::build_topology(s->mesh);
  const Index n = s->mesh.num_vertices();
  physics::Material mat;
  VecX mass = VecX::Zero(n);
  for (Index t = 0; t < s->mesh.num_triangles(); ++t)
    for (Index v : s->mesh.tris[t]) mass[v] += s->mesh.material_area(t) / 3.0 * mat.areal_density();
  VecX x(3 * n);
  for (Index i = 0; i < n; ++i) {
    const Vec2 u = s->mesh.u.col(i);
    x.segment<3>(3 * i) = Vec3(1.05 * u.x(), u.y(), 0.1 * std::sin(3.0 * u.x()));
  }
  s->objective = physics::Objective(n);
  auto& inertia = s->objective.add(std::make_unique<physics::InertiaTerm>(mass));
  inertia.set_prediction(x, 1.0 / 30.0);
  s->objective.add(std::make_unique<physics::StVKMembrane>(s->mesh, mat));
  s->objective.add(std::make_unique<physics::HingeBending>(s->mesh, s->topo, mat));
  s->objective.finalize();
  s->objective.hessian(x, s->H, true);
  s->hierarchy = hierarchy::build_triangle_hierarchy(s->mesh, {});
  return s;
}

std::vector<const linalg::StencilTable*> tables(const hierarchy::TriangleHierarchy& h) {
  std::vector<const linalg::StencilTable*> p;
  for (Index l = 0; l + 1 < h.num_levels(); ++l) p.push_back(&h.prolongation(l));
  return p;
}
}  // namespace

TEST(LinearMultigrid, VCycleConvergesAndMatchesDirectSolve) {
  auto s = cloth_system(2500);
  ASSERT_GE(s->hierarchy.num_levels(), 3);
  solvers::LinearMultigrid mg(tables(s->hierarchy), s->H);
  mg.set_matrix(s->H);
  const VecX b = VecX::Random(s->H.rows() * 3);
  VecX x = VecX::Zero(b.size());
  double previous = b.norm();
  for (int k = 0; k < 8; ++k) {
    mg.vcycle(b, x);
    const double r = (b - s->H * x).norm();
    EXPECT_LT(r, 0.6 * previous) << "cycle " << k;
    previous = r;
  }
  linalg::CholmodSolver chol;
  ASSERT_TRUE(chol.factorize(s->H));
  VecX exact;
  chol.solve(b, exact);
  EXPECT_LT((x - exact).norm(), 1e-2 * exact.norm());
}

TEST(LinearMultigrid, IsASymmetricPreconditionerThatBeatsBlockJacobi) {
  auto s = cloth_system(2500);
  solvers::LinearMultigrid mg(tables(s->hierarchy), s->H);
  mg.set_matrix(s->H);
  const VecX r1 = VecX::Random(3 * s->H.rows()), r2 = VecX::Random(3 * s->H.rows());
  VecX z1, z2;
  mg.precondition(r1, z1);
  mg.precondition(r2, z2);
  EXPECT_NEAR(r2.dot(z1), r1.dot(z2), 1e-9 * std::abs(r1.dot(z2)) + 1e-14);
  EXPECT_GT(r1.dot(z1), 0.0);

  const VecX b = VecX::Random(3 * s->H.rows());
  VecX x_mg = VecX::Zero(b.size()), x_cg = VecX::Zero(b.size());
  const int it_mg = linalg::pcg(s->H, b, x_mg, [&](const VecX& r, VecX& z) { mg.precondition(r, z); }, 1e-8, 500);
  const linalg::BlockJacobi jacobi(s->H);
  const int it_cg = linalg::pcg(s->H, b, x_cg, [&](const VecX& r, VecX& z) { jacobi.apply(r, z); }, 1e-8, 1000);
  EXPECT_LE((b - s->H * x_mg).norm(), 1e-8 * b.norm());
  EXPECT_LT(it_mg, 40);
  EXPECT_LT(4 * it_mg, it_cg) << "multigrid-PCG " << it_mg << ", block-Jacobi PCG " << it_cg;
}

TEST(LinearMultigrid, ContractionIsSmallAndMeshIndependent) {
  double rho[2];
  const Index sizes[2] = {5000, 40000};
  for (int i = 0; i < 2; ++i) {
    auto s = cloth_system(sizes[i]);
    solvers::LinearMultigrid mg(tables(s->hierarchy), s->H);
    mg.set_matrix(s->H);
    std::srand(11);  // Eigen's Random
    rho[i] = mg.contraction(VecX::Random(3 * s->H.rows()));
    std::printf("%d vertices, %d levels: V(2,2) contraction %.3f\n", s->mesh.num_vertices(), mg.num_levels(), rho[i]);
    EXPECT_LT(rho[i], 0.3) << sizes[i] << " vertices";
  }
  EXPECT_LT(rho[1], 1.5 * rho[0]);
}

TEST(LinearMultigrid, FullMultigridIsAccurateAfterOneCycle) {
  auto s = cloth_system(5000);
  solvers::LinearMultigrid mg(tables(s->hierarchy), s->H);
  mg.set_matrix(s->H);
  // A smooth solution (a cloth displacement field), where FMG's coarse-to-fine start pays off.
  VecX exact(3 * s->H.rows());
  for (Index i = 0; i < s->H.rows(); ++i) {
    const Vec2 u = s->mesh.u.col(i);
    exact.segment<3>(3 * i) = Vec3(std::sin(3.0 * u.x()), u.x() * u.y(), std::cos(2.0 * u.y()));
  }
  const VecX b = s->H * exact;
  VecX x_fmg, x_v = VecX::Zero(b.size());
  mg.fmg(b, x_fmg);
  mg.vcycle(b, x_v);
  const auto energy_error = [&](const VecX& x) { return std::sqrt((x - exact).dot(s->H * (x - exact))); };
  const double e0 = energy_error(VecX::Zero(b.size())), e_fmg = energy_error(x_fmg), e_v = energy_error(x_v);
  std::printf("energy-norm error: FMG %.3e, V-cycle %.3e (start %.3e)\n", e_fmg / e0, e_v / e0, 1.0);
  // FMG starts every level from the coarser level's solution, so one pass beats a V-cycle from zero.
  EXPECT_LT(e_fmg, 0.5 * e_v);
  EXPECT_LT(e_fmg, 0.05 * e0);
}

TEST(LinearMultigrid, ChebyshevSmoothingKeepsThePreconditionerSymmetric) {
  auto s = cloth_system(2500);
  solvers::MultigridParams p;
  p.chebyshev = true;
  solvers::LinearMultigrid mg(tables(s->hierarchy), s->H, p);
  mg.set_matrix(s->H);
  EXPECT_GT(mg.smoother_rho(0), 0.5);
  EXPECT_LT(mg.smoother_rho(0), 1.0);
  const VecX r1 = VecX::Random(3 * s->H.rows()), r2 = VecX::Random(3 * s->H.rows());
  VecX z1, z2;
  mg.precondition(r1, z1);
  mg.precondition(r2, z2);
  EXPECT_NEAR(r2.dot(z1), r1.dot(z2), 1e-9 * std::abs(r1.dot(z2)));
  VecX x = VecX::Zero(r1.size());
  const int it = linalg::pcg(s->H, r1, x, [&](const VecX& r, VecX& z) { mg.precondition(r, z); }, 1e-8, 200);
  EXPECT_LT(it, 40);
}
