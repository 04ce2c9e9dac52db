#include <mgcloth/core/error.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/linalg/galerkin.hpp>
#include <mgcloth/solvers/line_search.hpp>
#include <mgcloth/solvers/rmtr.hpp>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace mgcloth::solvers {

struct Rmtr::Level {
  const physics::Objective* f = nullptr;
  const linalg::StencilTable* S = nullptr;  ///< prolongation from the level below to this one (null: coarsest)
  hierarchy::Projection project;                  ///< iterates from this level to the level below
  linalg::BlockMatrix3 norm_matrix;             ///< M_l = Iᵀ D I of eq. 4.9 (D on the finest: I, or the scaling)
  std::unique_ptr<linalg::NormMetric> metric;   ///< null where the norm is ℓ2
  std::unique_ptr<linalg::GalerkinProduct> rap; ///< norm_matrix of this level → the level below's (symbolic, once)
  // Second-order coarse models: this level's model Hessian, its Galerkin product for the level below, and (as the
  // level below) the correction δH = Sᵀ H S − ∇²f(x₀) in the pattern of ∇²f.
  std::unique_ptr<linalg::GalerkinProduct> hessian_rap;
  long rap_pattern = -1;  ///< the level objective's pattern version hessian_rap was built for
  linalg::BlockMatrix3 model_hessian, galerkin, delta_h;
  std::unique_ptr<LocalTrustRegion> tr;
  VecX last_end;  ///< as the level below: where its last visit of this solve ended (coarse_start "best")
  double norm(const VecX& s) const { return metric ? metric->norm(s) : s.norm(); }
};

Rmtr::Rmtr(RmtrParams params, std::string name) : m_params(std::move(params)), m_name(std::move(name)) {
  if (m_params.coarse_model != "first_order" && m_params.coarse_model != "second_order")
    throw_error("{}: coarse_model must be \"first_order\" or \"second_order\" (got \"{}\")", m_name, m_params.coarse_model);
  if (m_params.scaling != "none" && m_params.scaling != "jacobi" && m_params.scaling != "block_jacobi")
    throw_error("{}: scaling must be \"none\", \"jacobi\" or \"block_jacobi\" (got \"{}\")", m_name, m_params.scaling);
  if (m_params.initial != "fine" && m_params.initial != "nested")
    throw_error("{}: initial must be \"fine\" or \"nested\" (got \"{}\")", m_name, m_params.initial);
  if (m_params.projection != "reverse_subdivision" && m_params.projection != "least_squares")
    throw_error("{}: projection must be \"reverse_subdivision\" or \"least_squares\" (got \"{}\")", m_name,
                m_params.projection);
  if (m_params.coarse_start != "projection" && m_params.coarse_start != "best")
    throw_error("{}: coarse_start must be \"projection\" or \"best\" (got \"{}\")", m_name, m_params.coarse_start);
}

Rmtr::~Rmtr() = default;

namespace {

/// The identity as a block-diagonal matrix: the ℓ2 norm of the finest level, M_L of eq. 4.9.
linalg::BlockMatrix3 identity_blocks(Index n) {
  std::vector<std::pair<Index, Index>> pairs;
  for (Index i = 0; i < n; ++i) pairs.push_back({i, i});
  linalg::BlockMatrix3 M(n, std::move(pairs));
  for (Index i = 0; i < n; ++i) M.block(M.diagonal(i)) = Mat3::Identity();
  return M;
}
}  // namespace

