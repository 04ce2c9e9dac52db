#pragma once
#include <mgcloth/core/timer.hpp>
#include <mgcloth/solvers/line_search.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

#include <string>
#include <utility>
#include <vector>

namespace mgcloth::solvers {

/// When the system matrix A_0 (the PSD-projected Hessian, or the constant Projective Dynamics matrix) and its
/// Galerkin hierarchy are recomputed (Wang 2018 §4.2.1, Fig. 6).
enum class MatrixUpdate {
  Direction,  ///< before every search direction (every level of every V-cycle)
  Cycle,      ///< once per FMG cycle (the paper's choice)
  Step,       ///< once per time step (per minimize call)
  Constant,   ///< once; later steps reassemble it and refactor only if it changed (Projective Dynamics)
};
std::string to_string(MatrixUpdate u);
MatrixUpdate matrix_update_from_string(const std::string& s);  ///< throws InputError
std::vector<std::string> matrix_update_names();

/// Where the vectors of one nonlinear FMG solve live and how the objective, the model matrix and the multigrid act
/// on them: the CPU (VecX and LinearMultigrid, in nonlinear_fmg.cpp) or a device (cuda::DeviceFmg, in
/// fmg_cuda.cpp). The cycle (FmgCycle) sees only these operations, so both run one implementation of it.
class FmgBackend {
 public:
  /// The solve's vectors, each of the objective's size: the iterate, gradient and residual r = −g, the level's
  /// correction prolonged (D) and A_0 D, the search direction and A_0 P, the previous step and A_0 S, the trial
  /// point and its gradient, the previous iterate (Chebyshev weights) and the model's Newton step.
  enum Vec : int { X, G, R, D, Ad, P, Ap, S, As, Trial, GTrial, XPrev, C, NumVecs };

  virtual ~FmgBackend() = default;

  // The objective.
  virtual double energy(Vec x) = 0;
  virtual void gradient(Vec x, Vec g) = 0;
  /// energy(x) with gradient(x, g), in one pass where the backend can fuse them; the same values.
  virtual double energy_and_gradient(Vec x, Vec g) {
    gradient(x, g);
    return energy(x);
  }
  /// Makes x feasible against the obstacles (§4.5); the number of vertices moved. False has_projection(): none.
  virtual bool has_projection() const = 0;
  /// The objective's Term::max_step: the largest α <= alpha_max whose motion x + [0, α]·d is admissible (cloth
  /// contact: intersection-free). Backends whose objectives never limit steps return alpha_max.
  virtual double max_step(Vec /*x*/, Vec /*d*/, double alpha_max) { return alpha_max; }
  virtual bool limits_steps() const { return false; }
  virtual Index project(Vec x) = 0;
  /// Σ |term value| at x: the magnitude whose round-off bounds what an energy difference can resolve.
  virtual double energy_magnitude(Vec x) = 0;
  /// Whether gnorm at x is within a small factor of the gradient's round-off floor (physics::at_roundoff_floor).
  virtual bool at_roundoff_floor(Vec x, double gnorm, double* floor) = 0;

  // Vectors.
  virtual double dot(Vec a, Vec b) = 0;
  virtual double norm(Vec a) = 0;
  virtual void combine(Vec out, double a, Vec u, double b, Vec w) = 0;  ///< out = a·u + b·w
  virtual void scale(Vec out, double a, Vec u) = 0;                     ///< out = a·u
  /// out = ω (u − prev) + prev: the Chebyshev weighting of an iterate u against the previous one (Wang 2015).
  virtual void weight(Vec out, double omega, Vec u, Vec prev) = 0;
  virtual void copy(Vec to, Vec from) = 0;
  /// to = from, from unspecified afterwards (a swap where the vectors can be swapped).
  virtual void take(Vec to, Vec from) = 0;

