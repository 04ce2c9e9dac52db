#pragma once
// Solver benchmarks on the objectives of a scene (docs/ARCHITECTURE.md, "Data flow": studies freeze one step):
// convergence of several solvers on one frozen step, measured by the relative energy error against time (Wang
// 2018, Fig. 4), and the scalability of one solver with the cloth's vertex count.
#include <mgcloth/sim/simulator.hpp>

#include <array>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace mgcloth::studies {

/// A solver with its parameters, as written on the command line: "NAME" or "NAME@key=value@key=value…". Values
/// are JSON scalars (numbers, true/false, null, "strings"; a value that is not valid JSON is taken as an unquoted
/// string), e.g. "newton@linear_solver=pcg-mg@linear_tol=1e-3". The label is the whole spec string.
struct SolverSpec {
  std::string label;
  solvers::SolverConfig config;  ///< name and params; the stop criteria are the benchmark's
};

/// Parses one spec; a malformed one (empty name or key, no '=', a repeated key, an array or object value) is
/// InputError naming the spec. Names and keys are checked by check_solver_spec, not here.
SolverSpec parse_solver_spec(const std::string& spec);
/// Comma-separated specs ("newton,fmg@hessian_update=step"); an empty list or an empty entry is InputError.
std::vector<SolverSpec> parse_solver_list(const std::string& list);
/// Builds the solver through the factory (solvers::make_solver), so that an unknown name or parameter fails with
/// the factory's message, before any long computation. Returns whether the solver is projective().
bool check_solver_spec(const SolverSpec& spec);

/// (E_k − E*)/(E_0 − E*): 1 at the start point, 0 at the minimum. NaN when E_0 <= E* (nothing to measure).
double relative_energy_error(double energy, double initial_energy, double min_energy);

/// Every generated cloth mesh (rectangle or tube) of the scene with `vertices` as its target vertex count, each
/// cloth its own (five sheets at 2000 make a problem of about 10,000 points); a cloth read from a file is InputError
/// (it cannot be resized).
sim::Scene with_vertex_count(sim::Scene scene, Index vertices);

/// A simulator state: completed frames and steps, and every body's positions and velocities (Simulator::bodies()).
struct SimState {
  int frame = 0;
  long step = 0;
  std::vector<VecX> x, v;
};
/// The state after whole steps (frames derived from the step count: Simulator::step() does not count frames).
SimState simulator_state(const sim::Simulator& sim);
/// What a simulated state depends on, as a cache key: the scene without frames, threads and outputs (plus the size
/// and modification time of mesh files). Add what else the state depends on (the step count, …).
Json state_cache_key(const sim::Scene& scene);
/// The state cache of the benchmarks: a JSON key line (what the state depends on) followed by the binary vectors.
/// load_state_cache returns nothing when the file is missing, unreadable, or holds a state for a different key;
/// save_state_cache writes atomically.
std::optional<SimState> load_state_cache(const std::filesystem::path& file, const Json& key);
void save_state_cache(const std::filesystem::path& file, const Json& key, const SimState& state);

struct ConvergenceOptions {
  int step = 1;  ///< K: the benchmarked step is the K-th of the scene (K − 1 steps are simulated first)
  /// The body whose step objective is frozen (a cloth or shell of the scene by name; empty: the first body).
  /// Without cloth contact nothing couples the bodies: the study simulates the scene with every body solved
  /// separately, so the frozen problem is that body's own. With cloth contact (frozen_group_is_scenes) it keeps the
  /// scene's groups, and the frozen problem is the joint step of the group that holds the body: every cloth, the
  /// contact term included.
  std::string body;
  std::vector<SolverSpec> solvers;
  double budget_seconds = 10.0;  ///< wall time per solver (the timed run)
  int max_iters = 10000;         ///< iterations per solver (the timed run)
  int threads = 0;               ///< 0: the scene's
  std::string state_cache;       ///< file caching the state at the start of step K ("": none)
  /// A run's checkpoint.bin ("": none): the state at the start of step K is the checkpoint's, whose scene
  /// fingerprint must be this scene's; K is its step + 1 (step 0 here: taken from the checkpoint). Nothing is
  /// simulated, so a step late in a long run costs one solve.
  std::string checkpoint;
  /// The solver that simulates steps 1 … K − 1 (empty label: the elastic reference, newton-direct). At 120K vertices
  /// with cloth contact, newton-direct took 13 minutes for step 4 alone; the start point only has to be a state of
  /// the scene, and the state cache's key names the solver.
  SolverSpec warmup;
  double reference_rel_grad = 1e-10;  ///< how far the reference solvers go for E*
  int reference_max_iters = 500;      ///< Newton-type reference (elastic form)
  int pd_reference_max_iters = 20000;  ///< Projective Dynamics reference (linear convergence: generous)
  double reference_max_seconds = 600.0;  ///< wall-time cap of each reference solve
};

