#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>
#include <mgcloth/linalg/patch_smoother.hpp>
#include <mgcloth/linalg/trust_region_qp.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth::linalg {

std::string to_string(QpStop reason) {
  switch (reason) {
    case QpStop::Converged: return "converged";
    case QpStop::Boundary: return "boundary";
    case QpStop::NegativeCurvature: return "negative_curvature";
    case QpStop::MaxIters: return "max_iters";
  }
  return "unknown";
}

NormMetric::NormMetric(BlockMatrix3 M) : m_matrix(std::move(M)), m_cholmod(std::make_unique<CholmodSolver>()) {
  // CHOLMOD reads only the lower triangle and would "factorize" NaN (see factorize_shifted); an asymmetric M would
  // make solve() the inverse of another matrix than multiply() applies, and the norm of the CG iterates would no
  // longer be the one the preconditioner grows monotonically.
  double scale = 0.0;
  for (const Mat3& b : m_matrix.blocks()) {
    if (!b.allFinite()) throw_error("NormMetric: M has a non-finite entry");
    scale = std::max(scale, b.cwiseAbs().maxCoeff());
  }
  for (Index r = 0; r < m_matrix.rows(); ++r)
    for (Index k = m_matrix.row_offsets()[r]; k < m_matrix.row_offsets()[r + 1]; ++k) {
      const Index c = m_matrix.col_indices()[k];
      const double asym = (m_matrix.block(k) - m_matrix.block(m_matrix.find(c, r)).transpose()).cwiseAbs().maxCoeff();
      if (asym > 1e-12 * scale) throw_error("NormMetric: M is not symmetric (blocks ({}, {}) and ({}, {}))", r, c, c, r);
    }
  if (!m_cholmod->factorize(m_matrix)) throw_error("NormMetric: M ({} points) is not positive definite", rows());
}

void NormMetric::multiply(const VecX& s, VecX& out) const { m_matrix.multiply(s, out); }

void NormMetric::solve(const VecX& r, VecX& out) const { m_cholmod->solve(r, out); }

double NormMetric::dot(const VecX& a, const VecX& b) const { return a.dot(m_matrix * b); }

double NormMetric::norm(const VecX& s) const { return std::sqrt(std::max(0.0, dot(s, s))); }

namespace {

void check_metric(const NormMetric* metric, Index dofs, const char* where) {
  if (metric && 3 * metric->rows() != dofs)
    throw_error("{}: the metric has {} points, the vectors {} entries", where, metric->rows(), dofs);
}

/// The two roots τ₋ ≤ 0 ≤ τ₊ of ‖z + τd‖ = Δ for ‖z‖ ≤ Δ, in the cancellation-free form.
std::pair<double, double> boundary_roots(double zz, double zd, double dd, double delta) {
  const double room = std::max(0.0, delta * delta - zz);
  const double root = std::sqrt(zd * zd + dd * room);
  if (zd > 0.0) {
    const double lo = (-zd - root) / dd;
    return {lo, room / (zd + root)};
  }
  const double hi = (-zd + root) / dd;
  return {root - zd > 0.0 ? -room / (root - zd) : 0.0, hi};
}

/// The Cauchy point −t·y (Nocedal-Wright eq. 4.12) from gg = gᵀy, gHg = yᵀHy and Δ, where −y is the steepest
/// descent of the norm: y = g in ℓ2, y = M⁻¹g in ‖·‖_M. Both uses of gg hold for either, since gᵀy = ‖y‖²_M
/// (= ‖g‖²_{M⁻¹}) gives the slope and the length alike. Returns t and the model decrease.
std::pair<double, double> cauchy_step(double gg, double gHg, double delta) {
  const double g_norm = std::sqrt(gg);
  if (g_norm == 0.0) return {0.0, 0.0};
  const double t_boundary = delta / g_norm;
  const double t = gHg > 0.0 ? std::min(gg / gHg, t_boundary) : t_boundary;
  return {t, t * gg - 0.5 * t * t * gHg};
}

double model_decrease(const BlockMatrix3& H, const VecX& g, const VecX& s) {
  return -(g.dot(s) + 0.5 * s.dot(H * s));
}

/// Round-off can put a boundary step a few ulps outside the ball; pull it back so that ‖s‖ ≤ Δ holds exactly.
/// Returns ‖s‖ afterwards, in ℓ2 or in ‖·‖_M.
double clamp_to_ball(VecX& s, double delta, const NormMetric* metric) {
  const double n = metric ? metric->norm(s) : s.norm();
  if (n > delta) {
    s *= delta / n;
    return delta;
  }
  return n;
}

}  // namespace

