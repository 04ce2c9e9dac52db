#pragma once
#include <mgcloth/sim/convergence.hpp>
#include <mgcloth/sim/scene.hpp>

#include <functional>

namespace mgcloth::sim {

/// The time-step robustness study of Kopaničáková 2019 (§7.4.1, Fig. 10): the largest time step at which a solver
/// converges at every step of a simulation. Each scene is simulated from rest over a fixed window of simulated time
/// with dt = max_dt, max_dt/2, max_dt/4, … down to min_dt; for each solver the halving stops at the first dt that
/// passes.
struct TimestepBenchOptions {
  int level = 0;  ///< > 0: every shell at this subdivision level (3: 1,083 dofs); 0: the scenes' levels
  std::vector<SolverSpec> solvers;
  double max_dt = 1.0;           ///< the paper tests nothing above 1 s (one result per frame is needed anyway)
  double min_dt = 1.0 / 64.0;    ///< the last dt tried is the smallest max_dt / 2^k that is at least min_dt
  /// > 0: simulated seconds per try; 0: the scene's duration (frames × frame_time) capped at kDefaultWindowCap,
  /// so that the small steps do not take forever. A try runs max(1, ⌈window / dt⌉) steps.
  double window = 0.0;
  int max_iters = 0;             ///< > 0: overrides the scenes' solver.max_iters (per solve)
  double max_seconds = 0.0;      ///< > 0: wall-time cap per solve
  /// A "stalled" solve passes when ‖g‖ ≤ stall_rel_grad · ‖g₀‖: the second clause of criterion (7.1), which stops
  /// the trust region at the limiting accuracy; a stall with a larger gradient is a failure.
  double stall_rel_grad = 1e-5;
  int threads = 0;

  static constexpr double kDefaultWindowCap = 2.0;
};

/// One (scene, solver, dt) try.
struct TimestepBenchRow {
  std::string scene, shells, solver;  ///< shells: the scene's shell names joined by '+'
  int level = 0;                      ///< of the first shell
  Index dofs = 0;                     ///< all shells together
  double time_step = 0.0, window = 0.0;
  int steps = 0;       ///< steps the window needs at this dt
  int steps_run = 0;   ///< steps attempted, the failing one included
  bool passed = false; ///< every step converged
  int failed_step = 0; ///< 1-based; 0 when none failed
  /// "converged" for a try that passed; otherwise the failing solve's status ("max_iters", "time_limit",
  /// "stalled", "linearized", …) or "diverged" for a SolveError (non-finite energy, failed line search).
  std::string status;
  std::string message;       ///< the SolveError's text, when one ended the try
  double grad_norm = 0.0, initial_grad_norm = 0.0;  ///< of the failing solve (of the last one when all passed)
  int stalled_steps = 0;     ///< steps accepted as stalled at the limiting accuracy
  long iterations = 0;       ///< nonlinear iterations over all steps run
  int max_step_iterations = 0;
  double wall_s = 0.0;       ///< all steps run
};

/// The outcome per (scene, solver): the largest dt that passed (0 when none did) and what that try cost.
struct TimestepBenchSummary {
  std::string scene, shells, solver;
  Index dofs = 0;
  double largest_dt = 0.0;
  long iterations = 0;
  double wall_s = 0.0;
  int tries = 0;
  double total_wall_s = 0.0;  ///< all tries
};

/// Whether one solve meets the stopping criterion (7.1): converged, or stalled at ‖g‖ ≤ stall_rel_grad · ‖g₀‖.
bool meets_criterion(const solvers::SolveReport& report, double stall_rel_grad);

/// Called after every finished row with all rows so far, so that a long study can write its results as it goes.
using TimestepBenchProgress = std::function<void(const std::vector<TimestepBenchRow>&)>;

/// The time steps tried, largest first; InputError for a non-positive or non-finite min_dt or max_dt, or
/// min_dt > max_dt.
std::vector<double> timestep_ladder(const TimestepBenchOptions& options);
/// Every scene with every solver; a scene without shells, or bad options, is InputError before anything runs.
std::vector<TimestepBenchRow> run_timestep_bench(const std::vector<Scene>& scenes, const TimestepBenchOptions& options,
                                                 const TimestepBenchProgress& on_row = {});
/// In the order of first appearance of (scene, solver) in `rows`.
std::vector<TimestepBenchSummary> timestep_bench_summary(const std::vector<TimestepBenchRow>& rows);
/// scene,shells,level,dofs,solver,time_step,window,steps,steps_run,passed,failed_step,status,grad_norm,rel_grad,
/// stalled_steps,iterations,max_step_iterations,wall_s
std::string timestep_bench_csv(const std::vector<TimestepBenchRow>& rows);
/// The options, every row (with the SolveError messages) and the summary.
Json timestep_bench_json(const std::vector<TimestepBenchRow>& rows, const TimestepBenchOptions& options);

}  // namespace mgcloth::sim