/// The minimum E* of one energy form and how it was reached.
struct ReferenceEnergy {
  std::string form;    ///< "elastic" or "projective"
  std::string solver;  ///< the reference solver that was run, with its parameters
  double energy = 0.0;          ///< E*
  double initial_energy = 0.0;  ///< E_0 at the start point x0 (in this form)
  int iterations = 0;
  double rel_grad = 0.0;  ///< |∇E(x*)| / |∇E(x0)| reached
  std::string status;     ///< the reference solve's status
  bool reached = false;   ///< rel_grad <= ConvergenceOptions::reference_rel_grad
  double seconds = 0.0;
  /// Set when a benchmarked solver ended below the minimum found from x0 and the reference solver, continued from
  /// that solver's final iterate, found this lower E* (the step problems are not convex).
  std::string polished_from;
  double unpolished_energy = 0.0;
};

/// One iteration of one solver's timed run (a row of convergence.csv).
struct ConvergenceRow {
  std::string solver;  ///< SolverSpec::label
  int iteration = 0;
  double wall_s = 0.0;
  double energy = 0.0;
  double grad_norm = 0.0;
  double rel_energy_error = 0.0;
};

/// Cloth contact at one point of the frozen problem (all -1/NaN without cloth contact): pairs inside the contact
/// layer and the smallest distance (physics::ClothContact::stats; +inf: no pair within reach), and the triangle pairs
/// that intersect by the independent exact checker (collision::find_intersections), as stats.csv has them.
struct ContactCheck {
  Index pairs = -1;
  double min_distance = std::numeric_limits<double>::quiet_NaN();
  Index intersections = -1;
};

/// The error levels the summary reports the time to reach.
inline constexpr std::array<double, 3> kErrorLevels{1e-2, 1e-3, 1e-4};

struct SolverSummary {
  std::string solver;  ///< label
  std::string form;    ///< energy form it minimizes
  int iterations = 0;
  double final_error = 0.0;  ///< relative energy error of the last iterate
  double final_rel_grad = 0.0;
  double seconds = 0.0;        ///< timed run
  double warmup_seconds = 0.0;  ///< the untimed one-iteration warm-up (set-up that is reused across steps)
  std::string status;
  std::array<std::optional<double>, kErrorLevels.size()> time_to{};  ///< first wall_s with error <= level
  /// The timed run's solver counters (SolveReport::counters: time per phase, line-search evaluations, …).
  std::vector<std::pair<std::string, double>> counters;
  ContactCheck contact;  ///< at the timed run's final iterate (cloth contact only)
};

/// Whether the study keeps the scene's groups and freezes the step of the group that holds the body (cloth contact
/// couples the bodies of a group) rather than the body's own step.
bool frozen_group_is_scenes(const sim::Scene& scene);

struct ConvergenceResult {
  std::string scene;
  std::string cloth;  ///< the body chosen (ConvergenceOptions::body; default the first)
  std::vector<std::string> bodies;  ///< the bodies of the frozen problem: the chosen one, or its whole group
  Index vertices = 0;  ///< points of the whole frozen problem (every body of `bodies`)
  bool cloth_contact = false;  ///< the frozen problem has a cloth contact term (then `start` and each summary's
                               ///< `contact` are measured)
  ContactCheck start;  ///< contact at x0
  int step = 1;
  std::string start_state;  ///< "simulated", "cache" or "checkpoint"
  std::string warmup_solver;  ///< the solver that simulated steps 1 … K − 1
  std::vector<ReferenceEnergy> references;
  std::vector<ConvergenceRow> rows;
  std::vector<SolverSummary> summaries;
};

