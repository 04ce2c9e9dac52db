#pragma once
#include <mgcloth/linalg/stencil_table.hpp>
#include <mgcloth/physics/objective.hpp>

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace mgcloth::cuda {

/// Settings of the device FMG: the subset of solvers::FmgParams that the GPU pipeline implements (the paper's
/// configuration: one linear V-cycle of the Galerkin hierarchy per search direction, §4.2, with the CPU solver's
/// model step, momentum and backtracking line search).
struct FmgSettings {
  int pre_smooth = 3, post_smooth = 3;
  bool chebyshev = true;        ///< Chebyshev-accelerated symmetric Gauss-Seidel smoothing
  int matrix_update = 1;        ///< 0 every direction, 1 every cycle, 2 once per step (solvers::MatrixUpdate order)
  double armijo = 1e-4, shrink = 0.5;
  int max_line_search_steps = 30;
  bool momentum = true;
  double adaptive_threshold = 0.0;  ///< adaptive smoothing inside the V-cycles (§4.3), 0 = off
  /// The coarsest level's solve: "device" (dense Cholesky on the device: cuSOLVER on the CUDA backend) or "host"
  /// (CHOLMOD on the CPU, the coarse vectors copied each way); "auto" is "device".
  std::string coarse_solve = "auto";
  /// Time the V-cycle's parts (smoothing, coarse solve, transfers) with a device synchronization around each, and
  /// report the smoother's achieved memory bandwidth (counters smoothing_ms, coarse_ms, transfer_ms,
  /// smoother_gb_per_s). The synchronizations cost time, so the solve's own timing is taken with this off.
  bool profile = false;
  /// Replay the V-cycle as one captured graph (CUDA Graphs) instead of launching its kernels one by one.
  bool graphs = true;
  /// Once per pipeline, at its first matrix: time the Galerkin gather of every level against a general SpGEMM
  /// computing Pᵀ(A P) on the scalar CSR forms (cuSPARSE on the GPU, as Wang 2018 §5 compares its own RAP; Eigen
  /// on the host backend) and check that both give the same coarse matrices. Counters spgemm_gather_ms,
  /// spgemm_reference_ms (per update of the whole hierarchy) and spgemm_max_rel_diff, on every later solve too.
  bool compare_spgemm = false;
};

struct Limits {
  double rel_grad = 1e-6, abs_grad = 0.0;
  int max_iters = 100;
  double max_seconds = 1e300;
  bool interruptible = false;
};

struct Row {
  int iteration = 0;
  double energy = 0.0, grad_norm = 0.0, wall_ms = 0.0, step = 0.0;
};

struct Outcome {
  int iterations = 0;
  std::string status;
  double energy = 0.0, grad_norm = 0.0, initial_grad_norm = 0.0, target = 0.0, wall_ms = 0.0;
  std::vector<std::pair<std::string, double>> counters;
  std::vector<Row> trace;
};

/// The nonlinear FMG of Wang 2018 §4.2 with every step of a solve on one device: element kernels, BSR assembly,
/// Galerkin products, multi-color Gauss-Seidel, V-cycles, line search. Built for one objective and hierarchy and
/// kept across time steps (only the step's prediction, pin targets and obstacle poses are uploaded per minimize()).
class DeviceFmg {
 public:
  virtual ~DeviceFmg() = default;
  /// Minimizes `objective` from x (updated). `project`: make iterates feasible against the contact term's
  /// obstacles (the simulator's Problem::project). Throws InputError for an objective the pipeline cannot take and
  /// SolveError when the solve diverges, with the CPU solver's messages.
  virtual Outcome minimize(const physics::Objective& objective,
                           const std::vector<const linalg::StencilTable*>& prolongations, bool project, VecX& x,
                           const Limits& limits, bool trace) = 0;
  /// The time step's end on the device, after minimize() on the same objective (what bodies::ClothBody::finish_step
  /// does on the CPU): the solution projected out of the obstacles (§4.5), v = (x − x_old)/h, and the friction
  /// filter against the obstacles at the step's end (hd::filter_velocity). x (the solution minimize() left on the
  /// device) and v come back in the problem's numbering.
  virtual void finish_step(const VecX& x_old, double h, VecX& x, VecX& v) = 0;
  /// "host" or the CUDA device's name.
  virtual std::string device() const = 0;
  /// The Chebyshev spectral radius of every level's sweep, finest first: estimated on the first matrix and kept for
  /// later solves, so a checkpoint holds them (empty before the first solve).
  virtual std::vector<double> smoother_radii() const = 0;
  /// Gives smoother_radii() back before the next minimize(); empty: estimate them afresh.
  virtual void restore_smoother_radii(std::vector<double> radii) = 0;
};

enum class Backend { Cuda, Host };

/// Whether this build compiled the CUDA backend (MGCLOTH_CUDA).
bool cuda_compiled();
/// A CUDA device is present and usable; otherwise `why` says why not (no CUDA in this build, no device, driver).
bool cuda_available(std::string* why = nullptr);

/// Backend::Cuda throws Error with the reason when cuda_available() is false. Backend::Host runs the same pipeline
/// on the CPU (for tests and for checking the device code path without a GPU).
std::unique_ptr<DeviceFmg> make_device_fmg(Backend backend, const FmgSettings& settings);

}  // namespace mgcloth::cuda
