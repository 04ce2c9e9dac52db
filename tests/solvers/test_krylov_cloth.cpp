// The Krylov baselines of linalg (PCG with block-Jacobi or BoomerAMG) on a real projected cloth Hessian; here
// because building one needs the mesh and physics modules, which the linalg tests may not link.
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

#include <gtest/gtest.h>

using namespace mgcloth;

namespace {
/// The projected Hessian of one cloth step (inertia at Δt = 1/30 s, StVK, hinge bending) at a stretched, curved
/// state of a 1 m unstructured sheet, and the Newton right-hand side −g there.
struct System {
  linalg::BlockMatrix3 H;
  VecX b;
};

System cloth_hessian(Index vertices) {
  mesh::RectangleSpec spec;
  spec.target_vertices = vertices;
  spec.unstructured = true;
  const mesh::TriMesh m = mesh::make_rectangle(spec);
  const mesh::Topology topo = mesh::build_topology(m);
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
  physics::Objective objective(n);
  auto& inertia = objective.add(std::make_unique<physics::InertiaTerm>(mass));
  inertia.set_prediction(x, 1.0 / 30.0);
  objective.add(std::make_unique<physics::StVKMembrane>(m, mat));
  objective.add(std::make_unique<physics::HingeBending>(m, topo, mat));
  objective.finalize();
  System s;
  objective.hessian(x, s.H, true);
  objective.gradient(x, s.b);
  s.b = -s.b;
  return s;
}
}  // namespace

TEST(KrylovBaselines, BlockJacobiAndBoomerAmgPcgMatchCholmodOnAClothHessian) {
  const System s = cloth_hessian(1600);
  linalg::CholmodSolver chol;
  ASSERT_TRUE(chol.factorize(s.H));
  VecX exact;
  chol.solve(s.b, exact);

  linalg::BlockJacobi jacobi(s.H);
  linalg::HypreAmg amg;
  amg.set_matrix(s.H);
  VecX x_jacobi = VecX::Zero(s.b.size()), x_amg = VecX::Zero(s.b.size());
  const int it_jacobi =
      linalg::pcg(s.H, s.b, x_jacobi, [&](const VecX& r, VecX& z) { jacobi.apply(r, z); }, 1e-8, 5000);
  const int it_amg = linalg::pcg(s.H, s.b, x_amg, [&](const VecX& r, VecX& z) { amg.apply(r, z); }, 1e-8, 500);
  for (const VecX* x : {&x_jacobi, &x_amg}) {
    EXPECT_LE((s.b - s.H * *x).norm(), 1e-8 * s.b.norm());
    EXPECT_LT((*x - exact).norm(), 1e-6 * exact.norm());
  }
  EXPECT_LT(it_amg, 40);
  EXPECT_LT(5 * it_amg, it_jacobi) << "BoomerAMG-PCG " << it_amg << ", block-Jacobi PCG " << it_jacobi;
}
