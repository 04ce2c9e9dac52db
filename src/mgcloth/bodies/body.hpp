#pragma once
#include <mgcloth/core/types.hpp>
#include <mgcloth/hierarchy/hierarchy.hpp>
#include <mgcloth/mesh/tri_mesh.hpp>
#include <mgcloth/physics/cloth_contact.hpp>
#include <mgcloth/physics/objective.hpp>

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace mgcloth::bodies {

/// The step a body prepares: from t to t + h. Static analyses (shells) apply `load_factor` of their loads and
/// prescribed displacements instead of stepping in time; dynamic ones ignore it.
struct StepTime {
  double t = 0.0;
  double h = 0.0;
  double load_factor = 1.0;
};

/// One probe reading: the position of a material point of the body and its displacement from the rest state.
struct ProbeReading {
  Vec2 at;
  Vec3 x, u;
};

/// Everything that moves (docs/ARCHITECTURE.md): a discretization with a state, the terms of its step's objective
/// and its hierarchy. The simulator knows bodies only through this interface: it prepares each body's step,
/// solves, and hands the result back; outputs, checkpoints and the Python module read the state and the surface.
/// The unknown of a body is its points' positions x (3 per point, xyz interleaved), with velocities v.
class Body {
 public:
  virtual ~Body() = default;

  virtual const std::string& name() const = 0;
  /// "cloth", "shell": what the body is, in messages.
  virtual std::string kind() const = 0;
  /// The body's size in messages, e.g. "3990 vertices" or "289 control points".
  virtual std::string size_text() const = 0;

  virtual VecX& x() = 0;
  virtual VecX& v() = 0;
  virtual const VecX& x() const = 0;
  virtual const VecX& v() const = 0;
  Index num_points() const { return x().size() / 3; }

  /// Sets the objective of the step (inertial prediction, pin targets, loads, obstacles at the step's end) on every
  /// level built so far, and returns the solve's start point.
  virtual VecX prepare_step(const StepTime& step) = 0;
  /// The objective prepare_step() set (the body's own terms over its own points).
  virtual physics::Objective& objective() = 0;
  /// The body's hierarchy as a solver sees it (levels finest first, level 0 this objective's unknown): the
  /// prolongations; with `rediscretized` also the step's objective on every level, projections of iterates and
  /// smoothing patches (FAS, RMTR). Built on first use and kept; valid until the next prepare_step().
  virtual hierarchy::Hierarchy solver_hierarchy(bool rediscretized) = 0;
  /// Makes an iterate feasible (projection out of obstacles, Wang 2018 §4.5), returning how many points it moved;
  /// empty where the body has nothing to project.
  virtual std::function<Index(VecX&)> feasibility_projection() const { return {}; }
  /// Ends the step from the solve's result: projection onto the feasible set (x_new is changed in place), the new
  /// velocity and friction.
  virtual void finish_step(VecX& x_new, double h) = 0;
  /// Ends the step with a state computed elsewhere (a device solver that ends the step itself).
  virtual void accept_step(const VecX& x_new, const VecX& v_new) {
    x() = x_new;
    v() = v_new;
  }

  /// The surface that takes part in cloth contact (bodies::Assembly::add_cloth_contact), in this body's numbering
  /// (offset 0), with the given thickness; nullopt for bodies that are no contact surface (shells).
  virtual std::optional<physics::ContactSurface> contact_surface(double /*thickness*/) const { return std::nullopt; }
  /// Whether the body moves its points out of obstacles by projection (feasibility_projection, finish_step). Cloth
  /// contact turns it off: a projection is no motion that continuous collision detection has checked.
  virtual void set_obstacle_projection(bool /*on*/) {}

  /// Static analysis (load stepping) rather than dynamics.
  virtual bool is_static() const { return false; }
  /// The surface drawn in the frame outputs (OBJ, glb, the viewer): its triangles (fixed for the run), the texture
  /// coordinates written with them, and the positions of its vertices in the current state.
  virtual const mesh::TriMesh& surface_mesh() const = 0;
  virtual Mat2X surface_uv() const = 0;
  virtual Mat3X surface_positions() const = 0;
  /// Material points the body reports after every step (probes.csv).
  virtual std::size_t num_probes() const { return 0; }
  virtual std::vector<ProbeReading> probes() const { return {}; }
};

}  // namespace mgcloth::bodies
