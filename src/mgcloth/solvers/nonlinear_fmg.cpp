#include <mgcloth/core/error.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/solvers/cpu_backend.hpp>
#include <mgcloth/solvers/nonlinear_fmg.hpp>

#include <bit>
#include <cassert>
#include <cmath>

namespace mgcloth::solvers {

NonlinearFMG::NonlinearFMG(FmgParams params, std::string name) : m_params(std::move(params)), m_name(std::move(name)) {
  if (m_params.single_level) m_params.multigrid.factorize_coarsest = false;
  m_params.multigrid.adaptive_threshold = m_params.adaptive_threshold;
}

std::vector<FmgStage> NonlinearFMG::schedule(Index L) const {
  const int pre = m_params.multigrid.pre_smooth, post = m_params.multigrid.post_smooth;
  if (m_params.single_level) return {{0, false, pre}};
  std::vector<FmgStage> out;
  // One V-cycle from every level, coarsest first (Fig. 2b with one V-cycle per level, §4.2.1).
  for (Index top = m_params.interleave ? L - 1 : 0; top >= 0; --top) {
    const Index linear_from = std::max<Index>(top, std::min<Index>(m_params.residual_levels, L - 1));
    for (Index h = top; h < linear_from; ++h) out.push_back({h, false, pre});
    out.push_back({linear_from, true, 0});
    for (Index h = linear_from - 1; h >= top; --h) out.push_back({h, false, post});
  }
  return out;
}

namespace {
/// FNV-1a of a matrix's values, −0 counted as +0 (as the == that update_constant_matrix compares with does).
std::uint64_t constant_matrix_hash(const linalg::BlockMatrix3& A) {
  std::uint64_t h = 1469598103934665603ull;
  for (const Mat3& b : A.blocks())
    for (Index i = 0; i < 9; ++i) {
      const auto bits = std::bit_cast<std::uint64_t>(b.data()[i] + 0.0);
      for (int k = 0; k < 8; ++k) h = (h ^ ((bits >> (8 * k)) & 0xffu)) * 1099511628211ull;
    }
  return h;
}

constexpr std::string_view kStateTag = "fmg";
}  // namespace

// Layout: L, the L radii, the L line-search scales, 1 and the matrix hash's bits (a constant matrix) or 0 and 0.
std::string NonlinearFMG::carried_state() const {
  if (!m_mg) return {};  // no solve yet: a fresh solver
  std::vector<double> v{static_cast<double>(m_mg->num_levels())};
  for (double rho : m_mg->smoother_rhos()) v.push_back(rho);
  v.insert(v.end(), m_beta.begin(), m_beta.end());
  const bool constant = m_params.matrix_update == MatrixUpdate::Constant && m_have_matrix;
  v.push_back(constant ? 1.0 : 0.0);
  v.push_back(constant ? std::bit_cast<double>(constant_matrix_hash(m_A)) : 0.0);
  return encode_carried_state(kStateTag, v);
}

void NonlinearFMG::restore_carried_state(std::string_view state) {
  m_restore.clear();
  if (state.empty()) {
    m_mg.reset();  // as a fresh solver: the radii are estimated on the next matrix
    return;
  }
  std::vector<double> v = decode_carried_state(kStateTag, state);
  const bool fits = v.size() >= 3 && v[0] >= 1.0 && v[0] <= 64.0 && v[0] == std::floor(v[0]) &&
                    v.size() == 2 * static_cast<size_t>(v[0]) + 3;
  if (!fits) throw_input_error("{}: a solver state of {} values that does not describe a multigrid", m_name, v.size());
  for (size_t l = 0; l < static_cast<size_t>(v[0]); ++l) {
    const double beta = v[1 + static_cast<size_t>(v[0]) + l];
    if (!(beta > 0.0 && beta <= 1.0)) throw_input_error("{}: line-search scale {} is not in (0, 1]", m_name, beta);
  }
  m_restore = std::move(v);
}

/// FmgCycle's backend on the CPU: the solver's LinearMultigrid and matrix, its matrix update policy for a constant
/// matrix, and its time per phase.
class NonlinearFMG::Backend final : public CpuVectors {
 public:
  Backend(NonlinearFMG& fmg, const Problem& problem)
      : CpuVectors(*problem.objective, problem.project, &fmg.m_A), m_fmg(fmg), m_mg(*fmg.m_mg),
        m_rl(static_cast<size_t>(m_mg.num_levels())), m_cl(static_cast<size_t>(m_mg.num_levels())) {}

