#pragma once
#include <mgcloth/bodies/assembly.hpp>
#include <mgcloth/bodies/cloth_body.hpp>
#include <mgcloth/bodies/shell_body.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

#include <memory>
#include <string_view>

namespace mgcloth::sim {

using bodies::Body;
using bodies::ClothBody;
using bodies::ProbeReading;
using bodies::ShellBody;

/// Statistics of one implicit-Euler step of one solve: of one body, or of every body solved jointly.
struct StepStats {
  int frame = 0;
  long step = 0;
  double sim_time = 0.0;
  std::string body;  ///< the body's name, or the names joined by '+' (stats.csv's "cloth" column)
  std::string solver;
  solvers::SolveReport report;
  double wall_ms = 0.0;  ///< the whole step: set-up, solve, projection, friction
  Index projected = 0;   ///< vertices pushed out of obstacles after the solve
  /// Cloth contact at the step's end (scene "cloth_contact"; -1 and NaN without): pairs inside the contact layer,
  /// the smallest distance between non-neighbouring primitives (within reach of the contact layer; +inf where none
  /// is that close), and triangle pairs that intersect by the exact checker (-1: not checked).
  Index contact_pairs = -1;
  double min_distance = std::numeric_limits<double>::quiet_NaN();
  Index intersections = -1;
  /// With cloth contact: the step's time in contact detection (ContactTimes: broad phase, distances of cached pairs,
  /// continuous collision detection), and in the exact intersection checker (NaN: not run), ms.
  double contact_detection_ms = std::numeric_limits<double>::quiet_NaN();
  double check_ms = std::numeric_limits<double>::quiet_NaN();
  /// Mesh obstacles: the solves after the first that the step took because an obstacle was still short of its
  /// pose (Simulator::step); their iterations and time are in `report`.
  int obstacle_rounds = 0;
  /// Sewn cloths (stitch groups: a pattern's seams, an OBJ's UV seams): the largest distance between two points sewn
  /// together at the step's end, m (NaN: no cloth of the step has seams). Below the contact layer, a seam is shut.
  double seam_gap = std::numeric_limits<double>::quiet_NaN();
  /// The solver's estimate of the largest per-vertex velocity error of the step's end (SolveReport::step_error / h),
  /// m/s, whatever the stop rule; infinite where no estimate was possible, NaN where the solver makes none.
  double velocity_error = std::numeric_limits<double>::quiet_NaN();
  /// The mass-weighted RMS of the velocity error that the solver's Newton decrement estimates, sqrt(λ²/M) with M the
  /// step's cloth mass (SolveReport::decrement; its kinetic energy ½Mv² is at most E − E* ≈ λ²/2), m/s, whatever the
  /// stop rule. Measured at the last iterate but one, whose step was then taken. An estimate of the model, not of the
  /// cloth: the true error was 0.8-8x it in the median step of the scenes measured, up to 23x (bench/RESULTS.md,
  /// "Stopping by the Newton decrement"). For a solver that measures no decrement: the gradient's bound of the same
  /// error at the last iterate, h|∇E|/√(m_min·M) (at least 1.9x the true error where measured); NaN without cloth mass.
  double velocity_rms_error = std::numeric_limits<double>::quiet_NaN();
  /// With Simulator::set_accuracy_check: the distance of the step's result to the minimizer of its objective, as
  /// velocities (m/s): the largest per vertex and the vertices' root mean square (NaN: not checked, or the check's
  /// solve did not converge).
  double true_velocity_error = std::numeric_limits<double>::quiet_NaN();
  double true_velocity_rms = std::numeric_limits<double>::quiet_NaN();
  solvers::Trace trace;  ///< per-iteration trace, when the simulator records traces
  /// Shells: the load factor of the step (static runs; 1 in dynamic runs) and the probes after the step.
  double load_factor = 1.0;
  std::vector<ProbeReading> probes;
  std::size_t first_probe = 0;  ///< the number of probes.front() in the scene's probe order
};

/// An obstacle's motion that a program driving the simulation can steer between steps (Simulator::set_obstacle_pose,
/// for scripted or interactive animation): the scene's motion until the first steer, then keyframes through the
/// poses set (KeyframedMotion's interpolation), held after the last. Velocities are those of the segment that ends
/// at t, so the step that reaches a pose sees the obstacle moving (friction at the step's end).
class SteerableMotion final : public geometry::RigidMotion {
 public:
  explicit SteerableMotion(std::shared_ptr<const geometry::RigidMotion> scene_motion);
  geometry::Pose pose(double t) const override;
  void velocity(double t, Vec3& linear, Vec3& angular) const override;
  /// From t0 the obstacle moves from pose(t0) to `target`, reached at t1 > t0; keys after t0 (a pose set earlier
  /// for a step not yet taken) are replaced.
  void steer(double t0, double t1, const geometry::Pose& target);

