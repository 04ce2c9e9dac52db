#include <mgcloth/core/error.hpp>
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

namespace {

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

/// The Cauchy point −t·g (Nocedal-Wright eq. 4.12) from ‖g‖², gᵀHg and Δ; returns t and the model decrease.
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
void clamp_to_ball(VecX& s, double delta) {
  const double n = s.norm();
  if (n > delta) s *= delta / n;
}

}  // namespace

QpResult cauchy_point(const BlockMatrix3& H, const VecX& g, double delta) {
  QpResult r;
  const double gg = g.squaredNorm();
  const auto [t, dec] = cauchy_step(gg, g.dot(H * g), delta);
  r.s = -t * g;
  clamp_to_ball(r.s, delta);
  r.model_decrease = model_decrease(H, g, r.s);
  r.reason = t * std::sqrt(gg) >= delta * (1.0 - 1e-12) ? QpStop::Boundary : QpStop::Converged;
  return r;
}

QpResult steihaug_cg(const BlockMatrix3& H, const VecX& g, double delta, int max_iters, double rel_tol) {
  QpResult out;
  const Index n = static_cast<Index>(g.size());
  if (max_iters <= 0) max_iters = 3 * static_cast<int>(n);
  VecX z = VecX::Zero(n), r = g, d = -g, Hd;
  const double g_norm = g.norm();
  const double tol = rel_tol * g_norm;
  out.reason = QpStop::MaxIters;
  double rr = r.squaredNorm();
  double gHg = 0.0;  // dᵀHd of the first iteration, where d = −g
  if (g_norm == 0.0) {
    out.s = z;
    out.reason = QpStop::Converged;
    return out;
  }
  int j = 0;
  for (; j < max_iters; ++j) {
    H.multiply(d, Hd);
    const double dHd = d.dot(Hd);
    if (j == 0) gHg = dHd;
    const double zz = z.squaredNorm(), zd = z.dot(d), dd = d.squaredNorm();
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
    const double alpha = rr / dHd;
    if ((z + alpha * d).squaredNorm() >= delta * delta) {
      z += boundary_roots(zz, zd, dd, delta).second * d;
      out.reason = QpStop::Boundary;
      ++j;
      break;
    }
    z += alpha * d;
    r += alpha * Hd;
    const double rr_next = r.squaredNorm();
    if (std::sqrt(rr_next) <= tol) {
      out.reason = QpStop::Converged;
      ++j;
      break;
    }
    d = -r + (rr_next / rr) * d;
    rr = rr_next;
  }
  out.iterations = j;
  clamp_to_ball(z, delta);
  out.model_decrease = model_decrease(H, g, z);
  // In exact arithmetic every CG iterate improves on the first (the Cauchy point); with a Hessian of condition
  // 1e13 round-off can undo that, and SDC must hold regardless.
  const auto [t, cauchy_decrease] = cauchy_step(g_norm * g_norm, gHg, delta);
  if (!(out.model_decrease >= cauchy_decrease)) {
    VecX c = -t * g;
    clamp_to_ball(c, delta);
    const double dec = model_decrease(H, g, c);
    if (!(out.model_decrease >= dec)) {
      z.swap(c);
      out.model_decrease = dec;
    }
  }
  out.s = std::move(z);
  return out;
}

ShiftedFactorization factorize_shifted(CholmodSolver& solver, const BlockMatrix3& H, int max_attempts, double start) {
  // CHOLMOD "factorizes" a matrix with NaN entries (its pivot tests compare false) and the solve returns NaN.
  for (const Mat3& b : H.blocks())
    if (!b.allFinite()) throw SolveError("factorize_shifted: the matrix has a non-finite entry");
  ShiftedFactorization f;
  ++f.attempts;
  if (solver.factorize(H, 0.0)) return f;
  double scale = 0.0;
  for (Index i = 0; i < H.rows(); ++i) scale = std::max(scale, H.block(H.diagonal(i)).diagonal().cwiseAbs().maxCoeff());
  if (scale == 0.0) scale = 1.0;
  // Successive Hessians of one solve need similar shifts: starting a decade below the last one saves most of the
  // failed factorizations of a search from 1e-8·max|diag| each time.
  const double first = std::max(1e-8 * scale, start > 0.0 ? 0.1 * start : 0.0);
  for (double shift = first; f.attempts < max_attempts; shift *= 10.0) {
    ++f.attempts;
    if (solver.factorize(H, shift)) {
      f.shift = shift;
      return f;
    }
  }
  throw SolveError(fmt::format("factorize_shifted: H + λI not positive definite after {} attempts (λ up to {:.3e})",
                               f.attempts, first * std::pow(10.0, f.attempts - 2)));
}

void Dogleg::prepare(const BlockMatrix3& H, const VecX& g) {
  m_g = g;
  m_gg = g.squaredNorm();
  m_g_norm = std::sqrt(m_gg);
  m_prepared = true;
  if (m_g_norm == 0.0) {
    m_newton = VecX::Zero(g.size());
    m_gHg = m_gp = m_gHp = m_pHp = m_newton_norm = 0.0;
    return;
  }
  VecX Hv;
  H.multiply(g, Hv);
  m_gHg = g.dot(Hv);
  const auto f = factorize_shifted(m_cholmod, H, 40, m_shift);
  m_factorizations += f.attempts;
  m_shift = f.shift;
  if (f.shift > 0.0) ++m_fallbacks;
  m_cholmod.solve(-g, m_newton);
  // A nearly singular H + λI can overflow the solve; the dogleg then degenerates to the Cauchy point.
  if (!m_newton.allFinite()) m_newton.setZero();
  m_gp = g.dot(m_newton);
  H.multiply(m_newton, Hv);
  m_gHp = g.dot(Hv);
  m_pHp = m_newton.dot(Hv);
  m_newton_norm = m_newton.norm();
}

double Dogleg::decrease(double a, double b) const {
  const double gs = a * m_gg + b * m_gp;
  const double sHs = a * a * m_gHg + 2.0 * a * b * m_gHp + b * b * m_pHp;
  return -(gs + 0.5 * sHs);
}

QpResult Dogleg::step(double delta) const {
  if (!m_prepared) throw_error("Dogleg::step called before prepare");
  QpResult out;
  if (m_g_norm == 0.0) {
    out.s = VecX::Zero(m_g.size());
    return out;
  }
  // Steps are s = a·g + b·p_B; the model of such a step needs only the scalars of prepare().
  double a = 0.0, b = 0.0;
  if (m_newton_norm > 0.0 && m_newton_norm <= delta) {
    b = 1.0;
    out.reason = QpStop::Converged;
  } else if (m_newton_norm > 0.0 && !(m_gHg > 0.0)) {
    // No Cauchy minimizer along −g (the segment 0 → p_U is unbounded): the Newton point of H + λI, cut at Δ.
    b = delta / m_newton_norm;
    out.reason = QpStop::Boundary;
  } else if (m_newton_norm > 0.0) {
    const double u = m_gg / m_gHg;  // p_U = −u·g
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
  out.s = a * m_g + b * m_newton;
  const double norm = out.s.norm();
  if (norm > delta) {
    a *= delta / norm;
    b *= delta / norm;
    out.s *= delta / norm;
  }
  out.model_decrease = decrease(a, b);
  return out;
}

}  // namespace mgcloth::linalg