QpResult cauchy_point(const BlockMatrix3& H, const VecX& g, double delta, const NormMetric* metric) {
  check_metric(metric, static_cast<Index>(g.size()), "cauchy_point");
  QpResult r;
  // −M⁻¹g minimizes gᵀd over ‖d‖_M = ‖g‖_{M⁻¹} (Cauchy-Schwarz in the M inner product).
  VecX Minv_g;
  if (metric) metric->solve(g, Minv_g);
  const VecX& y = metric ? Minv_g : g;
  const double gg = metric ? std::max(0.0, g.dot(Minv_g)) : g.squaredNorm();
  const auto [t, dec] = cauchy_step(gg, y.dot(H * y), delta);
  r.s = -t * y;
  r.norm = clamp_to_ball(r.s, delta, metric);
  r.model_decrease = model_decrease(H, g, r.s);
  r.reason = t * std::sqrt(gg) >= delta * (1.0 - 1e-12) ? QpStop::Boundary : QpStop::Converged;
  return r;
}

namespace {
/// The model's minimizer along a smoother's direction d inside the ball, or the Cauchy point where d is no descent
/// direction or decreases the model less (SDC).
QpResult along_direction(const BlockMatrix3& H, const VecX& g, const VecX& d, double delta, int sweeps,
                         const NormMetric* metric) {
  QpResult cauchy = cauchy_point(H, g, delta, metric);
  cauchy.iterations = sweeps;
  const double gd = g.dot(d);
  const double dHd = d.dot(H * d);
  const double dn = metric ? metric->norm(d) : d.norm();
  if (!(gd < 0.0) || !std::isfinite(dHd) || !(dn > 0.0)) return cauchy;
  // m(τd) = τ gᵀd + ½ τ² dᵀHd, minimized over 0 < τ ≤ Δ/‖d‖.
  const double tmax = delta / dn;
  const double t = dHd > 0.0 ? std::min(tmax, -gd / dHd) : tmax;
  QpResult r;
  r.s = t * d;
  r.norm = t * dn;
  r.model_decrease = model_decrease(H, g, r.s);
  r.iterations = sweeps;
  r.reason = t >= tmax * (1.0 - 1e-12) ? QpStop::Boundary : QpStop::Converged;
  return r.model_decrease >= cauchy.model_decrease ? r : cauchy;
}
}  // namespace

QpResult gauss_seidel_step(const BlockMatrix3& H, const VecX& g, double delta, int sweeps,
                           const MultiColorGaussSeidel& gs, const NormMetric* metric) {
  check_metric(metric, static_cast<Index>(g.size()), "gauss_seidel_step");
  if (g.norm() == 0.0) return cauchy_point(H, g, delta, metric);
  VecX d = VecX::Zero(g.size());
  gs.symmetric_sweeps(-g, d, std::max(1, sweeps));
  return along_direction(H, g, d, delta, sweeps, metric);
}

QpResult patch_step(const BlockMatrix3& H, const VecX& g, double delta, int sweeps, const PatchSmoother& patches,
                    const NormMetric* metric) {
  check_metric(metric, static_cast<Index>(g.size()), "patch_step");
  if (g.norm() == 0.0) return cauchy_point(H, g, delta, metric);
  VecX d = VecX::Zero(g.size());
  patches.symmetric_sweeps(-g, d, std::max(1, sweeps));
  return along_direction(H, g, d, delta, sweeps, metric);
}