  bool update_matrix(Vec xv) override {
    NonlinearFMG& f = m_fmg;
    Stats& st = f.m_stats;
    const VecX& x = (*this)[xv];
    Timer t;
    bool changed = true;
    if (f.m_params.matrix_update == MatrixUpdate::Constant) {
      changed = update_constant_matrix(m_obj, x, f.m_have_matrix, f.m_params.project_psd, f.m_A, f.m_scratch);
      st.assembly_ms += t.ms();
      const bool restored = f.m_restored_matrix.has_value();
      if (restored) {
        // The hierarchy must be built either way; whether the model is new is what the writer's matrix says.
        changed = constant_matrix_hash(f.m_A) != *f.m_restored_matrix;
        f.m_restored_matrix.reset();
      }
      logger().debug("{}: constant matrix {}{}", f.m_name, changed ? "changed" : "unchanged", restored ? " (restored)" : "");
      if (!changed && !restored) return false;  // e.g. the same contact set: keep the hierarchy and its factors
    } else {
      m_obj.hessian_reusing_constant(x, f.m_A, f.m_params.project_psd, f.m_constant);
      st.assembly_ms += t.ms();
    }
    Timer tg;
    // The constant blocks are promised only for matrices that hessian_reusing_constant filled.
    const bool split = f.m_params.matrix_update != MatrixUpdate::Constant &&
                       m_obj.variable_blocks().size() < m_obj.constant_blocks().size();
    if (split) m_mg.set_matrix(f.m_A, &m_obj.constant_blocks(), m_obj.pattern_stamp());
    else m_mg.set_matrix(f.m_A);
    st.galerkin_ms += tg.ms();
    f.m_have_matrix = true;
    return changed;
  }

  void multiply(Vec in, Vec out) override {
    if (!m_fmg.m_have_matrix) throw_error("multiply: this solve has no model matrix");
    m_mg.multiply(0, (*this)[in], (*this)[out]);
  }

  double correction(Index level, bool linear, int sweeps, Vec rv, Vec dv) override {
    Stats& st = m_fmg.m_stats;
    Timer tt;
    const VecX* rh = &(*this)[rv];
    for (Index l = 0; l < level; ++l) {
      m_mg.restrict_to(l, *rh, m_rl[l + 1]);
      rh = &m_rl[l + 1];
    }
    st.transfer_ms += tt.ms();
    VecX& c = m_cl[level];
    c.setZero(rh->size());
    Timer ts;
    if (!linear) {
      const double threshold = m_fmg.m_params.adaptive_threshold;
      const std::vector<char>* m = nullptr;
      const Index n = m_mg.level_size(level);
      if (threshold > 0.0) {
        const double rms = rh->norm() / std::sqrt(static_cast<double>(std::max<Index>(1, n)));
        const Index active = linalg::adaptive_mask(*rh, threshold * rms, m_mask);
        st.rows_skipped += static_cast<double>(n - active) * 2.0 * sweeps;
        st.rows_relaxed += static_cast<double>(active) * 2.0 * sweeps;
        m = &m_mask;
      } else {
        st.rows_relaxed += static_cast<double>(n) * 2.0 * sweeps;
      }
      m_mg.smooth(level, *rh, c, sweeps, m);
      st.smoothing_ms += ts.ms();
    } else {
      m_mg.vcycle(level, *rh, c);
      st.linear_ms += ts.ms();
    }
    const double cr = c.dot(*rh);
    if (!(cr > 0.0)) return cr;
    Timer tp;
    VecX& d = (*this)[dv];
    const VecX* dh = &c;
    for (Index l = level - 1; l >= 0; --l) {
      m_mg.prolong(l, *dh, l == 0 ? d : m_rl[l]);
      dh = l == 0 ? &d : &m_rl[l];
    }
    if (level == 0) d = c;
    st.transfer_ms += tp.ms();
    return cr;
  }

