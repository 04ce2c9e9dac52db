#pragma once
#include <mgcloth/sim/cloth_body.hpp>
#include <mgcloth/sim/shell_body.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

#include <map>
#include <memory>
#include <string_view>

namespace mgcloth::sim {

/// Statistics of one implicit-Euler step of one cloth.
struct StepStats {
  int frame = 0;
  long step = 0;
  double sim_time = 0.0;
  std::string cloth;
  std::string solver;
  solvers::SolveReport report;
  double wall_ms = 0.0;  ///< the whole step: set-up, solve, projection, friction
  Index projected = 0;   ///< vertices pushed out of obstacles after the solve
  solvers::Trace trace;  ///< per-iteration trace, when the simulator records traces
  /// Shells: the load factor of the step (static runs; 1 in dynamic runs) and the probes after the step.
  double load_factor = 1.0;
  std::vector<ProbeReading> probes;
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

/// The time loop: every step minimizes each cloth's incremental potential with the scene's solver
/// (ARCHITECTURE.md data flow), then projects contacts and filters friction.
class Simulator {
 public:
  explicit Simulator(Scene scene);
  /// `meshes`: per cloth of the scene, a mesh given in memory by a program (the Python module's arrays) that
  /// replaces the cloth's mesh file or generator; missing or null entries keep the scene's.
  Simulator(Scene scene, const std::vector<std::shared_ptr<const mesh::TriMesh>>& meshes);

  const Scene& scene() const { return m_scene; }
  std::vector<std::unique_ptr<ClothBody>>& cloths() { return m_cloths; }
  const std::vector<std::unique_ptr<ClothBody>>& cloths() const { return m_cloths; }
  const std::vector<geometry::Obstacle>& obstacles() const { return m_obstacles; }
  std::vector<std::unique_ptr<ShellBody>>& shells() { return m_shells; }
  const std::vector<std::unique_ptr<ShellBody>>& shells() const { return m_shells; }

  /// Completed frames and steps; time is derived from the step count so that a resumed run lands on the same
  /// floating-point times as an uninterrupted one.
  int frame() const { return m_frame; }
  long step_count() const { return m_step; }
  double time() const { return static_cast<double>(m_step) * m_scene.step_size(); }

  /// The problem of the next step of cloth c (the objective prepared for t → t + h, with hierarchy, contact
  /// projection and coarse objectives as its solver needs) and its start point x0, without solving it. Used by
  /// step() and by benchmarks that freeze one step's objective. Valid until the next prepare or step.
  solvers::Problem prepare_problem(size_t c, VecX& x0);
  solvers::NonlinearSolver& solver(size_t c) { return *m_solvers[c]; }
  /// The same for shell s: its step objective and start point, and the load factor of the step.
  solvers::Problem prepare_shell_problem(size_t s, VecX& x0, double* load_factor = nullptr);
  solvers::NonlinearSolver& shell_solver(size_t s) { return *m_shell_solvers[s]; }

  /// Runs the substeps of the next frame.
  std::vector<StepStats> advance_frame();
  /// One step of every cloth.
  std::vector<StepStats> step();
  /// Keep the solver's per-iteration trace (energy, gradient norm, wall time) in every StepStats.
  void set_record_trace(bool on) { m_record_trace = on; }

  /// Scripted animation between frames (the Python module): cloth c's pins pull towards `targets` (its
  /// pinned_vertices() order), reached at the end of the next frame, moving linearly from where they pull now; the
  /// scene's pin motion no longer applies. Not kept in checkpoints.
  void set_pin_targets(size_t c, const std::vector<Vec3>& targets);
  /// Obstacle o moves to `pose` over the next frame (SteerableMotion) and stays there. Not kept in checkpoints.
  void set_obstacle_pose(size_t o, const geometry::Pose& pose);

  /// State for checkpoints: frame, step, and x and v of every cloth, then of every shell. Throws InputError when
  /// the counts or sizes do not fit the scene.
  void set_state(int frame, long step, const std::vector<VecX>& x, const std::vector<VecX>& v);
  /// What the solver of `body` (every cloth, then every shell) carries from one step into the next, as opaque
  /// bytes for checkpoints (sim::Checkpoint::Body::solver_state); empty when it carries nothing.
  std::string solver_state(size_t body) const;
  /// Gives a solver_state() back to the solver of `body` after set_state(), so that the next step goes on as the
  /// uninterrupted run's. Throws InputError when the state does not fit that solver.
  void set_solver_state(size_t body, std::string_view state);

 private:
  Scene m_scene;
  /// InputError when cloth c starts deeper inside an obstacle than the contact thickness.
  void check_start_outside_obstacles(size_t c) const;
  std::vector<geometry::Obstacle> m_obstacles;
  /// The motion of each obstacle, shared with every copy of it (cloth bodies, contact terms) so that a steer
  /// reaches them all.
  std::vector<std::shared_ptr<SteerableMotion>> m_steering;
  std::vector<std::unique_ptr<ClothBody>> m_cloths;
  std::vector<std::unique_ptr<solvers::NonlinearSolver>> m_solvers;
  std::vector<std::unique_ptr<ShellBody>> m_shells;
  std::vector<std::unique_ptr<solvers::NonlinearSolver>> m_shell_solvers;
  int m_frame = 0;
  long m_step = 0;
  bool m_record_trace = false;
};

}  // namespace mgcloth::sim
