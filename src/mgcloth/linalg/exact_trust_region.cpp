#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/exact_trust_region.hpp>

#include <Eigen/Eigenvalues>
#include <cmath>

namespace mgcloth::linalg {

namespace {
MatX dense(const BlockMatrix3& A) {
  const Index n = A.rows();
  MatX D = MatX::Zero(3 * n, 3 * n);
  for (Index i = 0; i < n; ++i)
    for (Index k = A.row_offsets()[i]; k < A.row_offsets()[i + 1]; ++k)
      D.block<3, 3>(3 * i, 3 * A.col_indices()[k]) = A.block(k);
  return D;
}
}  // namespace

void ExactTrustRegion::prepare(const BlockMatrix3& H, const VecX& g, const NormMetric* metric) {
  const Index n = 3 * H.rows();
  if (n > max_dofs)
    throw Error(fmt::format("exact trust-region subproblem: {} dofs, more than the {} a dense eigen-decomposition is "
                            "meant for (use it on the coarsest level only)", n, max_dofs));
  MatX Hd = dense(H);
  Hd = 0.5 * (Hd + Hd.transpose()).eval();
  if (metric) {
    const MatX Md = dense(metric->matrix());
    Eigen::GeneralizedSelfAdjointEigenSolver<MatX> eig(Hd, Md);
    if (eig.info() != Eigen::Success) throw SolveError("exact trust-region subproblem: eigen-decomposition failed");
    m_V = eig.eigenvectors();
    m_lambda = eig.eigenvalues();
  } else {
    Eigen::SelfAdjointEigenSolver<MatX> eig(Hd);
    if (eig.info() != Eigen::Success) throw SolveError("exact trust-region subproblem: eigen-decomposition failed");
    m_V = eig.eigenvectors();
    m_lambda = eig.eigenvalues();
  }
  m_a = m_V.transpose() * g;
}

QpResult ExactTrustRegion::step(double delta) const {
  const Index n = m_lambda.size();
  const double lmin = m_lambda[0], lmax = std::abs(m_lambda[n - 1]);
  const double a_norm = m_a.norm();
  // ‖s(σ)‖_M² = Σ a_i² / (λ_i + σ)², decreasing in σ > −λ_min.
  const auto norm_at = [&](double sigma) {
    double s = 0.0;
    for (Index i = 0; i < n; ++i) {
      const double d = m_lambda[i] + sigma;
      if (d > 0.0) s += m_a[i] * m_a[i] / (d * d);
    }
    return std::sqrt(s);
  };
  VecX c(n);
  QpResult out;
  const double tiny = 1e-13 * std::max(lmax, 1e-300);
  if (lmin > tiny && norm_at(0.0) <= delta) {
    c = -m_a.cwiseQuotient(m_lambda);
    out.reason = QpStop::Converged;
  } else {
    // The boundary solution: σ > max(0, −λ_min) with ‖s(σ)‖ = Δ; bracketed by lo and hi = ‖a‖/Δ − λ_min, where
    // ‖s‖ ≤ ‖a‖ / (λ_min + σ) = Δ.
    double lo = std::max(0.0, -lmin), hi = std::max(lo, a_norm / delta - lmin) + tiny;
    // Components along the lowest eigenvalue(s) that g does not see: the hard case when even σ → −λ_min leaves
    // ‖s‖ < Δ; then s = s(−λ_min) + τ v_min fills the ball.
    double norm_lo = 0.0;
    for (Index i = 0; i < n; ++i) {
      const double d = m_lambda[i] - lmin;
      if (d > tiny) norm_lo += m_a[i] * m_a[i] / (d * d);
      else if (std::abs(m_a[i]) > 1e-12 * std::max(a_norm, 1e-300)) norm_lo = kInf;
    }
    norm_lo = std::sqrt(norm_lo);
    if (lmin <= tiny && norm_lo < delta) {
      const double sigma = -lmin;
      for (Index i = 0; i < n; ++i) {
        const double d = m_lambda[i] + sigma;
        c[i] = d > tiny ? -m_a[i] / d : 0.0;
      }
      const double tau = std::sqrt(std::max(0.0, delta * delta - c.squaredNorm()));
      c[0] += m_a[0] <= 0.0 ? tau : -tau;  // either sign is optimal; this one does not oppose g
    } else {
      // Newton on the secular equation 1/‖s(σ)‖ − 1/Δ = 0 (concave, Moré-Sorensen), safeguarded by bisection.
      double sigma = hi;
      for (int it = 0; it < 100; ++it) {
        const double ns = norm_at(sigma);
        if (std::abs(ns - delta) <= 1e-10 * delta) break;
        if (ns > delta) lo = sigma; else hi = sigma;
        // d‖s‖/dσ = −Σ a_i²/(λ_i+σ)³ / ‖s‖
        double dq = 0.0;
        for (Index i = 0; i < n; ++i) {
          const double d = m_lambda[i] + sigma;
          if (d > 0.0) dq += m_a[i] * m_a[i] / (d * d * d);
        }
        const double dphi = dq / (ns * ns * ns);  // d(1/‖s‖)/dσ
        double next = sigma - (1.0 / ns - 1.0 / delta) / dphi;
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (next == sigma) break;
        sigma = next;
      }
      for (Index i = 0; i < n; ++i) {
        const double d = m_lambda[i] + sigma;
        c[i] = d > 0.0 ? -m_a[i] / d : 0.0;
      }
    }
    out.reason = QpStop::Boundary;
  }
  out.s = m_V * c;
  out.model_decrease = -(m_a.dot(c) + 0.5 * c.dot(m_lambda.cwiseProduct(c)));
  out.norm = c.norm();
  return out;
}

}  // namespace mgcloth::linalg
