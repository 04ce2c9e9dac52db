#pragma once
#include <mgcloth/linalg/block_matrix.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>

#include <string>

namespace mgcloth::linalg {

/// Approximate solvers of the trust-region subproblem (Kopaničáková 2019, eq. 4.1)
///   min m(s) = gᵀs + ½ sᵀHs  subject to  ‖s‖₂ ≤ Δ,
/// for a symmetric, possibly indefinite H. Every solver returns a step with at least the Cauchy point's model
/// decrease, so the sufficient decrease condition (SDC) holds with κ = 1 relative to the Cauchy point.

/// Why a subproblem solve ended.
enum class QpStop {
  Converged,          ///< interior solution (CG residual below tolerance, or the dogleg's Newton point)
  Boundary,           ///< the step reached ‖s‖ = Δ
  NegativeCurvature,  ///< CG met dᵀHd ≤ 0 and went to the boundary along d
  MaxIters,           ///< CG iteration limit
};
std::string to_string(QpStop reason);

struct QpResult {
  VecX s;
  double model_decrease = 0.0;  ///< −(gᵀs + ½ sᵀHs) with the true H; > 0 unless g = 0
  int iterations = 0;           ///< CG iterations (0 for the dogleg)
  QpStop reason = QpStop::Converged;
};

/// The Cauchy point: the model's minimizer along −g inside the ball (Nocedal-Wright eq. 4.11-4.12); along −g to
/// the boundary when gᵀHg ≤ 0.
QpResult cauchy_point(const BlockMatrix3& H, const VecX& g, double delta);

/// Steihaug-Toint truncated CG (Nocedal-Wright Alg. 7.2) from s = 0: stops at ‖r‖ ≤ rel_tol·‖g‖, at the boundary,
/// at negative curvature (then goes to the boundary point along d with the lower model) or after max_iters
/// iterations (≤ 0: 3·dofs). Its first iterate is the Cauchy point, and a final step that lost model decrease to
/// round-off against it is replaced by the Cauchy point, so SDC holds in floating point too.
QpResult steihaug_cg(const BlockMatrix3& H, const VecX& g, double delta, int max_iters, double rel_tol);

/// What a shifted Cholesky factorization needed.
struct ShiftedFactorization {
  double shift = 0.0;  ///< λ of the factorization that succeeded (0: H itself is positive definite)
  int attempts = 0;    ///< numeric factorizations tried
};

/// Factorizes H, or H + λI when CHOLMOD reports H not positive definite, with λ from max(1e-8·max|diag H|,
/// start / 10), then ×10 per failed attempt, until the factorization succeeds (`start`: the shift a previous,
/// similar matrix needed; 0 for none). Throws SolveError after `max_attempts` failures.
ShiftedFactorization factorize_shifted(CholmodSolver& solver, const BlockMatrix3& H, int max_attempts = 40,
                                       double start = 0.0);

/// Powell's dogleg (Nocedal-Wright §4.1) on the exact Hessian. prepare() factorizes once per point x and computes
/// the Cauchy and Newton points; step() then returns the dogleg point for any radius without refactoring, so a
/// rejected trust-region step (smaller Δ at the same x) costs no factorization. An H that is not positive definite
/// gives the Newton point of H + λI (factorize_shifted); the step's model decrease is always that of the true H.
/// The symbolic analysis of CHOLMOD is reused for every H with the same pattern.
class Dogleg {
 public:
  void prepare(const BlockMatrix3& H, const VecX& g);
  QpResult step(double delta) const;

  /// Numeric factorizations done by every prepare() so far (step() does none).
  int factorizations() const { return m_factorizations; }
  /// prepare() calls whose H was not positive definite and needed a shift.
  int fallbacks() const { return m_fallbacks; }
  /// λ of the last prepare() (0 when H was positive definite).
  double shift() const { return m_shift; }
  /// Symbolic analyses of the CHOLMOD solver (one per Hessian pattern).
  int analyses() const { return m_cholmod.analyses(); }
  /// ‖p_B‖ of the last prepare(): the radius beyond which step() returns the Newton point.
  double newton_norm() const { return m_newton_norm; }

 private:
  /// Model decrease −(gᵀs + ½ sᵀHs) of s = a·g + b·p_B, from the scalar products computed in prepare().
  double decrease(double a, double b) const;

  CholmodSolver m_cholmod;
  VecX m_g, m_newton;  ///< g and the Newton point p_B = −(H + λI)⁻¹g
  double m_gg = 0.0, m_gHg = 0.0, m_gp = 0.0, m_gHp = 0.0, m_pHp = 0.0;
  double m_g_norm = 0.0, m_newton_norm = 0.0;
  double m_shift = 0.0;
  int m_factorizations = 0;
  int m_fallbacks = 0;
  bool m_prepared = false;
};

}  // namespace mgcloth::linalg