  void newton_step(Vec rv, Vec cv, double tol) override {
    const VecX& r = (*this)[rv];
    VecX& c = (*this)[cv];
    c.setZero(r.size());
    VecX Ac;
    for (int it = 0; it < 30; ++it) {
      if (m_fmg.m_params.single_level) m_mg.smooth(0, r, c, 20);  // no coarse levels to cycle through
      else m_mg.vcycle(r, c);
      m_mg.multiply(0, c, Ac);
      if ((r - Ac).norm() <= tol) break;
    }
  }

  std::vector<std::pair<std::string, double>> counters() const override {
    Stats& st = m_fmg.m_stats;
    // Relaxations inside the linear V-cycles (counted only when the adaptive smoother is on).
    st.rows_relaxed += m_mg.rows_active();
    st.rows_skipped += m_mg.rows_total() - m_mg.rows_active();
    const double relaxations = st.rows_relaxed + st.rows_skipped;
    return {{"skipped_fraction", relaxations > 0.0 ? st.rows_skipped / relaxations : 0.0},
            {"assembly_ms", st.assembly_ms},
            {"galerkin_ms", st.galerkin_ms},
            {"smoothing_ms", st.smoothing_ms},
            {"linear_ms", st.linear_ms},
            {"transfer_ms", st.transfer_ms}};
  }

 private:
  NonlinearFMG& m_fmg;
  LinearMultigrid& m_mg;
  std::vector<VecX> m_rl, m_cl;  ///< per level: restricted residuals (and prolonged corrections), corrections
  std::vector<char> m_mask;
};

void NonlinearFMG::prepare(const Problem& problem) {
  const auto prolongations = problem.hierarchy.prolongations();
  if (!m_mg || m_mg_for != prolongations) {
    const auto& levels = m_params.single_level ? std::vector<const linalg::StencilTable*>{} : prolongations;
    m_mg = std::make_unique<LinearMultigrid>(levels, problem.objective->hessian_pattern(), m_params.multigrid);
    m_mg_for = prolongations;
    m_have_matrix = false;
    m_beta.assign(static_cast<size_t>(m_mg->num_levels()), 1.0);
  }
  const Index L = m_mg->num_levels();
  if (!m_restore.empty()) {
    const std::vector<double> state = std::move(m_restore);
    m_restore.clear();
    if (state[0] != static_cast<double>(L))
      throw_input_error("{}: a solver state for {} levels, the cloth's hierarchy has {}", m_name, state[0], L);
    m_mg->set_smoother_rhos({state.begin() + 1, state.begin() + 1 + L});
    m_beta.assign(state.begin() + 1 + L, state.begin() + 1 + 2 * L);
    m_have_matrix = false;
    m_restored_matrix.reset();
    if (state[1 + 2 * L] != 0.0) m_restored_matrix = std::bit_cast<std::uint64_t>(state[2 + 2 * L]);
  }
  m_mg->reset_adaptive_stats();
}

SolveReport NonlinearFMG::minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) {
  const Timer clock;
  m_stats = Stats{};
  prepare(problem);
  Backend backend(*this, problem);
  backend[FmgBackend::X].swap(x);
  SolveReport rep;
  try {
    rep = FmgCycle::run(backend, m_name, m_params.cycle(), schedule(m_mg->num_levels()), m_beta, stop, trace, m_stats, clock);
  } catch (...) {
    x.swap(backend[FmgBackend::X]);
    throw;
  }
  x.swap(backend[FmgBackend::X]);
  return rep;
}

}  // namespace mgcloth::solvers
