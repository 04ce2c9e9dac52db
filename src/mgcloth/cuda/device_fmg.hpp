#pragma once
#include <mgcloth/linalg/stencil_table.hpp>
#include <mgcloth/physics/objective.hpp>

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace mgcloth::cuda {

/// Settings of the device pipeline: its smoother, coarse solve and instrumentation. The cycle's own settings
/// (matrix update policy, momentum, line search) are solvers::FmgCycleParams: the cycle is solvers::FmgCycle, the
/// same one the CPU solver runs, and this pipeline is its device backend.
struct FmgSettings {
  int pre_smooth = 3, post_smooth = 3;
  bool chebyshev = true;        ///< Chebyshev-accelerated symmetric Gauss-Seidel smoothing
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

/// The device half of the nonlinear FMG of Wang 2018 §4.2: the objective, the model matrix and the multigrid with
/// every vector on one device (element kernels, BSR assembly, Galerkin products, multi-color Gauss-Seidel,
/// V-cycles, contact projection). solvers::FmgCuda runs solvers::FmgCycle over it. Vectors are numbered
/// 0..kVectors-1 (solvers::FmgBackend::Vec; vector 0 is the iterate), each of the objective's size, in the device's
/// own numbering. Built for one objective and hierarchy and kept across time steps (only the step's prediction, pin
/// targets and obstacle poses are uploaded per begin()).
class DeviceFmg {
 public:
  static constexpr int kVectors = 13;
  virtual ~DeviceFmg() = default;
  /// Starts a solve of `objective` from x (into vector 0): builds the device layout when the objective, the
  /// hierarchy or the objective's Hessian pattern changed (true then), and uploads the step's data. Throws
  /// InputError for an objective the pipeline cannot take.
  virtual bool begin(const physics::Objective& objective, const std::vector<const linalg::StencilTable*>& prolongations,
                     const VecX& x) = 0;
  /// Vector v in the problem's numbering (3n, xyz interleaved).
  virtual void download(int v, VecX& x) const = 0;

  virtual double energy(int x) = 0;
  virtual void gradient(int x, int g) = 0;
  /// Moves vertices inside obstacles onto their surfaces (§4.5); the number moved.
  virtual Index project(int x) = 0;
  virtual double dot(int a, int b) = 0;
  virtual void combine(int out, double a, int u, double b, int w) = 0;  ///< out = a·u + b·w
  virtual void scale(int out, double a, int u) = 0;                     ///< out = a·u
  virtual void weight(int out, double omega, int u, int prev) = 0;      ///< out = ω (u − prev) + prev
  virtual void copy(int to, int from) = 0;
  /// The PSD-projected Hessian at x into level 0 and its Galerkin hierarchy (smoothers, coarsest factorization).
  virtual void update_matrix(int x) = 0;
  virtual void multiply(int in, int out) = 0;  ///< out = A_0 in
  /// d = one linear V-cycle of the Galerkin hierarchy from zero on r; returns d·r.
  virtual double vcycle(int r, int d) = 0;
  /// c from zero by V-cycles on A_0 c = r until ‖r − A_0 c‖ <= tol (at most 30).
  virtual void newton_step(int r, int c, double tol) = 0;
  virtual void synchronize() = 0;
  /// What the pipeline measured since begin(): time per phase (setup, assembly, Galerkin, V-cycles), levels,
  /// graph launches, the adaptive smoother's skipped fraction, and the profile's and SpGEMM comparison's counters.
  virtual std::vector<std::pair<std::string, double>> counters() const = 0;

  /// The time step's end on the device, after a solve of the same objective (what bodies::ClothBody::finish_step
  /// does on the CPU): the solution (vector 0) projected out of the obstacles (§4.5), v = (x − x_old)/h, and the
  /// friction filter against the obstacles at the step's end (hd::filter_velocity). x and v come back in the
  /// problem's numbering.
  virtual void finish_step(const VecX& x_old, double h, VecX& x, VecX& v) = 0;
  /// "host" or the CUDA device's name.
  virtual std::string device() const = 0;
  /// The Chebyshev spectral radius of every level's sweep, finest first: estimated on the first matrix and kept for
  /// later solves, so a checkpoint holds them (empty before the first solve).
  virtual std::vector<double> smoother_radii() const = 0;
  /// Gives smoother_radii() back before the next solve; empty: estimate them afresh.
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
