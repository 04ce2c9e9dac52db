#pragma once
#include <mgcloth/bodies/body.hpp>
#include <mgcloth/geometry/obstacle.hpp>
#include <mgcloth/linalg/stencil_table.hpp>
#include <mgcloth/physics/cloth_friction.hpp>

#include <memory>
#include <vector>

namespace mgcloth::bodies {

/// Several bodies as one unknown, for one objective per step over all of them (docs/ARCHITECTURE.md): the joint
/// state is the concatenation of the bodies' points in order, the joint objective the sum of the bodies' objectives
/// (physics::SubObjectiveTerm, each at its body's offset) plus coupling terms written in the joint numbering (none
/// yet; contact between bodies adds them), and the joint hierarchy the block-diagonal union of the bodies'
/// hierarchies. A body whose hierarchy has fewer levels keeps its coarsest level on the deeper ones (identity
/// prolongation), so the union has as many levels as the deepest body's.
/// With one body and no coupling terms everything is the body's own (its objective, its hierarchy): a scene of one
/// body solves exactly as before.
class Assembly {
 public:
  explicit Assembly(std::vector<Body*> bodies);
  ~Assembly();

  const std::vector<Body*>& bodies() const { return m_bodies; }
  Index num_points() const { return m_offsets.back(); }
  /// First point of body b in the joint unknown.
  Index offset(size_t b) const { return m_offsets[b]; }

  VecX x() const;
  VecX v() const;
  /// Prepares every body's step and returns the joint start point.
  VecX prepare_step(const StepTime& step);
  /// The joint objective of the prepared step (built on first use; the bodies update their terms in place).
  physics::Objective& objective();
  /// The joint hierarchy (see the class comment), built on first use of each kind and kept.
  hierarchy::Hierarchy solver_hierarchy(bool rediscretized);
  /// Cloth–cloth contact, self and between bodies, over every body with a contact surface (Body::contact_surface,
  /// `thickness` per body), as one term of the group's objective: the body's own objective for a group of one body,
  /// else a coupling term of the joint one. Obstacle projections are turned off (Body::set_obstacle_projection) and
  /// the start point of every step is limited to an intersection-free motion from the current state.
  /// Mesh obstacles (`meshes`, each with its contact_thickness resolved) join the term as kinematic surfaces, placed
  /// at their poses at time t0.
  void add_cloth_contact(const physics::ClothContactParams& params, const std::vector<double>& thickness,
                         std::vector<geometry::Obstacle> meshes = {}, double t0 = 0.0);
  /// The mesh obstacles of the contact term, in its kinematic order.
  const std::vector<geometry::Obstacle>& mesh_obstacles() const { return m_meshes; }
  /// Puts the mesh obstacles at their poses at time t (a state set from outside, as on --resume).
  void place_obstacles(double t);
  /// Whether the mesh obstacles are short of their poses at the end of the prepared step: the start point's motion
  /// could take them only part of the way without a collision (prepare_step). The solve then pushes the cloth
  /// back, and advance_obstacles takes them further from its result.
  bool obstacles_behind() const { return m_behind; }
  /// Moves the mesh obstacles from where they are towards their poses at the end of the step as far as the cloths
  /// at x allow, carrying the cloth inside their contact layer along (x changes); returns the fraction of the
  /// remaining way they went.
  double advance_obstacles(VecX& x);
  /// The cloth contact term; null without one.
  const physics::ClothContact* cloth_contact() const { return m_contact; }
  /// Lagged friction between the cloths of the contact term (add_cloth_contact first), frozen at every step's start
  /// in prepare_step. Nothing is added where every coefficient is zero.
  void add_cloth_friction(const physics::ClothFrictionParams& params);
  /// The cloth friction term; null without one.
  const physics::ClothFriction* cloth_friction() const { return m_friction; }
  /// Every body's feasibility projection on its part of the joint iterate; empty when no body has one.
  std::function<Index(VecX&)> feasibility_projection() const;
  /// Hands each body its part of the solve's result (finish_step), then writes the bodies' ends (projected) back.
  void finish_step(VecX& x, double h);
  void accept_step(const VecX& x, const VecX& v);

 private:
  struct Union;
  /// The union of the bodies' level objectives (level >= 1) or own objectives (level 0).
  std::unique_ptr<physics::Objective> joint_objective(const std::vector<const physics::Objective*>& parts) const;

  std::vector<Body*> m_bodies;
  std::vector<Index> m_offsets;  ///< per body, then the total
  std::unique_ptr<physics::Objective> m_objective;
  std::unique_ptr<Union> m_galerkin, m_rediscretized;
  /// A term over all the bodies (contact, friction): in the one body's own objective, or the joint one (kept in
  /// m_pending until that exists).
  void add_coupling(std::unique_ptr<physics::Term> term);

  physics::ClothContact* m_contact = nullptr;
  physics::ClothFriction* m_friction = nullptr;
  /// The mesh obstacles' vertices at their poses at time t, in the contact term's kinematic order.
  VecX obstacle_positions(double t) const;
  std::vector<geometry::Obstacle> m_meshes;
  /// Cloth within this of a mesh obstacle's vertex sweep is in its way (half its longest edge, at most 5 cm, plus
  /// the thickest contact layer), m.
  double m_sweep_pad = 0.0;
  /// Sets dx_i (for points with !skip[i]) to the motion of the obstacle vertex whose sweep from y_from by
  /// motion passes nearest point i, within m_sweep_pad: the cloth ahead of a moving obstacle moves with it.
  void carry_swept(const VecX& x, const VecX& y_from, const VecX& motion, const std::vector<char>& skip, VecX& dx) const;
  VecX m_mesh_target;    ///< the kinematic points at the end of the prepared step
  bool m_behind = false;
  std::vector<std::unique_ptr<physics::Term>> m_pending;  ///< coupling terms until the joint objective exists
};

}  // namespace mgcloth::bodies