QpResult steihaug_cg(const BlockMatrix3& H, const VecX& g, double delta, int max_iters, double rel_tol,
                     const NormMetric* metric) {
  check_metric(metric, static_cast<Index>(g.size()), "steihaug_cg");
  QpResult out;
  const Index n = static_cast<Index>(g.size());
  if (max_iters <= 0) max_iters = 3 * static_cast<int>(n);
  VecX z = VecX::Zero(n), r = g, d = -g, Hd;
  const double g_norm = g.norm();
  const double tol = rel_tol * g_norm;
  out.reason = QpStop::MaxIters;
  double rr = r.squaredNorm();
  double gHg = 0.0;  // dᵀHd of the first iteration, where d = −y₀
  if (g_norm == 0.0) {
    out.s = z;
    out.reason = QpStop::Converged;
    return out;
  }
  // Preconditioned by M (Conn-Gould-Toint Alg. 7.5.1): y = M⁻¹r takes the place of r in the direction and in α, β
  // (ry = rᵀy), which makes the iterates' M-norms, not their ℓ2 norms, grow monotonically (CGT Thm. 7.5.1), so the
  // boundary tests below are in ‖·‖_M. Without a metric y is r itself. The stopping test stays ‖r‖₂ ≤ rel_tol·‖g‖₂:
  // the caller's tolerance keeps its meaning, and the metric changes only the constraint, not when an interior
  // step counts as converged.
  VecX Minv_r, y0, Mz, Md;
  if (metric) {
    metric->solve(r, Minv_r);
    y0 = Minv_r;
    Mz = VecX::Zero(n);
    d = -Minv_r;
  }
  const VecX& y = metric ? Minv_r : r;
  double ry = metric ? r.dot(Minv_r) : rr;
  const double ry0 = ry;
  int j = 0;
  for (; j < max_iters; ++j) {
    H.multiply(d, Hd);
    const double dHd = d.dot(Hd);
    if (j == 0) gHg = dHd;
    // ‖z‖², zᵀd and ‖d‖² in the norm of the subproblem. With a metric they come from explicit products (Md, and
    // Mz carried along with z) rather than from the scalar recurrences for zᵀMd and dᵀMd (CGT §7.5.1), which hold
    // only as long as the residuals stay orthogonal; one M product per iteration buys immunity to that loss.
    double zz, zd, dd;
    if (metric) {
      metric->multiply(d, Md);
      zz = z.dot(Mz);
      zd = z.dot(Md);
      dd = d.dot(Md);
    } else {
      zz = z.squaredNorm();
      zd = z.dot(d);
      dd = d.squaredNorm();
    }
    if (!(dHd > 0.0)) {
      // Negative curvature: the model is unbounded along ±d; take the boundary point with the lower model,
      // m(z + τd) − m(z) = τ rᵀd + ½ τ² dᵀHd.
      const auto [lo, hi] = boundary_roots(zz, zd, dd, delta);
      const double rd = r.dot(d);
      const auto change = [&](double tau) { return tau * rd + 0.5 * tau * tau * dHd; };
      z += (change(lo) < change(hi) ? lo : hi) * d;
      out.reason = QpStop::NegativeCurvature;
      ++j;
      break;
    }
    const double alpha = ry / dHd;
    const double next_norm2 = metric ? zz + alpha * (2.0 * zd + alpha * dd) : (z + alpha * d).squaredNorm();
    if (next_norm2 >= delta * delta) {
      z += boundary_roots(zz, zd, dd, delta).second * d;
      out.reason = QpStop::Boundary;
      ++j;
      break;
    }
    z += alpha * d;
    if (metric) Mz += alpha * Md;
    r += alpha * Hd;
    const double rr_next = r.squaredNorm();
    if (std::sqrt(rr_next) <= tol) {
      out.reason = QpStop::Converged;
      ++j;
      break;
    }
    double ry_next = rr_next;
    if (metric) {
      metric->solve(r, Minv_r);
      ry_next = r.dot(Minv_r);
    }
    d = -y + (ry_next / ry) * d;
    ry = ry_next;
  }
  out.iterations = j;
  out.norm = clamp_to_ball(z, delta, metric);
  out.model_decrease = model_decrease(H, g, z);
  // In exact arithmetic every CG iterate improves on the first (the Cauchy point of the norm); with a Hessian of
  // condition 1e13 round-off can undo that, and SDC must hold regardless.
  const auto [t, cauchy_decrease] = cauchy_step(metric ? ry0 : g_norm * g_norm, gHg, delta);
  if (!(out.model_decrease >= cauchy_decrease)) {
    VecX c = -t * (metric ? y0 : g);
    const double c_norm = clamp_to_ball(c, delta, metric);
    const double dec = model_decrease(H, g, c);
    if (!(out.model_decrease >= dec)) {
      z.swap(c);
      out.model_decrease = dec;
      out.norm = c_norm;
    }
  }
  out.s = std::move(z);
  return out;
}

