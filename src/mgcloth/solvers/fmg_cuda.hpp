#pragma once
#include <mgcloth/cuda/device_fmg.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

#include <memory>

namespace mgcloth::solvers {

/// "fmg-cuda": the nonlinear FMG of Wang 2018 (§4.2, the paper's configuration: one linear V-cycle of the Galerkin
/// hierarchy per search direction, Chebyshev-accelerated multi-color Gauss-Seidel, line search) with the whole
/// solve on the GPU (cuda::DeviceFmg): element kernels, BSR assembly, Galerkin products, smoothing, coarse
/// Cholesky, line search, contact projection and the step's friction filter. One iteration is one FMG cycle, as for "fmg". backend "host" runs
/// the same pipeline on the CPU (the kernels' check without a GPU; not a fast solver).
class FmgCuda final : public NonlinearSolver {
 public:
  /// Throws Error when backend is Cuda and no GPU is usable (the message says why: no CUDA in this build, no
  /// device, an old driver).
  FmgCuda(cuda::Backend backend, cuda::FmgSettings settings, std::string name = "fmg-cuda");
  std::string name() const override { return m_name; }
  bool needs_hierarchy() const override { return true; }
  /// The device pipeline has kernels for the elastic terms only.
  std::vector<physics::EnergyForm> energy_forms() const override { return {physics::EnergyForm::Elastic}; }
  /// Counters: those of "fmg" (directions, energy evaluations, matrix updates, time per phase) plus setup_ms.
  SolveReport minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) override;
  /// On the device: projection, velocity and friction filter (cuda::DeviceFmg::finish_step).
  bool finish_step(const VecX& x_old, double h, VecX& x, VecX& v) override {
    m_impl->finish_step(x_old, h, x, v);
    return true;
  }
  std::string device() const { return m_impl->device(); }
  /// The Chebyshev radii of every level (cuda::DeviceFmg::smoother_radii).
  std::string carried_state() const override;
  void restore_carried_state(std::string_view state) override;

 private:
  std::string m_name;
  std::unique_ptr<cuda::DeviceFmg> m_impl;
};

}  // namespace mgcloth::solvers
