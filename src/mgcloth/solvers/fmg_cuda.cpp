#include <mgcloth/core/error.hpp>
#include <mgcloth/solvers/fmg_cuda.hpp>

#include <cmath>

namespace mgcloth::solvers {

static_assert(cuda::DeviceFmg::kVectors == FmgBackend::NumVecs, "the device holds every vector of the cycle");

FmgCycleParams FmgCuda::device_cycle() {
  FmgCycleParams p;
  p.line_search_params.max_steps = 30;
  return p;
}

FmgCuda::FmgCuda(cuda::Backend backend, cuda::FmgSettings settings, FmgCycleParams cycle, std::string name)
    : m_name(std::move(name)), m_cycle(std::move(cycle)), m_impl(cuda::make_device_fmg(backend, settings)) {
  if (m_cycle.matrix_update == MatrixUpdate::Constant)
    throw InputError(m_name + ": matrix_update \"constant\" is not implemented on the device (use direction, cycle or step)");
  if (m_cycle.chebyshev_rho > 0.0 || !m_cycle.line_search)
    throw InputError(m_name + ": the device pipeline runs the cycle with a line search and without Chebyshev weights");
}

/// FmgCycle's backend on the device: every vector and operator is the pipeline's; what only the host objective
/// knows (the round-off of its sums) is measured on a copy of x, paid only by a solve that is stuck.
class FmgCuda::Backend final : public FmgBackend {
 public:
  Backend(cuda::DeviceFmg& d, const physics::Objective& objective, bool project)
      : m_d(d), m_obj(objective), m_project(project) {}
  double energy(Vec x) override { return m_d.energy(x); }
  void gradient(Vec x, Vec g) override { m_d.gradient(x, g); }
  bool has_projection() const override { return m_project; }
  Index project(Vec x) override { return m_project ? m_d.project(x) : 0; }
  double energy_magnitude(Vec x) override {
    double magnitude = 0.0;
    for (const auto& [name, value] : m_obj.term_values(host(x))) magnitude += std::abs(value);
    return magnitude;
  }
  bool at_roundoff_floor(Vec x, double gnorm, double* floor) override {
    return physics::at_roundoff_floor(m_obj, host(x), gnorm, floor);
  }
  double dot(Vec a, Vec b) override { return m_d.dot(a, b); }
  double norm(Vec a) override { return std::sqrt(m_d.dot(a, a)); }
  void combine(Vec out, double a, Vec u, double b, Vec w) override { m_d.combine(out, a, u, b, w); }
  void scale(Vec out, double a, Vec u) override { m_d.scale(out, a, u); }
  void weight(Vec out, double omega, Vec u, Vec prev) override { m_d.weight(out, omega, u, prev); }
  void copy(Vec to, Vec from) override { m_d.copy(to, from); }
  void take(Vec to, Vec from) override { m_d.copy(to, from); }
  bool update_matrix(Vec x) override {
    m_d.update_matrix(x);
    return true;
  }
  void multiply(Vec in, Vec out) override { m_d.multiply(in, out); }
  double correction(Index level, bool linear, int /*sweeps*/, Vec r, Vec d) override {
    if (level != 0 || !linear) throw Error("fmg-cuda: the device cycle takes one linear V-cycle from the finest level");
    return m_d.vcycle(r, d);
  }
  void newton_step(Vec r, Vec c, double tol) override { m_d.newton_step(r, c, tol); }
  // Two host copies of x per cycle, made whatever the stop rule; their cost on the device is not measured yet.
  void mark(Vec x) override { m_d.download(x, m_mark); }
  double max_distance_from_mark(Vec x) override { return max_vertex_distance(host(x), m_mark); }
  void synchronize() override { m_d.synchronize(); }
  std::vector<std::pair<std::string, double>> counters() const override { return m_d.counters(); }

 private:
  const VecX& host(Vec x) {
    m_d.download(x, m_host);
    return m_host;
  }
  cuda::DeviceFmg& m_d;
  const physics::Objective& m_obj;
  bool m_project;
  VecX m_host, m_mark;
};

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
  const Timer clock;
  if (!problem.objective) throw Error(m_name + ": the problem has no objective");
  if (problem.hierarchy.num_levels() < 2)
    throw InputError(m_name + ": needs a hierarchy of at least two levels (the cloth is too small to coarsen)");
  if (m_impl->begin(*problem.objective, problem.hierarchy.prolongations(), x)) m_beta.assign(1, 1.0);
  Backend backend(*m_impl, *problem.objective, static_cast<bool>(problem.project));
  FmgCycle::Counts counts;
  // The paper's configuration: every direction is one linear V-cycle from the finest level (§4.2).
  const SolveReport rep = FmgCycle::run(backend, m_name, m_cycle, {{0, true, 0}}, m_beta, stop, trace, counts, clock);
  m_impl->download(FmgBackend::X, x);
  return rep;
}

}  // namespace mgcloth::solvers