 private:
  /// The keyframe segment [k0, k1] with k0.time < t <= k1.time (t inside the keyed span), as its own motion.
  geometry::KeyframedMotion segment(double t) const;

  std::shared_ptr<const geometry::RigidMotion> m_scene;
  std::vector<geometry::Keyframe> m_keys;  ///< empty: not steered
};

/// The time loop over the scene's bodies (cloths, then shells, in scene order): every step minimizes the step's
/// objective over all bodies (or, with "solve_bodies": "separately", each body's own) with the scene's solver
/// (docs/ARCHITECTURE.md, data flow), then lets every body end its step (contact projection, velocity, friction).
/// The bodies solved together are a group (bodies::Assembly) with one solver.
class Simulator {
 public:
  explicit Simulator(Scene scene);
  /// `meshes`: per cloth of the scene, a mesh given in memory by a program (the Python module's arrays) that
  /// replaces the cloth's mesh file or generator; missing or null entries keep the scene's.
  Simulator(Scene scene, const std::vector<std::shared_ptr<const mesh::TriMesh>>& meshes);

  const Scene& scene() const { return m_scene; }
  /// Every body: the scene's cloths, then its shells. Checkpoints, outputs and solver states are in this order.
  const std::vector<std::unique_ptr<Body>>& bodies() const { return m_bodies; }
  Body& body(size_t b) { return *m_bodies[b]; }
  /// The body named `name`; InputError listing the names when there is none.
  size_t body_index(const std::string& name) const;
  /// The bodies of each kind (views of bodies(), in scene order).
  std::vector<ClothBody*> cloths() const;
  std::vector<ShellBody*> shells() const;
  const std::vector<geometry::Obstacle>& obstacles() const { return m_obstacles; }

  /// Completed frames and steps; time is derived from the step count so that a resumed run lands on the same
  /// floating-point times as an uninterrupted one.
  int frame() const { return m_frame; }
  long step_count() const { return m_step; }
  double time() const { return static_cast<double>(m_step) * m_scene.step_size(); }

  /// The groups of bodies solved together: one with every body, or one per body.
  size_t num_groups() const { return m_groups.size(); }
  const bodies::Assembly& group(size_t g) const { return *m_groups[g]; }
  /// The group of body b.
  size_t group_of(size_t b) const { return m_group_of[b]; }
  /// The problem of the next step of group g (the objective prepared for t → t + h, with the hierarchy and the
  /// feasibility projection its solver needs) and its start point x0, without solving it. Used by step() and by
  /// benchmarks that freeze one step's objective. Valid until the next prepare or step. `load_factor` receives
  /// the step's load factor (static shells; 1 otherwise). A scene of one body has one group: g = 0.
  solvers::Problem prepare_problem(size_t g, VecX& x0, double* load_factor = nullptr);
  solvers::NonlinearSolver& solver(size_t g) { return *m_solvers[g]; }