void Rmtr::setup(const Problem& problem) {
  const hierarchy::Hierarchy& H = problem.hierarchy;
  const size_t available = std::max<size_t>(1, H.num_levels());
  if (available > 1 && !H.has_objectives())
    throw Error(fmt::format("{}: the problem's hierarchy has {} levels but no coarse objectives (the simulation must "
                            "rediscretize the step on every level)", m_name, available));
  const bool lsq = m_params.projection == "least_squares";
  if (available > 1 && !H.has_projections(lsq))
    throw Error(fmt::format("{}: the problem provides no {} projection for its {} levels", m_name, m_params.projection,
                            available));
  const auto projection = [&](size_t k) { return lsq ? H.levels[k].project_lsq : H.levels[k].project; };
  const size_t used = m_params.levels > 0 ? std::min(available, static_cast<size_t>(m_params.levels)) : available;
  if (used < 2)
    throw Error(fmt::format("{}: needs at least two levels, the problem has {} (a shell of level 1, or a solver "
                            "block that did not ask for the hierarchy); use tr-dogleg on a single level",
                            m_name, available));

  std::vector<const void*> key{problem.objective};
  for (size_t k = 0; k + 1 < used; ++k) {
    key.push_back(H.levels[k + 1].objective);
    key.push_back(H.levels[k].prolongation);
  }
  if (key == m_key && m_levels.size() == used) {
    // Same hierarchy: keep the norm matrices and Local_TR objects; the projections may capture new state.
    for (size_t i = 1; i < used; ++i) m_levels[i]->project = projection(used - 1 - i);
    return;
  }
  m_key = key;
  m_levels.clear();
  m_levels.resize(used);
  // Internal numbering: 0 the coarsest used level, used - 1 the finest (the paper's l); problem level k = used-1-i.
  for (size_t i = 0; i < used; ++i) {
    const size_t k = used - 1 - i;
    auto lv = std::make_unique<Level>();
    lv->f = k == 0 ? problem.objective : H.levels[k].objective;
    if (i > 0) {
      lv->S = H.levels[k].prolongation;
      lv->project = projection(k);
      if (lv->S->num_rows * 3 != lv->f->num_dofs())
        throw Error(fmt::format("{}: level {}: the prolongation has {} fine points, the objective {} dofs", m_name, k,
                                lv->S->num_rows, lv->f->num_dofs()));
      if (lv->S->t_offsets.empty()) throw Error(fmt::format("{}: level {}: prolongation without transpose", m_name, k));
    }
    TrustRegionParams tp = m_params.tr;
    tp.qp = i == 0 ? m_params.coarsest_qp : m_params.smoother_qp;
    if (i > 0 && tp.qp == TrQp::SteihaugCg) {
      // A fixed budget of CG iterations (§7.3): the tolerance only stops CG at an exact solve.
      tp.stcg_max_iters = m_params.smoother_cg_iters;
      tp.stcg_rel_tol = 1e-12;
    }
    lv->tr = std::make_unique<LocalTrustRegion>(tp, fmt::format("{} level {}", m_name, k));
    if (tp.qp == TrQp::Schwarz) {
      const auto* patches = k < H.num_levels() ? H.levels[k].patches : nullptr;
      if (!patches)
        throw Error(fmt::format("{}: the Schwarz smoother needs patches, which the problem does not provide", m_name));
      lv->tr->set_patches(*patches);
    }
    m_levels[i] = std::move(lv);
  }
  // Eq. 4.9: ‖s‖_l = ‖I_{L-1}^L ⋯ I_l^{l+1} s‖₂, i.e. M_l = S_{l+1}ᵀ M_{l+1} S_{l+1} from M_L = I; built once per
  // hierarchy (Galerkin products of the fixed tables) and factorized once.
  m_levels[used - 1]->norm_matrix = identity_blocks(m_levels[used - 1]->f->num_dofs() / 3);
  for (size_t i = used - 1; i-- > 0;) {
    Level& fine = *m_levels[i + 1];
    const linalg::StencilTable& S = *fine.S;
    fine.rap = std::make_unique<linalg::GalerkinProduct>(fine.norm_matrix, S);
    fine.rap->compute(fine.norm_matrix, m_levels[i]->norm_matrix);  // the pattern the next level's product needs
  }
  update_norms(false);
}

void Rmtr::update_norms(bool finest_scaled) {
  const size_t used = m_levels.size();
  Level& top = *m_levels[used - 1];
  top.metric = finest_scaled ? std::make_unique<linalg::NormMetric>(top.norm_matrix) : nullptr;
  for (size_t i = used - 1; i-- > 0;) {
    const Level& fine = *m_levels[i + 1];
    fine.rap->compute(fine.norm_matrix, m_levels[i]->norm_matrix);
    m_levels[i]->metric =
        m_params.level_norms ? std::make_unique<linalg::NormMetric>(m_levels[i]->norm_matrix) : nullptr;
  }
}

void Rmtr::scale_finest(const VecX& x) {
  // A fixed diagonal scaling of the finest level for the whole solve: D = diag(d_i I₃) with d_i the mean diagonal
  // entry of the Hessian's block at the start (floored, so that D is SPD where a block is indefinite). The ST-CG
  // smoother is then Jacobi-preconditioned and the finest trust region is the ellipsoid ‖s‖_D ≤ Δ (Conn-Gould-
  // Toint §6.7); the coarse norms (4.9) follow as Iᵀ D I.
  Level& top = *m_levels.back();
  top.f->hessian(x, m_scaling_hessian, /*project_psd=*/false);
  ++m_counters.back().hessian_assemblies;
  const Index n = top.norm_matrix.rows();
  if (m_params.scaling == "block_jacobi") {
    // D_i = the 3x3 diagonal block itself, its eigenvalues floored: it separates a point's in-plane (membrane)
    // and normal (bending) stiffness, which differ by (h/t)² and which a scalar scaling cannot tell apart.
    double emax = 0.0;
    std::vector<Eigen::SelfAdjointEigenSolver<Mat3>> eig(static_cast<size_t>(n));
    for (Index i = 0; i < n; ++i) {
      eig[static_cast<size_t>(i)].compute(m_scaling_hessian.block(m_scaling_hessian.diagonal(i)));
      emax = std::max(emax, eig[static_cast<size_t>(i)].eigenvalues().maxCoeff());
    }
    if (!(emax > 0.0)) throw SolveError(fmt::format("{}: the Hessian has no positive diagonal to scale by", m_name));
    for (Index i = 0; i < n; ++i) {
      const auto& e = eig[static_cast<size_t>(i)];
      const Vec3 lambda = e.eigenvalues().cwiseMax(1e-8 * emax);
      top.norm_matrix.block(top.norm_matrix.diagonal(i)) = e.eigenvectors() * lambda.asDiagonal() * e.eigenvectors().transpose();
    }
    update_norms(true);
    return;
  }
  std::vector<double> d(static_cast<size_t>(n));
  double dmax = 0.0;
  for (Index i = 0; i < n; ++i) {
    const Mat3& b = m_scaling_hessian.block(m_scaling_hessian.diagonal(i));
    d[static_cast<size_t>(i)] = b.trace() / 3.0;
    dmax = std::max(dmax, d[static_cast<size_t>(i)]);
  }
  if (!(dmax > 0.0)) throw SolveError(fmt::format("{}: the Hessian has no positive diagonal to scale by", m_name));
  for (Index i = 0; i < n; ++i)
    top.norm_matrix.block(top.norm_matrix.diagonal(i)) = std::max(d[static_cast<size_t>(i)], 1e-8 * dmax) * Mat3::Identity();
  update_norms(true);
}