/// The first wall_s at which `solver`'s rows reach a relative energy error <= level.
std::optional<double> time_to_error(const std::vector<ConvergenceRow>& rows, const std::string& solver, double level);

/// The convergence benchmark. Simulates the scene to the start of step K with the reference solver
/// (`newton-direct`, or `newton` with CHOLMOD where that is not built) and the scene's stop criteria, or loads that
/// state from opt.state_cache; freezes step K's objective of the chosen body (or, with cloth contact, of its group:
/// frozen_group_is_scenes) and runs every solver from the same start x0,
/// each with its own Simulator so that it gets the problem it gets in a simulation (hierarchy, coarse objectives,
/// and the Projective Dynamics energy form for projective solvers). Each solver is warmed up first by one
/// iteration on a copy of x0 (untimed, so that one-time set-up — symbolic factorizations, colorings, hierarchies —
/// is not charged to the step), then timed to opt.budget_seconds or opt.max_iters. E* per energy form comes from
/// the reference solver of that form (newton-direct; pd-direct) run from x0 to opt.reference_rel_grad.
/// Every spec is checked (check_solver_spec) before anything is simulated; with cloth contact, solvers that do not
/// keep their trial points within the contact's step limits are refused then too, by name. The frozen problem is
/// the one Simulator::prepare_problem gives a simulation (the contact-limited start point, no projection), so every
/// solver keeps the contact guarantee by itself; the result has the contact at x0 and at each solver's end.
ConvergenceResult run_convergence(const sim::Scene& scene, const ConvergenceOptions& opt);

/// convergence.csv: solver,iteration,wall_s,energy,grad_norm,rel_energy_error.
std::string convergence_csv(const ConvergenceResult& result);
/// convergence.json: E* per form and how it was reached, the options, and the per-solver summaries.
Json to_json(const ConvergenceResult& result, const ConvergenceOptions& opt);

struct ScalabilityOptions {
  std::vector<Index> vertices;  ///< target vertex counts (every generated cloth)
  SolverSpec solver;
  int steps = 3;    ///< measured steps
  int warmup = 1;   ///< steps before the measurement (set-up, first contact)
  double rel_grad = 1e-2;  ///< stop criterion of every step: relative gradient (residual) norm
  int threads = 0;         ///< 0: the scene's
};

struct ScalabilityRow {
  Index target_vertices = 0;
  Index vertices = 0;  ///< all cloths, as generated
  std::string solver;
  double ms_per_step = 0.0;  ///< whole steps (set-up, solve, contact, friction)
  double solve_ms_per_step = 0.0;
  double iterations_per_step = 0.0;
  int unconverged_steps = 0;  ///< steps that stopped before reaching rel_grad
  double setup_ms = 0.0;      ///< building the simulator (meshes, objectives)
  /// The solver's *_ms counters (time per phase) and its rates (*_per_s), per measured step (rates: averaged).
  std::vector<std::pair<std::string, double>> phases;
};

/// For each vertex count: builds the scene with that count, simulates opt.warmup steps, then times opt.steps steps
/// with the solver stopping at opt.rel_grad (and the scene's max_iters). The spec is checked first.
std::vector<ScalabilityRow> run_scalability(const sim::Scene& scene, const ScalabilityOptions& opt);
/// scalability.csv: vertices,solver,ms_per_step,iterations_per_step,solve_ms_per_step,unconverged_steps,
/// target_vertices,steps,warmup,rel_grad,threads,setup_ms,ms_per_iteration,phases (phases: "name=ms;…" per step).
std::string scalability_csv(const std::vector<ScalabilityRow>& rows, const ScalabilityOptions& opt);

}  // namespace mgcloth::studies
