#pragma once
#include <mgcloth/geometry/rigid_motion.hpp>
#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/attachment.hpp>
#include <mgcloth/physics/contact.hpp>
#include <mgcloth/physics/inertia.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/sim/scene.hpp>

namespace mgcloth::sim {

/// One cloth: its discretization, its per-step objective, and its state.
class ClothBody {
 public:
  /// `projective`: build the Projective Dynamics form of the energy (NonlinearSolver::projective()).
  ClothBody(const ClothSpec& spec, const std::vector<geometry::Obstacle>& obstacles, const physics::ContactParams& contact,
            const Vec3& gravity, bool projective = false);

  const std::string& name() const { return m_name; }
  const mesh::TriMesh& mesh() const { return m_mesh; }
  const mesh::Topology& topology() const { return m_topology; }
  double material_scale() const { return m_material_scale; }
  const VecX& mass() const { return m_mass; }
  const std::vector<Index>& pinned_vertices() const { return m_pin_vertices; }

  VecX& x() { return m_x; }
  VecX& v() { return m_v; }
  const VecX& x() const { return m_x; }
  const VecX& v() const { return m_v; }

  /// Sets the objective of the step from t to t + h: inertial prediction, pin targets and obstacles at t + h.
  /// Returns the predicted positions y = x + h v (the solve's start, made feasible against obstacles).
  VecX prepare_step(double t, double h);
  physics::Objective& objective() { return m_objective; }
  const physics::ObstacleContact* contact() const { return m_contact; }
  /// Contact projection and friction after the solve: x_new is projected, v = (x_new − x)/h then filtered.
  void finish_step(VecX& x_new, double t_next, double h);
  std::vector<Vec3> pin_targets(double t) const;
  /// The cloth's mesh hierarchy (Wang 2018 App. B), built on first use with the pinned vertices kept.
  const hierarchy::TriangleHierarchy& hierarchy(const hierarchy::HierarchyParams& params);

 private:
  std::string m_name;
  mesh::TriMesh m_mesh;
  mesh::Topology m_topology;
  double m_material_scale = 1.0;
  VecX m_mass, m_area, m_x, m_v;
  physics::Objective m_objective{0};
  physics::InertiaTerm* m_inertia = nullptr;
  physics::AttachmentTerm* m_pins = nullptr;
  physics::ObstacleContact* m_contact = nullptr;
  std::vector<Index> m_pin_vertices;
  std::vector<Vec3> m_pin_rest;
  std::vector<size_t> m_pin_spec;  ///< which PinSpec each pinned vertex came from
  std::vector<PinSpec> m_pin_specs;
  std::vector<geometry::PointCurve> m_pin_curves;
  std::unique_ptr<hierarchy::TriangleHierarchy> m_hierarchy;
};

/// The prolongation tables of a hierarchy, finest first (what solvers::Problem carries).
std::vector<const hierarchy::TransferTable*> prolongations(const hierarchy::TriangleHierarchy& h);

/// Lumped (one third of each adjacent triangle) vertex areas in material space.
VecX lumped_vertex_area(const mesh::TriMesh& mesh);

}  // namespace mgcloth::sim