  // The model and the multigrid.
  /// Recomputes the matrix A_0 at x and its hierarchy; false when the matrix is the same as before (a constant
  /// matrix that did not change), and nothing else was done.
  virtual bool update_matrix(Vec x) = 0;
  virtual void multiply(Vec in, Vec out) = 0;  ///< out = A_0 in
  /// The correction of level `level` for the fine residual r, prolonged to the finest level into d: `sweeps`
  /// smoothing sweeps there (linear = false) or one linear V-cycle from there down (linear = true), from zero on the
  /// restricted residual I_0^hᵀ r. Returns c·(I_0^hᵀ r) = d·r, > 0 for an SPD smoother (Theorems 4.1, 4.2).
  virtual double correction(Index level, bool linear, int sweeps, Vec r, Vec d) = 0;
  /// The model's Newton step A_0 c = r by V-cycles from zero until ‖r − A_0 c‖ <= tol.
  virtual void newton_step(Vec r, Vec c, double tol) = 0;
  /// Remembers x, and measures the largest per-vertex distance of a later x from it: the step of one cycle, for
  /// Stop::step_tol.
  virtual void mark(Vec x) = 0;
  virtual double max_distance_from_mark(Vec x) = 0;
  /// Waits for queued work (the device's), so that a timer around a call measures the call.
  virtual void synchronize() {}
  /// What the backend measured: the time of its own phases (assembly, Galerkin, smoothing, ...), its own counts.
  virtual std::vector<std::pair<std::string, double>> counters() const = 0;
};

/// One move of the cycle's schedule: a smoothing on a nonlinear level, or the linear V-cycle from a level down.
struct FmgStage {
  Index level = 0;
  bool linear = false;
  int sweeps = 0;
};

/// What the cycle itself does, whatever the backend (FmgParams' cycle part).
struct FmgCycleParams {
  MatrixUpdate matrix_update = MatrixUpdate::Cycle;
  double refresh_below = 0.25;
  bool line_search = true;
  LineSearchParams line_search_params{.interpolate = true, .refine = 3};
  double chebyshev_rho = 0.0;
  int chebyshev_delay = 1;
  bool momentum = true;
};

/// The nonlinear FMG cycle of Wang et al. 2018 (§4.2, Fig. 5) over a backend: for every stage of the schedule, the
/// level's correction of the fine residual is a search direction for the finest-level objective, scaled by the
/// quadratic model (§4.2.3) and by momentum, line-searched on the true energy, projected (§4.5); the matrix is
/// updated per policy (§4.2.1); a cycle in which no direction moved falls back (a fresh matrix, steepest descent,
/// the model's Newton step) before it reports that the solve cannot go on.
class FmgCycle {
 public:
  struct Counts {
    long directions = 0, rejected = 0, energy_evals = 0, matrix_updates = 0, refreshes = 0, fallbacks = 0;
    int cycles = 0;
    double line_search_ms = 0.0, gradient_ms = 0.0, model_ms = 0.0;
    double step_limit_ms = 0.0;  ///< the motion's limits (cloth contact's collision detection along each step)
  };

  /// `beta`: per level, the accepted step over the model step of its last direction, the next line search's
  /// start (§4.2.3); kept by the caller across solves. x is in the backend's X. `clock`: started when the
  /// caller's minimize() began (its set-up counts in the solve's time, as in every solver's).
  static SolveReport run(FmgBackend& backend, const std::string& name, const FmgCycleParams& params,
                         const std::vector<FmgStage>& stages, std::vector<double>& beta, const Stop& stop,
                         Trace* trace, Counts& counts, const Timer& clock);
};

/// Steepest descent from the backend's X (gradient in G, energy e): along r = −g from the step that minimizes the
/// model A_0 along it (with `use_model`; else a secant curvature from a gradient at a small probe), backtracking.
/// On success X, e are the new point and its energy (the gradient is not recomputed); false when no step decreased
/// the energy. Uses R, Ad, Trial, GTrial.
bool steepest_descent(FmgBackend& backend, bool use_model, double& e, long* energy_evals = nullptr);

}  // namespace mgcloth::solvers