/// One visit of a level (Alg. 4.2 on level l): its model h_l, the control of its Local_TR runs, its radius and the
/// model's value at the current iterate.
struct Rmtr::Visit {
  int l = 0;
  Level& L;
  RmtrLevelCounters& C;
  /// "finest" is the top of the current V-cycles: the finest level, or a coarser one during nested iteration.
  bool finest = false, coarsest = false, really_finest = false;
  VecX x0{};  ///< where the visit started
  std::unique_ptr<LevelModel> h{};
  LocalTrControl c{};
  double f0 = 0.0;      ///< h_l(x₀) on a coarse level
  double radius = 0.0;  ///< Δ^l
  double fx = 0.0;      ///< h_l at the current iterate
  CycleResult out{};
};

namespace {
/// δH = Sᵀ ∇²h_{l+1} S − ∇²f_l(x₀) in the pattern of ∇²f_l: `delta_h` holds ∇²f_l(x₀) on entry, `galerkin` the
/// Galerkin operator (whose blocks outside that pattern are not part of the model).
void galerkin_difference(const linalg::BlockMatrix3& galerkin, linalg::BlockMatrix3& delta_h) {
  const auto& rows = delta_h.row_offsets();
  const auto& cols = delta_h.col_indices();
  for (Index i = 0; i < delta_h.rows(); ++i)
    for (Index k = rows[i]; k < rows[i + 1]; ++k) {
      const Index kg = galerkin.find(i, cols[k]);
      const Mat3 gk = kg >= 0 ? galerkin.block(kg) : Mat3::Zero();
      delta_h.block(k) = gk - delta_h.block(k);
    }
}
}  // namespace

void Rmtr::build_model(Visit& v, const VecX* restricted, const linalg::BlockMatrix3* galerkin, double parent_radius,
                       const LocalTrControl& base) {
  Level& L = v.L;
  v.c = base;
  v.c.metric = L.metric.get();
  if (v.finest) {
    v.h = std::make_unique<LevelModel>(*L.f);
    v.radius = m_radius;
    if (m_start_gradient) {
      v.c.start_energy = &m_finest_energy;
      v.c.start_gradient = m_start_gradient;
    }
    return;
  }
  VecX g0;
  v.f0 = L.f->value(v.x0);
  L.f->gradient(v.x0, g0);
  ++v.C.energy_evaluations;
  ++v.C.gradient_assemblies;
  if (galerkin) {
    // Second order (beyond the paper): ∇²h(x₀) = Sᵀ ∇²h_{l+1} S, the Galerkin operator, so that near a minimizer
    // the V-cycle is a two-grid method with the exact coarse operator whatever the coarse state's strains.
    L.f->hessian(v.x0, L.delta_h, /*project_psd=*/false);
    ++v.C.hessian_assemblies;
    galerkin_difference(*galerkin, L.delta_h);
    v.h = std::make_unique<LevelModel>(*L.f, *restricted - g0, v.x0, &L.delta_h);
  } else {
    v.h = std::make_unique<LevelModel>(*L.f, *restricted - g0, v.x0);
  }
  v.c.start_energy = &v.f0;
  v.c.start_gradient = restricted;
  v.c.rel_grad = 0.0;
  v.c.abs_grad = m_params.coarse_abs_grad > 0.0 ? m_params.coarse_abs_grad : base.abs_grad;
  v.c.project = nullptr;
  v.c.trace = nullptr;
  v.radius = parent_radius;
  // Alg. 4.3, lines 3-7: what is left of the fine radius for this level's further steps. (The printed
  // condition of line 4 is inverted; the text says δ = 0 exactly when no room is left.)
  v.c.radius_cap = [this, &L, &x0 = v.x0, parent_radius](const VecX& xi, double r) {
    const double d = L.norm(xi - x0);
    return d < (1.0 - m_params.eps_delta) * parent_radius ? std::min(r, parent_radius - d) : 0.0;
  };
}

void Rmtr::record(const Visit& v, double energy) {
  if (v.really_finest && (m_finest_energies.empty() || energy != m_finest_energies.back()))
    m_finest_energies.push_back(energy);
}

void Rmtr::note_finest(const Visit& v, const LocalTrResult& r) {
  if (!v.finest) return;
  m_finest_energy = v.fx;
  if (r.status == "stalled") m_finest_stalled = true;
  if (r.iterations > 0) m_finest_newton = v.L.tr->history().back().newton;
  if (r.status == "stagnated") m_finest_stagnated = true;
  record(v, v.fx);
}

