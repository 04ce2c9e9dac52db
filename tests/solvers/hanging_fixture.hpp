#pragma once
// A small hanging-cloth objective shared by the solver tests.
#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/attachment.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/inertia.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/objective.hpp>

#include <memory>

namespace mgcloth::test {
struct Hanging {
  mesh::TriMesh mesh;
  mesh::Topology topo;
  physics::Objective objective{0};
  VecX x0;
  std::vector<Index> pins;  ///< the two pinned corners
};

/// A 0.4 m square hanging from its two top corners: gravity, StVK, bending (the hinge unless said), pins; static
/// when `h` is 0.
inline std::unique_ptr<Hanging> hanging(Index vertices, double h, physics::BendingModel bending = physics::BendingModel::Hinge) {
  auto p = std::make_unique<Hanging>();
  mesh::RectangleSpec spec;
  spec.width = spec.height = 0.4;
  spec.target_vertices = vertices;
  p->mesh = mesh::make_rectangle(spec);
  p->topo = mesh::build_topology(p->mesh);
  physics::Material mat;
  mat.bending = bending;
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
  p->objective.add(physics::make_bending(p->mesh, p->topo, mat, /*projective=*/false));
  Index a = 0, b = 0;
  (p->mesh.u.colwise() - Vec2(0, 0)).colwise().squaredNorm().minCoeff(&a);
  (p->mesh.u.colwise() - Vec2(0.4, 0)).colwise().squaredNorm().minCoeff(&b);
  auto& pins = p->objective.add(std::make_unique<physics::AttachmentTerm>(std::vector<Index>{a, b}, std::vector<double>{1e4, 1e4}, n));
  pins.set_targets({p->x0.segment<3>(3 * a), p->x0.segment<3>(3 * b)});
  p->pins = {a, b};
  p->objective.finalize();
  return p;
}

/// The cloth's multigrid hierarchy, pins kept on every level, coarsest level of 30-60 vertices.
inline hierarchy::TriangleHierarchy small_hierarchy(const Hanging& cloth) {
  hierarchy::HierarchyParams hp;
  hp.keep = cloth.pins;
  hp.max_coarse_vertices = 60;
  hp.min_coarse_vertices = 30;
  return hierarchy::build_triangle_hierarchy(cloth.mesh, hp);
}
}  // namespace mgcloth::test
