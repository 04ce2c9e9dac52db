#pragma once
#include <mgcloth/geometry/rigid_motion.hpp>
#include <mgcloth/hierarchy/reverse_subdivision.hpp>
#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/attachment.hpp>
#include <mgcloth/physics/contact.hpp>
#include <mgcloth/physics/inertia.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/physics/projective.hpp>
#include <mgcloth/bodies/body.hpp>
#include <mgcloth/bodies/cloth_spec.hpp>
#include <mgcloth/geometry/obstacle.hpp>
#include <mgcloth/physics/energy_form.hpp>

namespace mgcloth::bodies {

/// What a cloth's step depends on besides its own spec: the scene's obstacles, contact, gravity, energy form and
/// hierarchy settings.
struct ClothEnvironment {
  std::vector<geometry::Obstacle> obstacles;
  physics::ContactParams contact;
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);
  /// Projective: the Projective Dynamics form of the energy (PD strain membrane, quadratic bending unless the
  /// material has none, PD contact) instead of the elastic membrane, the material's bending model and the cubic
  /// contact penalty (physics/projective.hpp).
  physics::EnergyForm energy_form = physics::EnergyForm::Elastic;
  hierarchy::HierarchyParams hierarchy;  ///< the pinned vertices are added to its `keep`
};

/// One cloth: its discretization, its per-step objective (and, for solvers that rediscretize, the same objective on
/// each coarse level of its hierarchy), and its state.
class ClothBody final : public Body {
 public:
  /// `mesh`: the cloth's mesh given in memory by a program (the Python module's arrays), used instead of the spec's
  /// file or generator; it is validated (mesh::validate) like a mesh read from a file.
  ClothBody(const ClothSpec& spec, const ClothEnvironment& environment, const mesh::TriMesh* mesh = nullptr);

  const std::string& name() const override { return m_name; }
  std::string kind() const override { return "cloth"; }
  std::string size_text() const override;
  const mesh::TriMesh& mesh() const { return m_mesh; }
  const mesh::Topology& topology() const { return m_topology; }
  double material_scale() const { return m_material_scale; }
  const VecX& mass() const { return m_mass; }
  const std::vector<Index>& pinned_vertices() const { return m_pin_vertices; }
  bool projective() const { return m_projective; }

  VecX& x() override { return m_x; }
  VecX& v() override { return m_v; }
  const VecX& x() const override { return m_x; }
  const VecX& v() const override { return m_v; }

  /// Sets the objective of the step from t to t + h (and the coarse levels' objectives, once built): inertial
  /// prediction, pin targets, obstacles at t + h and, in the PD form, the contact active sets.
  /// Returns the predicted positions y = x + h v (the solve's start, made feasible against obstacles).
  VecX prepare_step(double t, double h);
  VecX prepare_step(const StepTime& step) override { return prepare_step(step.t, step.h); }
  physics::Objective& objective() override { return *m_levels[0].objective; }
  /// The obstacle penalty (cubic, or PD in the projective form); null without obstacles.
  const physics::ObstaclePenalty* contact() const { return m_levels[0].contact; }
  /// Contact projection and friction after the solve (the obstacles at the step's end, placed by prepare_step):
  /// x_new is projected, v = (x_new − x)/h then filtered.
  void finish_step(VecX& x_new, double h) override;
  /// The step's end computed elsewhere (a device solver's NonlinearSolver::finish_step): the new state as it is.
  void accept_step(const VecX& x_new, const VecX& v_new) override;
  /// Projection out of the obstacles at the step's end (placed by prepare_step); empty without obstacles.
  std::function<Index(VecX&)> feasibility_projection() const override;
  std::optional<physics::ContactSurface> contact_surface(double thickness) const override;
  void set_obstacle_projection(bool on) override { m_project_obstacles = on; }
  /// Where the pins pull at time t: the scene's pin motion, or the targets a program set (set_pin_targets).
  std::vector<Vec3> pin_targets(double t) const;
  /// Scripted pin targets (pinned_vertices() order), set between steps by a program driving the simulation: from
  /// t0 the targets move linearly from pin_targets(t0) to `targets`, reached at t1 > t0, and stay there; the
  /// scene's pin motion no longer applies. InputError when the count is wrong or a target is not finite.
  void set_pin_targets(const std::vector<Vec3>& targets, double t0, double t1);
  /// The cloth's mesh hierarchy (Wang 2018 App. B), built on first use with the pinned vertices kept.
  const hierarchy::TriangleHierarchy& hierarchy();
  /// The step's objective rediscretized on levels 1..H of hierarchy() (entry l is level l + 1), for
  /// Problem::level_objectives: the fine objective's terms built on the coarse mesh (masses and contact weights from
  /// the coarse lumped material areas, scaled so that the total mass is the fine one; membrane and bending from the
  /// coarse triangles and hinges; seams from the coarse stitch groups; the pins on their kept vertices). Built on
  /// first use; prepare_step keeps them on the current step, each level's prediction the fine one injected.
  std::vector<const physics::Objective*> level_objectives();
  /// hierarchy() as a solver sees it: prolongations and injections; with `rediscretized` also the step's objective
  /// on every level (level_objectives) and the least-squares projections of eq. 5.18 (factorized on first use and
  /// kept: the hierarchy does not change between steps).
  hierarchy::Hierarchy solver_hierarchy(bool rediscretized) override;