Rmtr::CycleResult Rmtr::finish(Visit& v, bool converged) {
  v.out.h_end = v.fx;
  v.out.converged = converged;
  if (v.finest) m_radius = v.radius;
  return v.out;
}

LocalTrResult Rmtr::pre_smooth(Visit& v, VecX& x) {
  Level& L = v.L;
  v.c.max_iters = v.coarsest ? (m_params.coarsest_iters > 0 ? m_params.coarsest_iters : m_params.pre_smoothing)
                             : m_params.pre_smoothing;
  const LocalTrResult r1 = L.tr->run(*v.h, x, v.radius, v.c);
  if (!v.finest)
    logger().debug("rmtr level {} pre-smoothing: {} after {} iterations, |g| {:.3e} -> {:.3e} (target {:.3e}), h {:.6e}",
                   v.l, r1.status, r1.iterations, r1.initial_grad_norm, r1.grad_norm, r1.grad_target,
                   r1.initial_energy);
  v.out.h_start = r1.initial_energy;
  v.out.h_end = r1.energy;
  v.fx = r1.energy;
  if (v.finest) m_start_gradient = &L.tr->gradient();
  note_finest(v, r1);
  return r1;
}

VecX Rmtr::coarse_start(int l, const VecX& x) {
  Level& L = *m_levels[static_cast<size_t>(l)];
  Level& Lc = *m_levels[static_cast<size_t>(l - 1)];
  VecX xc0;
  L.project(x, xc0);
  if (m_params.coarse_start == "best" && Lc.last_end.size() == xc0.size()) {
    // Any x₀ keeps first-order consistency (4.5), the correction being S(x − x₀); the lower coarse energy is the
    // start whose model round-off does not swamp.
    const double e_proj = Lc.f->value(xc0), e_kept = Lc.f->value(Lc.last_end);
    m_counters[static_cast<size_t>(l - 1)].energy_evaluations += 2;
    if (e_kept < e_proj || !std::isfinite(e_proj)) {
      xc0 = Lc.last_end;
      ++m_counters[static_cast<size_t>(l - 1)].starts_kept;
    }
  }
  return xc0;
}

const linalg::BlockMatrix3* Rmtr::coarse_galerkin(Visit& v, const VecX& x) {
  if (m_params.coarse_model != "second_order") return nullptr;
  Level& L = v.L;
  v.h->hessian(x, L.model_hessian);
  ++v.C.hessian_assemblies;
  if (!L.hessian_rap || L.rap_pattern != L.f->pattern_version()) {
    L.hessian_rap = std::make_unique<linalg::GalerkinProduct>(L.model_hessian, *L.S);
    L.rap_pattern = L.f->pattern_version();
  }
  L.hessian_rap->compute(L.model_hessian, L.galerkin);
  return &L.galerkin;
}

bool Rmtr::coarse_correction(Visit& v, VecX& x, const LocalTrControl& base) {
  VecX gc;
  v.L.S->apply_transpose(v.L.tr->gradient(), gc);
  const VecX xc0 = coarse_start(v.l, x);
  VecX xc = xc0;
  const linalg::BlockMatrix3* galerkin = coarse_galerkin(v, x);
  const CycleResult rc = visit(v.l - 1, xc, &gc, galerkin, v.radius, base);
  if (m_params.coarse_start == "best") m_levels[static_cast<size_t>(v.l - 1)]->last_end = xc;
  return test_correction(v, x, xc0, xc, rc);
}

bool Rmtr::test_correction(Visit& v, VecX& x, const VecX& xc0, const VecX& xc, const CycleResult& rc) {
  const TrustRegionParams& p = m_params.tr;
  RmtrCorrection corr;
  corr.level = v.l;
  corr.coarse_reduction = rc.h_start - rc.h_end;
  corr.radius = v.radius;
  bool moved = false;
  if (corr.coarse_reduction > 0.0) {
    VecX s;
    v.L.S->apply(VecX(xc - xc0), s);
    corr.step_norm = v.L.norm(s);
    VecX trial = x + s;
    double ft = v.h->value(trial);
    ++v.C.energy_evaluations;
    corr.fine_reduction = v.fx - ft;
    corr.rho = std::isfinite(ft) ? corr.fine_reduction / corr.coarse_reduction : -kInf;
    corr.accepted = corr.rho > p.eta1;
    if (!corr.accepted && m_params.correction_backtracking > 0) backtrack_correction(v, x, s, corr, trial, ft);
    if (corr.accepted) {
      x.swap(trial);
      v.fx = ft;
      moved = true;
      ++v.C.corrections_accepted;
      record(v, v.fx);
    } else {
      ++v.C.corrections_rejected;
    }
    // Line 12: Radius_update on this level, still bounded by the parent's radius.
    v.radius = radius_update(p, corr.rho, v.radius, corr.step_norm);
    if (v.c.radius_cap) v.radius = v.c.radius_cap(x, v.radius);
  }
  logger().debug("rmtr level {}: coarse reduction {:.3e}, fine {:.3e}, rho {:+.3e}, |s| {:.3e} of {:.3e}, {}", v.l,
                 corr.coarse_reduction, corr.fine_reduction, corr.rho, corr.step_norm, corr.radius,
                 !corr.accepted ? "rejected" : corr.fraction < 1.0 ? fmt::format("accepted at α = {}", corr.fraction)
                                                                    : std::string("accepted"));
  m_corrections.push_back(corr);
  return moved;
}

