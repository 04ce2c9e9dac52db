#pragma once
#include <mgcloth/studies/convergence.hpp>
#include <mgcloth/sim/scene.hpp>

#include <functional>

namespace mgcloth::studies {

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
  /// > 0: a try that has run this long stops before its next step (the first step always runs) and fails with status "try_time_limit" (the
  /// solve in progress may overrun it by up to max_seconds). Bounds the small steps of a solver that passes many
  /// steps before it fails.
  double max_try_seconds = 0.0;
  /// A "stalled" solve passes when ‖g‖ ≤ max(stall_rel_grad · ‖g₀‖, stall_abs_grad): the second clause of
  /// criterion (7.1), which stops the trust region at the limiting accuracy; a stall with a larger gradient is a
  /// failure. The paper's reading is absolute ("in practice ‖g‖ ≤ 5e-5", §7.2).
  double stall_rel_grad = 1e-5;
  double stall_abs_grad = 0.0;
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
  /// "stalled", "linearized", …), "diverged" for a SolveError (non-finite energy, failed line search), or
  /// "try_time_limit" when max_try_seconds ran out before failed_step (which was not run).
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

/// Whether one solve meets the stopping criterion (7.1): converged, or stalled at
/// ‖g‖ ≤ max(stall_rel_grad · ‖g₀‖, stall_abs_grad).
bool meets_criterion(const solvers::SolveReport& report, double stall_rel_grad, double stall_abs_grad = 0.0);

/// Called after every finished row with all rows so far, so that a long study can write its results as it goes.
using TimestepBenchProgress = std::function<void(const std::vector<TimestepBenchRow>&)>;

/// The time steps tried, largest first; InputError for a non-positive or non-finite min_dt or max_dt, or
/// min_dt > max_dt.
std::vector<double> timestep_ladder(const TimestepBenchOptions& options);
/// Every scene with every solver; a scene without shells, or bad options, is InputError before anything runs.
/// A row of `previous` (an earlier, interrupted run with the same options) with the same scene, solver, level,
/// window and time step is taken instead of running that try again, unless max_try_seconds would have cut it.
std::vector<TimestepBenchRow> run_timestep_bench(const std::vector<sim::Scene>& scenes, const TimestepBenchOptions& options,
                                                 const TimestepBenchProgress& on_row = {},
                                                 const std::vector<TimestepBenchRow>& previous = {});
/// In the order of first appearance of (scene, solver) in `rows`.
std::vector<TimestepBenchSummary> timestep_bench_summary(const std::vector<TimestepBenchRow>& rows);
/// scene,shells,level,dofs,solver,time_step,window,steps,steps_run,passed,failed_step,status,grad_norm,rel_grad,
/// stalled_steps,iterations,max_step_iterations,wall_s
std::string timestep_bench_csv(const std::vector<TimestepBenchRow>& rows);
/// The options, every row (with the SolveError messages) and the summary.
Json timestep_bench_json(const std::vector<TimestepBenchRow>& rows, const TimestepBenchOptions& options);
/// The rows of timestep_bench_json's "results".
std::vector<TimestepBenchRow> timestep_bench_rows(const Json& json);

}  // namespace mgcloth::studies
