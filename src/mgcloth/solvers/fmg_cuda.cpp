#include <mgcloth/core/error.hpp>
#include <mgcloth/solvers/fmg_cuda.hpp>

namespace mgcloth::solvers {

FmgCuda::FmgCuda(cuda::Backend backend, cuda::FmgSettings settings, std::string name)
    : m_name(std::move(name)), m_impl(cuda::make_device_fmg(backend, settings)) {}

std::string FmgCuda::carried_state() const {
  const std::vector<double> radii = m_impl->smoother_radii();
  return radii.empty() ? std::string() : encode_carried_state("fmg-cuda", radii);
}

void FmgCuda::restore_carried_state(std::string_view state) {
  if (state.empty()) {
    m_impl->restore_smoother_radii({});
    return;
  }
  std::vector<double> radii = decode_carried_state("fmg-cuda", state);
  for (double rho : radii)
    if (!(rho >= 0.0 && rho < 1.0)) throw_input_error("{}: smoother spectral radius {} is not in [0, 1)", m_name, rho);
  if (radii.empty()) throw_input_error("{}: a solver state without levels", m_name);
  m_impl->restore_smoother_radii(std::move(radii));
}

SolveReport FmgCuda::minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) {
  if (!problem.objective) throw Error(m_name + ": the problem has no objective");
  if (problem.hierarchy.num_levels() < 2)
    throw InputError(m_name + ": needs a hierarchy of at least two levels (the cloth is too small to coarsen)");
  cuda::Limits limits;
  limits.rel_grad = stop.rel_grad;
  limits.abs_grad = stop.abs_grad;
  limits.max_iters = stop.max_iters;
  limits.max_seconds = stop.max_seconds;
  limits.interruptible = stop.interruptible;
  const cuda::Outcome out =
      m_impl->minimize(*problem.objective, problem.hierarchy.prolongations(), static_cast<bool>(problem.project), x, limits, trace != nullptr);
  if (trace)
    for (const cuda::Row& r : out.trace) trace->push_back({r.iteration, r.energy, r.grad_norm, r.wall_ms, r.step});
  SolveReport rep;
  rep.initial_grad_norm = out.initial_grad_norm;
  rep.status = out.status;
  rep.counters = out.counters;
  finish_report(rep, out.iterations, out.energy, out.grad_norm, out.target, out.wall_ms);
  return rep;
}

}  // namespace mgcloth::solvers
