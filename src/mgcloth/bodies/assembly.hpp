#pragma once
#include <mgcloth/bodies/body.hpp>
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
  void add_cloth_contact(const physics::ClothContactParams& params, const std::vector<double>& thickness);
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
  std::vector<std::unique_ptr<physics::Term>> m_pending;  ///< coupling terms until the joint objective exists
};

}  // namespace mgcloth::bodies