  /// Runs the substeps of the next frame.
  std::vector<StepStats> advance_frame();
  /// One step of every cloth.
  std::vector<StepStats> step();
  /// Keep the solver's per-iteration trace (energy, gradient norm, wall time) in every StepStats.
  void set_record_trace(bool on) { m_record_trace = on; }
  /// Measures every step's accuracy (StepStats::true_velocity_error): after the solve, Newton + CHOLMOD goes on from
  /// its result to a gradient 1e-8 of the one the step started with, and the distance between the two is the
  /// error the solver's stop rule left. Each step is compared with its own minimizer, so stop rules can be compared
  /// on scenes whose trajectories part (contact, sliding). The check's solver is a separate object, so the step's
  /// solver carries on as it would have; what the two share is the objective's caches (cloth contact's near pairs),
  /// which can change later steps by round-off. The check minimizes the objective without the obstacles'
  /// feasibility projection (with it, Newton stalled on the drape's landing steps). Costs a Newton solve per step.
  void set_accuracy_check(bool on);
  bool accuracy_check() const { return !m_checkers.empty(); }

  /// Scripted animation between frames (the Python module): cloth c's pins pull towards `targets` (its
  /// pinned_vertices() order), reached at the end of the next frame, moving linearly from where they pull now; the
  /// scene's pin motion no longer applies. Not kept in checkpoints.
  void set_pin_targets(size_t c, const std::vector<Vec3>& targets);
  /// Obstacle o moves to `pose` over the next frame (SteerableMotion) and stays there. Not kept in checkpoints.
  void set_obstacle_pose(size_t o, const geometry::Pose& pose);

  /// State for checkpoints: frame, step, and x and v of every body. Throws InputError when the counts or sizes do
  /// not fit the scene.
  void set_state(int frame, long step, const std::vector<VecX>& x, const std::vector<VecX>& v);
  /// What the solver of `body` carries from one step into the next, as opaque bytes for checkpoints
  /// (sim::Checkpoint::Body::solver_state); empty when it carries nothing. A group's solver state is kept with its
  /// first body; the others' are empty.
  std::string solver_state(size_t body) const;
  /// Gives a solver_state() back to the solver of `body` after set_state(), so that the next step goes on as the
  /// uninterrupted run's. Throws InputError when the state does not fit that solver.
  void set_solver_state(size_t body, std::string_view state);

 private:
  Scene m_scene;
  /// InputError when cloth c (scene.cloths[c]) starts deeper inside an obstacle than the contact thickness.
  void check_start_outside_obstacles(size_t c, const ClothBody& body) const;
  /// Adds cloth contact to every group (scene "cloth_contact") and refuses a start whose cloths intersect, naming
  /// the triangles.
  void add_cloth_contact();
  std::vector<geometry::Obstacle> m_obstacles;
  /// The motion of each obstacle, shared with every copy of it (cloth bodies, contact terms) so that a steer
  /// reaches them all.
  std::vector<std::shared_ptr<SteerableMotion>> m_steering;
  std::vector<std::unique_ptr<Body>> m_bodies;
  std::vector<std::unique_ptr<bodies::Assembly>> m_groups;
  std::vector<size_t> m_group_of;
  /// One solver per group: solvers keep per-pattern state (the CHOLMOD analysis, the multigrid hierarchy).
  std::vector<std::unique_ptr<solvers::NonlinearSolver>> m_solvers;
  int m_frame = 0;
  long m_step = 0;
  bool m_record_trace = false;
  /// set_accuracy_check's solvers, one per group (empty: off).
  std::vector<std::unique_ptr<solvers::NonlinearSolver>> m_checkers;
  /// Fills s.true_velocity_error and s.true_velocity_rms for group g's step result x (set_accuracy_check).
  void check_accuracy(size_t g, const solvers::Problem& problem, const VecX& x, double h, StepStats& s);
};

}  // namespace mgcloth::sim