void Rmtr::backtrack_correction(Visit& v, const VecX& x, const VecX& s, RmtrCorrection& corr, VecX& trial,
                                double& ft) {
  const double slope = v.L.tr->gradient().dot(s);  // ∇hᵀs at x, where pre-smoothing left the gradient
  if (!(slope < 0.0)) return;
  LineSearchParams ls;  // α = ½, ¼, … with the trust region's own acceptance constant
  ls.armijo = m_params.tr.eta1;
  ls.max_steps = m_params.correction_backtracking;
  const LineSearchResult r = backtrack(
      [&](double alpha) {
        trial = x + alpha * s;
        ++v.C.energy_evaluations;
        return v.h->value(trial);
      },
      v.fx, slope, 0.5, ls);
  if (!r.success) return;
  corr.accepted = true;
  corr.fraction = r.alpha;
  ft = r.energy;
  ++v.C.corrections_backtracked;
}

Rmtr::CycleResult Rmtr::post_smooth(Visit& v, VecX& x, bool moved) {
  LocalTrControl c2 = v.c;
  c2.max_iters = v.coarsest ? (m_params.coarsest_iters > 0 ? 0 : m_params.post_smoothing) : m_params.post_smoothing;
  double f_here = v.fx;
  if (!moved) {
    // x is where pre-smoothing ended: its energy and gradient are known.
    c2.start_energy = &f_here;
    c2.start_gradient = &v.L.tr->gradient();
  } else {
    c2.start_energy = nullptr;
    c2.start_gradient = nullptr;
  }
  if (c2.max_iters == 0 && !moved) return finish(v, false);
  const LocalTrResult r2 = v.L.tr->run(*v.h, x, v.radius, c2);
  v.fx = r2.energy;
  note_finest(v, r2);
  if (r2.status == "radius_exhausted") ++v.C.radius_exhausted;
  return finish(v, r2.status == "converged");
}

Rmtr::CycleResult Rmtr::visit(int l, VecX& x, const VecX* restricted, const linalg::BlockMatrix3* galerkin,
                               double parent_radius, const LocalTrControl& base) {
  Visit v{.l = l,
          .L = *m_levels[static_cast<size_t>(l)],
          .C = m_counters[static_cast<size_t>(l)],
          .finest = l == m_top,
          .coarsest = l == 0,
          .really_finest = l == static_cast<int>(m_levels.size()) - 1,
          .x0 = x};
  ++v.C.visits;

  // Line 1: the level's model h_l (eq. 4.3) with δg of eq. 4.4; its gradient at x₀ is the restricted one (4.5).
  build_model(v, restricted, galerkin, parent_radius, base);

  // Line 2: pre-smoothing.
  const LocalTrResult r1 = pre_smooth(v, x);
  if (r1.status == "converged") return finish(v, true);
  if (r1.status == "radius_exhausted") {
    ++v.C.radius_exhausted;
    return finish(v, false);
  }
  if (r1.status == "time_limit") return finish(v, false);

  bool moved = false;
  if (!v.coarsest) {
    // Lines 4-12: the coarse correction from x^{l-1}_0 = P x (eq. 4.6) with the restricted gradient, in the
    // current radius (eq. 4.8), prolongated (eq. 4.10) and tested by the multilevel ratio (eq. 4.11).
    moved = coarse_correction(v, x, base);
    if (!(v.radius > 0.0)) {
      ++v.C.radius_exhausted;
      return finish(v, false);
    }
  }

  // Lines 13-17: post-smoothing; its first test is the termination of line 13.
  return post_smooth(v, x, moved);
}

void Rmtr::accumulate() {
  for (size_t i = 0; i < m_levels.size(); ++i) {
    const TrCounters& t = m_levels[i]->tr->counters();
    RmtrLevelCounters& C = m_counters[i];
    C.dofs = m_levels[i]->f->num_dofs();
    C.hessian_assemblies += t.hessian_assemblies;
    C.gradient_assemblies += t.gradient_assemblies;
    C.energy_evaluations += t.energy_evaluations;
    C.qp_calls += t.qp_calls;
    C.cg_iterations += t.cg_iterations;
    C.accepted += t.accepted;
    C.rejected += t.rejected;
    C.cholmod_fallbacks += t.cholmod_fallbacks;
    C.projected_models += t.projected_models;
    C.extrapolations += t.extrapolations;
    C.factorizations += t.factorizations;
  }
}