ShiftedFactorization factorize_shifted(CholmodSolver& solver, const BlockMatrix3& H, int max_attempts, double start,
                                       int bisections, bool* not_definite) {
  // CHOLMOD "factorizes" a matrix with NaN entries (its pivot tests compare false) and the solve returns NaN.
  for (const Mat3& b : H.blocks())
    if (!b.allFinite()) throw SolveError("factorize_shifted: the matrix has a non-finite entry");
  ShiftedFactorization f;
  ++f.attempts;
  if (not_definite) *not_definite = false;
  if (solver.factorize(H, 0.0)) return f;
  if (not_definite) {
    *not_definite = true;
    return f;
  }
  f.failed = 0.0;
  double scale = 0.0;
  for (Index i = 0; i < H.rows(); ++i) scale = std::max(scale, H.block(H.diagonal(i)).diagonal().cwiseAbs().maxCoeff());
  if (scale == 0.0) scale = 1.0;
  // Successive Hessians of one solve need similar shifts: starting a decade below the last one saves most of the
  // failed factorizations of a search from 1e-8·max|diag| each time.
  const double first = std::max(1e-8 * scale, start > 0.0 ? 0.1 * start : 0.0);
  double failed = 0.0;  // the largest shift known not to factorize (0: only H itself)
  for (double shift = first; f.attempts < max_attempts; shift *= 10.0) {
    ++f.attempts;
    if (solver.factorize(H, shift)) {
      f.shift = shift;
      f.failed = failed;
      if (bisections <= 0) return f;
      // The decade ladder can overshoot the smallest working shift 10-fold, and the step of H + λI is then as
      // much shorter in the soft directions; bisecting on log λ recovers most of that.
      double lo = failed > 0.0 ? failed : 0.1 * shift;
      bool holds = true;  // the solver holds the factor of f.shift
      for (int b = 0; b < bisections; ++b) {
        const double mid = std::sqrt(lo * f.shift);
        ++f.attempts;
        if (solver.factorize(H, mid)) {
          f.shift = mid;
          holds = true;
        } else {
          lo = mid;
          f.failed = mid;
          holds = false;
        }
      }
      if (!holds) {
        ++f.attempts;
        if (!solver.factorize(H, f.shift)) throw SolveError("factorize_shifted: a shift that factorized no longer does");
      }
      return f;
    }
    failed = shift;
  }
  throw SolveError(fmt::format("factorize_shifted: H + λI not positive definite after {} attempts (λ up to {:.3e})",
                               f.attempts, first * std::pow(10.0, f.attempts - 2)));
}

void Dogleg::prepare(const BlockMatrix3& H, const VecX& g, const NormMetric* metric) {
  prepare_model(H, g, metric, false);
}

bool Dogleg::prepare_model(const BlockMatrix3& H, const VecX& g, const NormMetric* metric, bool definite_only) {
  check_metric(metric, static_cast<Index>(g.size()), "Dogleg::prepare");
  m_metric = metric;
  m_H = &H;
  m_tried.clear();
  // In ‖·‖_M the first leg runs along −y = −M⁻¹g. Since My = g, every M-inner product step() needs is one of
  // the model's scalars already: ‖y‖²_M = gᵀy, yᵀMp_B = gᵀp_B; only ‖p_B‖_M costs an M product.
  if (metric) metric->solve(g, m_y);
  else m_y = g;
  m_gg = metric ? std::max(0.0, g.dot(m_y)) : g.squaredNorm();
  m_g_norm = std::sqrt(m_gg);
  m_prepared = true;
  if (m_g_norm == 0.0) {
    m_newton = VecX::Zero(g.size());
    m_gHg = m_gp = m_gHp = m_pHp = m_newton_norm = 0.0;
    return true;
  }
  m_g = g;
  VecX Hv;
  H.multiply(m_y, Hv);
  m_gHg = m_y.dot(Hv);
  bool not_definite = false;
  const auto f = factorize_shifted(m_cholmod, H, 40, m_shift, m_bisections, definite_only ? &not_definite : nullptr);
  m_factorizations += f.attempts;
  if (not_definite) {
    m_prepared = m_factor_holds = false;
    return false;
  }
  if (f.shift > 0.0) ++m_fallbacks;
  m_factor_holds = true;
  if (f.failed >= 0.0) m_tried.emplace_back(f.failed, kInf);
  const bool finite = newton_point(f.shift, true);
  if (f.shift > 0.0) m_tried.emplace_back(f.shift, finite ? m_newton_norm : kInf);
  return true;
}

