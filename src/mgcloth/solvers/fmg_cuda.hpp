#pragma once
#include <mgcloth/cuda/device_fmg.hpp>
#include <mgcloth/solvers/fmg_cycle.hpp>

#include <memory>

namespace mgcloth::solvers {

/// "fmg-cuda": the nonlinear FMG of Wang 2018 (§4.2, the paper's configuration: one linear V-cycle of the Galerkin
/// hierarchy per search direction, Chebyshev-accelerated multi-color Gauss-Seidel, line search) with the whole
/// solve on the GPU (cuda::DeviceFmg): element kernels, BSR assembly, Galerkin products, smoothing, coarse
/// Cholesky, line search, contact projection and the step's friction filter. The cycle is FmgCycle, the one "fmg"
/// runs; the device pipeline is its backend. One iteration is one FMG cycle, as for "fmg". backend "host" runs the
/// same pipeline on the CPU (the kernels' check without a GPU; not a fast solver).
class FmgCuda final : public NonlinearSolver {
 public:
  /// Throws Error when backend is Cuda and no GPU is usable (the message says why: no CUDA in this build, no
  /// device, an old driver).
  /// `cycle`: the paper's configuration (one linear V-cycle per direction) with any matrix update but `constant`,
  /// no Chebyshev weights across corrections, a line search.
  FmgCuda(cuda::Backend backend, cuda::FmgSettings settings, FmgCycleParams cycle = device_cycle(),
          std::string name = "fmg-cuda");
  /// The cycle settings fmg-cuda starts from.
  static FmgCycleParams device_cycle();
  std::string name() const override { return m_name; }
  bool needs_hierarchy() const override { return true; }
  /// Its one direction per cycle is the V-cycle from the finest level, whose c·r is the Newton decrement (as "fmg").
  bool estimates_decrement() const override { return m_cycle.line_search; }
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
  class Backend;
  std::string m_name;
  FmgCycleParams m_cycle;
  std::unique_ptr<cuda::DeviceFmg> m_impl;
  std::vector<double> m_beta{1.0};  ///< the line search's starting scale (§4.2.3), kept while the layout is
};

}  // namespace mgcloth::solvers