void Rmtr::nested_start(VecX& x, const LocalTrControl& base) {
  // Nested iteration (the F-cycle start of FMG, Gratton-Sartenaer-Toint 2008 §4): the problem of level t is the
  // step rediscretized on its control mesh, without the coupling term of (4.3), and its solution seeds level t+1
  // (how: at the end of the loop).
  const int top = static_cast<int>(m_levels.size()) - 1;
  std::vector<VecX> xs(static_cast<size_t>(top + 1));
  xs[static_cast<size_t>(top)] = x;
  for (int l = top; l > 0; --l) m_levels[static_cast<size_t>(l)]->project(xs[static_cast<size_t>(l)], xs[static_cast<size_t>(l - 1)]);
  const std::vector<VecX> x0s = xs;
  m_nested_cycles.assign(static_cast<size_t>(top), 0);
  for (int t = 0; t < top; ++t) {
    if ((base.timer && base.timer->seconds() >= base.max_seconds) || (base.interruptible && interrupted())) break;
    Level& L = *m_levels[static_cast<size_t>(t)];
    RmtrLevelCounters& C = m_counters[static_cast<size_t>(t)];
    VecX& xt = xs[static_cast<size_t>(t)];
    VecX g;
    double f = L.f->value(xt);
    L.f->gradient(xt, g);
    ++C.energy_evaluations;
    ++C.gradient_assemblies;
    check_finite(fmt::format("{} (nested level {})", m_name, top - t), f, g.norm(), 0);
    LocalTrControl c = base;
    c.rel_grad = 0.0;
    // The coarsest level starts from the projection of the given fine start, whose gradient measures how far the
    // step's boundary targets and loads moved (1.5e7 on the Drape's coarsest level of 5: the held corners' penalty
    // at β = h⁻⁵), not the problem: relative to it, the solve stopped after one step at 1e-3 of that. It is cheap,
    // so it gets the finest level's target; the levels above start from a prolongated solution.
    c.abs_grad = t == 0 ? base.abs_grad : m_params.nested_rel_grad * g.norm();
    c.project = nullptr;
    c.trace = nullptr;
    int& cycles = m_nested_cycles[static_cast<size_t>(t)];
    // Energies after each V-cycle (each 100 Local_TR iterations on the coarsest level), for nested_energy_tol.
    std::vector<double> energies{f};
    const auto settled = [&] {
      constexpr size_t window = 10;
      const size_t k = energies.size() - 1;
      return m_params.nested_energy_tol > 0.0 && k >= window &&
             energies[k - window] - energies[k] <= m_params.nested_energy_tol * (energies[0] - energies[k]);
    };
    double f_end = f;
    if (t == 0) {
      LevelModel h(*L.f);
      c.metric = L.metric.get();
      c.start_energy = &f_end;
      c.start_gradient = &g;
      double radius = m_params.tr.delta0;
      // In chunks of 100 iterations only where the energy rule needs them: a new run() reassembles the Hessian.
      const int chunk = m_params.nested_energy_tol > 0.0 ? 100 : 100 * m_params.nested_max_cycles;
      for (int done = 0; done < 100 * m_params.nested_max_cycles;) {
        c.max_iters = std::min(chunk, 100 * m_params.nested_max_cycles - done);
        const LocalTrResult r = L.tr->run(h, xt, radius, c);
        done += r.iterations;
        cycles = done;
        f_end = r.energy;
        c.start_gradient = &L.tr->gradient();
        energies.push_back(f_end);
        if (r.status != "max_iters" || settled()) break;
      }
    } else {
      m_top = t;
      m_radius = m_params.tr.delta0;
      m_finest_energy = f;
      m_start_gradient = &g;
      while (cycles < m_params.nested_max_cycles) {
        if ((base.timer && base.timer->seconds() >= base.max_seconds) || (base.interruptible && interrupted())) break;
        const VecX before = xt;
        m_finest_stalled = false;
        m_finest_stagnated = false;
        const CycleResult r = visit(t, xt, nullptr, nullptr, kInf, c);
        ++cycles;
        energies.push_back(m_finest_energy);
        if (r.converged || L.tr->gradient().norm() <= c.abs_grad) break;
        if (m_finest_stalled && (xt - before).norm() == 0.0) break;
        if (m_finest_stagnated) break;  // this level's limiting accuracy: its target is out of reach
        if (settled()) break;
      }
      m_start_gradient = nullptr;
      f_end = m_finest_energy;
    }
    // The level's solution is where its coarse corrections start from (coarse_start "best"): a projection of a
    // wrinkled fine state onto a coarse control mesh can have a coarse energy of 1e60 J and more (the woven
    // material's exponential response to the strains the projection introduces), where its model resolves nothing.
    if (m_params.coarse_start == "best") L.last_end = xt;
    // The next level starts from the lowest-energy of: its own start; that start corrected by S (x_t − x_t⁰), which
    // keeps the start's fine-scale content (a warm start's wrinkles); and S x_t, the coarse solution alone, which
    // is what is left when that content does not move with a large coarse motion (it is not rotated with it).
    Level& U = *m_levels[static_cast<size_t>(t + 1)];
    VecX& xu = xs[static_cast<size_t>(t + 1)];
    VecX s, corrected, replaced;
    U.S->apply(VecX(xt - x0s[static_cast<size_t>(t)]), s);
    corrected = xu + s;
    U.S->apply(xt, replaced);
    const double f_old = U.f->value(xu), f_corrected = U.f->value(corrected), f_replaced = U.f->value(replaced);
    m_counters[static_cast<size_t>(t + 1)].energy_evaluations += 3;
    logger().debug("rmtr nested level {}: {} cycles to energy {:.6e}, |g| {:.3e} -> {:.3e} (target {:.3e}); next "
                   "level's start {:.6e}, corrected {:.6e}, replaced {:.6e}",
                   top - t, cycles, f_end, g.norm(), L.tr->gradient().norm(), c.abs_grad, f_old, f_corrected, f_replaced);
    const double best = std::min({f_old, std::isfinite(f_corrected) ? f_corrected : kInf,
                                  std::isfinite(f_replaced) ? f_replaced : kInf});
    if (best == f_corrected && best < f_old) xu.swap(corrected);
    else if (best == f_replaced && best < f_old) xu.swap(replaced);
  }
  m_top = top;
  x = xs[static_cast<size_t>(top)];
}