bool Dogleg::newton_point(double shift, bool keep_overflow) {
  VecX p;
  m_cholmod.solve(-m_g, p);
  const bool finite = p.allFinite();
  if (!finite && !keep_overflow) return false;
  // A nearly singular H + λI can overflow the solve; the dogleg then degenerates to the Cauchy point.
  if (!finite) p.setZero();
  set_newton(std::move(p), shift);
  return finite;
}

void Dogleg::set_newton(VecX p, double shift) {
  m_newton = std::move(p);
  m_shift = shift;
  VecX Hv;
  m_gp = m_g.dot(m_newton);
  m_H->multiply(m_newton, Hv);
  m_gHp = m_y.dot(Hv);
  m_pHp = m_newton.dot(Hv);
  m_newton_norm = m_metric ? m_metric->norm(m_newton) : m_newton.norm();
}

namespace {
// |‖p‖ − Δ| ≤ 0.1Δ is Moré-Sorensen's usual tolerance: the step is then within 10% of the exact one's length,
// and a tighter λ costs factorizations that the next accepted point discards.
constexpr double kSphereTol = 0.1;
}  // namespace

void Dogleg::radius_shift(double delta) {
  constexpr double tol = kSphereTol;
  constexpr int max_factorizations = 6;
  const auto close = [&](double norm) { return std::abs(norm - delta) <= tol * delta; };
  if (close(m_newton_norm)) return;
  // Best so far: the Newton point the solver now describes, if its ‖p‖ ≤ (1 + tol)Δ.
  double best_shift = m_newton_norm <= (1.0 + tol) * delta ? m_shift : -1.0;
  double best_norm = best_shift >= 0.0 ? m_newton_norm : -1.0;
  VecX best_newton;
  if (best_shift >= 0.0) best_newton = m_newton;
  VecX w, Mp;
  for (int k = 0; k < max_factorizations; ++k) {
    // The bracket from every shift tried at this point: ‖p(λ)‖ falls with λ above −λ_min(H), and a shift that
    // did not factorize lies below −λ_min.
    double lo = 0.0, hi = kInf;
    for (const auto& [l, n] : m_tried) {
      if (n > delta && l > lo) lo = l;
      if (n < delta && l < hi) hi = l;
    }
    if (!(hi > lo)) break;
    // Newton on 1/‖p(λ)‖ = 1/Δ from the current point (Nocedal-Wright eq. 4.44): d‖p‖²/dλ = −2 pᵀM(H + λI)⁻¹p.
    double next = -1.0;
    if (m_factor_holds && m_newton_norm > 0.0) {
      if (m_metric) m_metric->multiply(m_newton, Mp);
      m_cholmod.solve(m_metric ? Mp : m_newton, w);
      const double c = m_newton.dot(w);
      if (c > 0.0 && std::isfinite(c))
        next = m_shift + (m_newton_norm - delta) / delta * (m_newton_norm * m_newton_norm / c);
    }
    // Safeguard: outside the bracket, bisect it geometrically (λ spans decades), or step a decade out of it.
    if (!(next > lo && next < hi)) next = hi == kInf ? 10.0 * std::max(lo, 1e-300) : lo > 0.0 ? std::sqrt(lo * hi) : 0.1 * hi;
    ++m_factorizations;
    // An overflowing solve counts as a failure: λ is then next to −λ_min, where ‖p‖ is unbounded.
    m_factor_holds = m_cholmod.factorize(*m_H, next) && newton_point(next, false);
    if (!m_factor_holds) {
      m_tried.emplace_back(next, kInf);
      continue;
    }
    m_tried.emplace_back(next, m_newton_norm);
    if (m_newton_norm <= (1.0 + tol) * delta && m_newton_norm > best_norm) {
      best_shift = next;
      best_norm = m_newton_norm;
      best_newton = m_newton;
    }
    if (close(m_newton_norm)) return;
  }
  // Out of factorizations: keep the longest Newton point within reach of the ball, else the last one found.
  if (best_shift >= 0.0 && best_shift != m_shift) {
    m_factor_holds = false;  // the solver holds the factor of another λ
    set_newton(std::move(best_newton), best_shift);
  }
}

