#pragma once
#include <mgcloth/studies/convergence.hpp>
#include <mgcloth/sim/scene.hpp>

#include <functional>

namespace mgcloth::studies {

/// The single-level solver study of Kopaničáková 2019 (Table 3, Fig. 10): each shell scene at each level, the
/// scene's first time step solved by each solver from the same start, with the scene's stopping criterion.
struct ShellBenchOptions {
  std::vector<int> levels{1, 2, 3, 4};
  std::vector<SolverSpec> solvers;
  double time_step = 0.0;   ///< > 0: overrides the scenes' time_step (one step per frame)
  int max_iters = 0;        ///< > 0: overrides the scenes' solver.max_iters
  double max_seconds = 0.0; ///< > 0: wall-time cap per solve
  int threads = 0;
  /// Non-empty: each solve's final iterate and row are written there (`<shell>-L<level>-<solver>.state.json`,
  /// atomically), so that a solve stopped by its cap can go on in a later run.
  std::string states_dir;
  /// With states_dir: a solve whose state exists starts from it instead of the step's start (a converged one is not
  /// solved again). RMTR then skips nested iteration (initial: fine). Iterations and wall time add up; the counters
  /// are those of the last part, plus `resumed_iterations` (the parts before) and the nested cycles of the first.
  bool resume = false;
  /// With states_dir, > 0: `tr-*` and `rmtr` solves also write their state (status "checkpoint") at most this
  /// often, in seconds, so that a killed run loses at most that much.
  double checkpoint_seconds = 600.0;
  /// States of solves at coarser levels (files written by an earlier `bench shells`, any solver): a solve of the
  /// same shell at a finer level, without a state of its own to resume, starts from that solution prolongated by
  /// subdivision (beyond the paper: the nested start of full multigrid without re-solving the levels a coarser run
  /// has already solved). RMTR then skips nested iteration, and its coarse levels start from the state's own levels
  /// and its solution (`coarse_start: best`). The row gets the counter `started_from_level`.
  std::vector<std::string> start_from;
};

struct ShellBenchRow {
  std::string scene, shell, solver;
  int level = 0;
  Index dofs = 0;
  double time_step = 0.0;
  int iterations = 0;
  bool converged = false;
  std::string status;
  double energy = 0.0, grad_norm = 0.0, initial_grad_norm = 0.0;
  double wall_s = 0.0;
  std::vector<std::pair<std::string, double>> counters;
};

/// A state file written by `bench shells` (its `states/`): the shell, level and iterate of one solve, with the
/// solver's own coarse-level states. `--start-from` reads these; so does mgcloth_bench_shell_roundoff.
struct ShellBenchState {
  std::string file, shell;
  int level = 0;
  VecX x;
  std::vector<VecX> levels;  ///< coarsest first, as Rmtr::level_states()
};

/// Reads and checks a state file (format, fields, "x" of "dofs" finite entries); throws InputError naming the file.
ShellBenchState read_shell_bench_state(const std::string& file);

/// The scene as the shell benchmarks run it: its shells only, each at `level` (0: the scene's), solved by `spec`
/// with the scene's stopping criterion, and opt's time step (one step per frame), caps and threads where they are
/// set; one frame.
sim::Scene shell_bench_scene(const sim::Scene& base, int level, const SolverSpec& spec, const ShellBenchOptions& opt);

/// Called after every finished row with all rows so far, so that a long study can write its results as it goes.
using ShellBenchProgress = std::function<void(const std::vector<ShellBenchRow>&)>;

/// Runs every (scene, level, solver); a solve that diverges (SolveError) is recorded with status "diverged".
/// A state file that does not belong to its (scene, shell, level, solver, dofs) or is malformed is an InputError
/// naming the file.
std::vector<ShellBenchRow> run_shell_bench(const std::vector<sim::Scene>& scenes, const ShellBenchOptions& options,
                                           const ShellBenchProgress& on_row = {});
/// scene,shell,level,dofs,time_step,solver,iterations,converged,status,energy,grad_norm,rel_grad,wall_s,
/// accepted,rejected,hessian_assemblies,qp_calls,cg_iterations,work_assembly,work_qp (multilevel solvers: the per-level
/// columns count the finest level; work_* are the work units of Kopaničáková 2019, eq. 7.3, over all levels)
std::string shell_bench_csv(const std::vector<ShellBenchRow>& rows);
Json shell_bench_json(const std::vector<ShellBenchRow>& rows, const ShellBenchOptions& options);

/// Building and applying the two projections of iterates between consecutive levels of a shell's hierarchy
/// (Kopaničáková 2019 §5.3.2, Table 8's "time and memory of building each operator").
struct ProjectionBenchRow {
  std::string operator_name;  ///< "reverse_subdivision" or "least_squares"
  int fine_level = 0;         ///< the paper's numbering: levels 1..L, the projection maps fine_level to fine_level − 1
  Index fine_dofs = 0, coarse_dofs = 0;
  double build_ms = 0.0;
  double apply_ms = 0.0;      ///< one application to an xyz vector, averaged
  std::size_t memory_bytes = 0;
  Index entries = 0;          ///< nonzeros stored (Q's table; the Cholesky factor of SᵀS)
  double exactness = 0.0;     ///< max over random coarse q of ‖P S q − q‖ / ‖q‖ (0 in exact arithmetic)
};
/// Every level pair of the scene's first shell at its level.
std::vector<ProjectionBenchRow> run_projection_bench(const sim::Scene& scene);
/// operator,fine_level,fine_dofs,coarse_dofs,build_ms,apply_ms,memory_bytes,entries,exactness
std::string projection_bench_csv(const std::vector<ProjectionBenchRow>& rows);

}  // namespace mgcloth::studies