std::vector<VecX> Rmtr::level_states() const {
  std::vector<VecX> out;
  if (m_params.coarse_start != "best" || m_levels.size() < 2) return out;
  for (size_t i = 0; i + 1 < m_levels.size(); ++i) out.push_back(m_levels[i]->last_end);
  return out;
}

double Rmtr::work_units_assembly() const {
  double w = 0.0;
  const int top = static_cast<int>(m_counters.size()) - 1;
  for (int l = 0; l <= top; ++l) w += std::ldexp(1.0, -2 * (top - l)) * m_counters[static_cast<size_t>(l)].hessian_assemblies;
  return w;
}

double Rmtr::work_units_qp() const {
  double w = 0.0;
  const int top = static_cast<int>(m_counters.size()) - 1;
  for (int l = 0; l <= top; ++l) w += std::ldexp(1.0, -2 * (top - l)) * m_counters[static_cast<size_t>(l)].qp_calls;
  return w;
}

std::string Rmtr::carried_state() const {
  std::vector<double> shifts;
  for (const auto& lv : m_levels) shifts.push_back(lv->tr->dogleg_shift());
  if (std::all_of(shifts.begin(), shifts.end(), [](double s) { return s == 0.0; })) return {};  // as a fresh solver
  return encode_carried_state("rmtr", shifts);
}

void Rmtr::restore_carried_state(std::string_view state) {
  m_restore_shifts.clear();
  for (auto& lv : m_levels) lv->tr->set_dogleg_shift(0.0);
  if (state.empty()) return;
  m_restore_shifts = decode_carried_state("rmtr", state);
  for (double s : m_restore_shifts)
    if (!(s >= 0.0 && std::isfinite(s))) throw_input_error("{}: a solver state with the shift {}", m_name, s);
  if (m_restore_shifts.empty()) throw_input_error("{}: a solver state without levels", m_name);
}