  const mesh::TriMesh& surface_mesh() const override { return m_mesh; }
  /// The mesh's texture coordinates (material coordinates over material_scale()).
  Mat2X surface_uv() const override { return m_mesh.u / m_material_scale; }
  Mat3X surface_positions() const override { return as_columns(m_x); }

 private:
  /// One level's objective and the terms that prepare_step updates.
  struct LevelObjective {
    std::unique_ptr<physics::Objective> objective;
    physics::InertiaTerm* inertia = nullptr;
    physics::AttachmentTerm* pins = nullptr;
    physics::ObstaclePenalty* contact = nullptr;
    physics::PDObstacleContact* pd_contact = nullptr;  ///< == contact in the PD form, else null
  };
  /// The objective of one discretization (the cloth's mesh or a coarse level): `area` the lumped vertex areas,
  /// `pins` the level's vertex of each entry of m_pin_vertices.
  LevelObjective build_objective(const mesh::TriMesh& mesh, const mesh::Topology& topology, const VecX& area,
                                 const std::vector<Index>& pins) const;
  /// Sets level `lv` for the step ending at t_next with prediction y; returns y projected out of obstacles.
  static VecX set_step(LevelObjective& lv, VecX y, double h, double t_next, const std::vector<Vec3>& targets);
  /// Sets coarse level l (>= 1) for the last prepared step.
  void set_coarse_step(size_t l);

  std::string m_name;
  mesh::TriMesh m_mesh;
  mesh::Topology m_topology;
  double m_material_scale = 1.0;
  VecX m_mass, m_area, m_x, m_v;
  bool m_project_obstacles = true;
  physics::Material m_material;
  Vec3 m_gravity = Vec3::Zero();
  double m_seam_stiffness = 0.0;
  std::vector<geometry::Obstacle> m_obstacles;
  physics::ContactParams m_contact_params;
  hierarchy::HierarchyParams m_hierarchy_params;
  bool m_projective = false;
  /// Level 0 is the cloth's own objective; levels 1..H are added by level_objectives().
  std::vector<LevelObjective> m_levels;
  bool m_coarse_built = false;
  /// The last prepare_step(): its unprojected prediction, step size and end time (h = 0: none yet).
  VecX m_prediction;
  double m_step_h = 0.0, m_step_end = 0.0;
  std::vector<Index> m_pin_vertices;
  std::vector<double> m_pin_stiffness;
  std::vector<Vec3> m_pin_rest;
  std::vector<size_t> m_pin_spec;  ///< which PinSpec each pinned vertex came from
  std::vector<PinSpec> m_pin_specs;
  std::vector<geometry::PointCurve> m_pin_curves;
  /// set_pin_targets(): targets at m_script_t0 and at m_script_t1 (empty: the scene's pin motion).
  std::vector<Vec3> m_script_from, m_script_to;
  double m_script_t0 = 0.0, m_script_t1 = 0.0;
  std::unique_ptr<hierarchy::TriangleHierarchy> m_hierarchy;
  std::vector<std::unique_ptr<hierarchy::LeastSquaresProjection>> m_lsq;  ///< per prolongation, built on first use
};

/// Lumped (one third of each adjacent triangle) vertex areas in material space.
VecX lumped_vertex_area(const mesh::TriMesh& mesh);

}  // namespace mgcloth::bodies