double Dogleg::decrease(double a, double b) const {
  const double gs = a * m_gg + b * m_gp;
  const double sHs = a * a * m_gHg + 2.0 * a * b * m_gHp + b * b * m_pHp;
  return -(gs + 0.5 * sHs);
}

QpResult Dogleg::step(double delta) {
  if (!m_prepared) throw_error("Dogleg::step called before prepare");
  QpResult out;
  if (m_g_norm == 0.0) {
    out.s = VecX::Zero(m_y.size());
    return out;
  }
  m_shift_on_sphere = false;
  if (m_radius_shift && !m_tried.empty()) {
    radius_shift(delta);
    m_shift_on_sphere = m_shift > 0.0 && std::abs(m_newton_norm - delta) <= kSphereTol * delta;
  }
  // Steps are s = a·y + b·p_B; the model of such a step, and its M-norm geometry, need only the scalars of
  // prepare(), in which the formulas of ℓ2 hold unchanged (‖y‖² → gᵀy, yᵀp_B → gᵀp_B, ‖p_B‖ → ‖p_B‖_M).
  double a = 0.0, b = 0.0;
  if (m_newton_norm > 0.0 && m_newton_norm <= delta) {
    b = 1.0;
    out.reason = m_shift_on_sphere ? QpStop::Boundary : QpStop::Converged;
  } else if (m_shift_on_sphere) {
    // p(λ) is the exact step of the ball of radius ‖p‖, within 10% of Δ; scaled onto Δ it stays close to the exact
    // step, where the segment from the Cauchy point towards it can lose most of the decrease along negative curvature.
    b = delta / m_newton_norm;
    out.reason = QpStop::Boundary;
  } else if (m_newton_norm > 0.0 && !(m_gHg > 0.0)) {
    // No Cauchy minimizer along −y (the segment 0 → p_U is unbounded): the Newton point of H + λI, cut at Δ.
    b = delta / m_newton_norm;
    out.reason = QpStop::Boundary;
  } else if (m_newton_norm > 0.0) {
    const double u = m_gg / m_gHg;  // p_U = −u·y
    if (u * m_g_norm >= delta) {
      a = -delta / m_g_norm;
    } else {
      // ‖p_U + τ(p_B − p_U)‖ = Δ for τ ∈ (0, 1) (Nocedal-Wright eq. 4.16).
      const double zz = u * u * m_gg;
      const double zd = -u * m_gp - zz;
      const double dd = m_newton_norm * m_newton_norm + 2.0 * u * m_gp + zz;
      const double tau = std::clamp(boundary_roots(zz, zd, dd, delta).second, 0.0, 1.0);
      a = -u * (1.0 - tau);
      b = tau;
    }
    out.reason = QpStop::Boundary;
  }
  // The Cauchy point guarantees SDC; the dogleg point of a shifted H (or a round-off-damaged one) may fall short.
  const auto [t, cauchy_decrease] = cauchy_step(m_gg, m_gHg, delta);
  const bool newton_part = b != 0.0;
  if (!newton_part || !(decrease(a, b) >= cauchy_decrease)) {
    a = -t;
    b = 0.0;
    out.reason = t * m_g_norm >= delta * (1.0 - 1e-12) ? QpStop::Boundary : QpStop::Converged;
  }
  out.s = a * m_y + b * m_newton;
  // Measured, not taken from the scalars: one M product, and the reported norm is the step's own.
  const double norm = m_metric ? m_metric->norm(out.s) : out.s.norm();
  if (norm > delta) {
    a *= delta / norm;
    b *= delta / norm;
    out.s *= delta / norm;
  }
  out.norm = std::min(norm, delta);
  out.model_decrease = decrease(a, b);
  return out;
}

}  // namespace mgcloth::linalg