SolveReport Rmtr::minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) {
  Timer timer;
  setup(problem);
  if (!m_restore_shifts.empty()) {
    if (m_restore_shifts.size() != m_levels.size())
      throw_input_error("{}: a solver state for {} levels, the problem has {}", m_name, m_restore_shifts.size(),
                        m_levels.size());
    for (size_t i = 0; i < m_levels.size(); ++i) m_levels[i]->tr->set_dogleg_shift(m_restore_shifts[i]);
    m_restore_shifts.clear();
  }
  for (auto& lv : m_levels) {
    lv->tr->reset();
    lv->last_end.resize(0);  // a previous solve's states belong to another time step
  }
  // An earlier part of this solve (a resumed benchmark): its coarse levels' kept states.
  if (m_params.coarse_start == "best" && m_resume_states.size() + 1 == m_levels.size())
    for (size_t i = 0; i < m_resume_states.size(); ++i)
      if (m_resume_states[i].size() == m_levels[i]->f->num_dofs()) m_levels[i]->last_end = m_resume_states[i];
  m_resume_states.clear();
  m_counters.assign(m_levels.size(), {});
  m_corrections.clear();
  m_finest_energies.clear();
  m_radius = m_params.tr.delta0;
  m_finest_stalled = false;
  m_top = static_cast<int>(m_levels.size()) - 1;
  m_nested_cycles.clear();
  Level& F = *m_levels.back();
  if (m_params.scaling != "none") scale_finest(x);

  LocalTrControl base;
  base.abs_grad = stop.abs_grad;
  base.max_seconds = stop.max_seconds;
  base.interruptible = stop.interruptible;
  base.timer = &timer;
  base.project = problem.project;
  // The start point's energy and gradient, shared with the first pre-smoothing. The report's initial gradient, the
  // relative target and the trace's first row are those of the given start, also with nested iteration.
  m_finest_energy = F.f->value(x);
  F.f->gradient(x, m_start);
  m_start_gradient = &m_start;
  ++m_counters.back().energy_evaluations;
  ++m_counters.back().gradient_assemblies;
  double gnorm = m_start.norm();
  check_finite(m_name, m_finest_energy, gnorm, 0);
  SolveReport rep;
  rep.initial_grad_norm = gnorm;
  const double target = std::max(stop.abs_grad, stop.rel_grad * gnorm);
  base.abs_grad = target;
  if (trace) trace->push_back({0, m_finest_energy, gnorm, timer.ms(), 0.0});
  if (m_params.initial == "nested") {
    const VecX given = x;
    nested_start(x, base);
    if (problem.project) problem.project(x);
    m_radius = m_params.tr.delta0;
    m_finest_energy = F.f->value(x);
    F.f->gradient(x, m_start);
    ++m_counters.back().energy_evaluations;
    ++m_counters.back().gradient_assemblies;
    gnorm = m_start.norm();
    check_finite(m_name, m_finest_energy, gnorm, 0);
    // Where the coarse solutions take the V-cycles to start: a second row at iteration 0, at the time it took.
    if (trace) trace->push_back({0, m_finest_energy, gnorm, timer.ms(), (x - given).norm()});
  }
  m_finest_energies.push_back(m_finest_energy);
  double last_df = kInf, last_dx = kInf, last_radius = 0.0;
  bool last_newton = false;
  double last_checkpoint = timer.seconds();
  int cycle = 0;
  VecX previous;
  StepTracker steps(stop.step_tol);
  for (;; ++cycle) {
    if (should_stop(gnorm, target, timer.seconds(), stop, rep) || cycle >= stop.max_iters) {
      if (rep.status.empty()) rep.status = "max_iters";
      break;
    }
    // Criterion (7.1), second part, on the finest level, active once Δ > 1e15 or the cycle ended with a Newton step
    // (the trust region acts as Newton's method either way; at the limiting accuracy the round-off rule keeps Δ,
    // so it would never pass 1e15). A cycle whose every step and correction was rejected has not moved (|Δx| = 0)
    // but says nothing about convergence; the round-off stall below covers the case where it cannot move.
    if ((last_radius > m_params.tr.stagnation_delta || last_newton) && last_dx > 0.0 &&
        (last_df < m_params.tr.stagnation_tol || last_dx < m_params.tr.stagnation_tol)) {
      rep.status = "stagnated";
      break;
    }
    if (steps.converged(x)) {
      rep.status = "converged";
      break;
    }
    previous = x;
    const double f_before = m_finest_energy;
    m_finest_stalled = false;
    m_finest_newton = false;
    m_finest_stagnated = false;
    visit(static_cast<int>(m_levels.size()) - 1, x, nullptr, nullptr, kInf, base);
    gnorm = F.tr->gradient().norm();
    check_finite(m_name, m_finest_energy, gnorm, cycle + 1);
    last_df = std::abs(f_before - m_finest_energy);
    last_dx = (x - previous).norm();
    last_radius = m_radius;
    last_newton = m_finest_newton;
    if (stop.checkpoint && timer.seconds() - last_checkpoint >= stop.checkpoint_seconds) {
      stop.checkpoint(x, cycle + 1, m_finest_energy, gnorm);
      last_checkpoint = timer.seconds();
    }
    if (trace) trace->push_back({cycle + 1, m_finest_energy, gnorm, timer.ms(), last_dx});
    logger().debug("rmtr cycle {:4d}: E = {:.12e}  |g| = {:.3e}  radius {:.3e}", cycle + 1, m_finest_energy, gnorm,
                   m_radius);
    if (last_dx == 0.0 && m_finest_stalled) {
      ++cycle;
      rep.status = "stalled";
      break;
    }
    if (m_finest_stagnated && gnorm > target) {
      ++cycle;
      rep.status = "stagnated";
      break;
    }
  }
  accumulate();
  finish_report(rep, cycle, m_finest_energy, gnorm, target, timer.ms());
  steps.finish(x, rep);
  int corr_acc = 0, corr_rej = 0, corr_back = 0;
  for (const auto& c : m_counters) {
    corr_acc += c.corrections_accepted;
    corr_rej += c.corrections_rejected;
    corr_back += c.corrections_backtracked;
  }
  rep.counters = {{"corrections_accepted", corr_acc}, {"corrections_rejected", corr_rej},
                  {"corrections_backtracked", corr_back},
                  {"work_assembly", work_units_assembly()}, {"work_qp", work_units_qp()},
                  {"final_radius", m_radius}, {"levels", static_cast<double>(m_levels.size())}};
  for (size_t i = 0; i < m_nested_cycles.size(); ++i)
    rep.counters.push_back({fmt::format("level{}_nested_cycles", m_counters.size() - 1 - i), m_nested_cycles[i]});
  for (size_t i = m_counters.size(); i-- > 0;) {
    const size_t k = m_counters.size() - 1 - i;  // 0 = finest
    const auto& c = m_counters[i];
    rep.counters.push_back({fmt::format("level{}_dofs", k), c.dofs});
    rep.counters.push_back({fmt::format("level{}_hessian_assemblies", k), c.hessian_assemblies});
    rep.counters.push_back({fmt::format("level{}_qp_calls", k), c.qp_calls});
    rep.counters.push_back({fmt::format("level{}_cg_iterations", k), static_cast<double>(c.cg_iterations)});
    rep.counters.push_back({fmt::format("level{}_radius_exhausted", k), c.radius_exhausted});
    if (m_params.coarse_start == "best" && k > 0) rep.counters.push_back({fmt::format("level{}_starts_kept", k), c.starts_kept});
    rep.counters.push_back({fmt::format("level{}_cholmod_fallbacks", k), c.cholmod_fallbacks});
    rep.counters.push_back({fmt::format("level{}_projected_models", k), c.projected_models});
    rep.counters.push_back({fmt::format("level{}_extrapolations", k), c.extrapolations});
    rep.counters.push_back({fmt::format("level{}_factorizations", k), c.factorizations});
  }
  m_start_gradient = nullptr;
  return rep;
}

}  // namespace mgcloth::solvers
