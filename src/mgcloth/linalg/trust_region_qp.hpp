#pragma once
#include <mgcloth/linalg/block_matrix.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace mgcloth::linalg {

/// Approximate solvers of the trust-region subproblem (Kopaničáková 2019, eq. 4.1)
///   min m(s) = gᵀs + ½ sᵀHs  subject to  ‖s‖ ≤ Δ,
/// for a symmetric, possibly indefinite H, in ‖·‖₂ or, given a NormMetric, in ‖·‖_M. Every solver returns a step
/// with at least the Cauchy point's model decrease (the Cauchy point of the same norm), so the sufficient decrease
/// condition (SDC) holds with κ = 1 relative to the Cauchy point.

/// The trust-region norm ‖s‖_M = √(sᵀ(M ⊗ I₃)s) for a symmetric positive definite M over the points: the
/// level-dependent norm of RMTR (Kopaničáková 2019, eqs. 4.8-4.9), ‖s‖_l = ‖I s‖₂ with I the prolongation
/// composed to the finest level, is that of M = IᵀI. In this norm the steepest-descent direction is −M⁻¹g: the
/// Cauchy point and the dogleg's first leg follow it, and the CG is preconditioned by M (Conn-Gould-Toint, Trust
/// Region Methods, §7.5.1). Nothing below depends on the blocks being scalar; an SPD BlockMatrix3 with full 3×3
/// blocks works too. Not copyable (it owns a factorization) but movable; solvers hold it by pointer. solve() uses
/// CHOLMOD's workspace, so one NormMetric must not serve two solves at the same time.
class NormMetric {
 public:
  /// M as a BlockMatrix3 whose blocks are scalar multiples of I₃ (m_ij I₃). Factorizes it once (CholmodSolver);
  /// throws mgcloth::Error when M is not positive definite, not symmetric (to 1e-12·max|m_ij|) or has a non-finite
  /// entry.
  explicit NormMetric(BlockMatrix3 M);
  NormMetric(const NormMetric&) = delete;
  NormMetric& operator=(const NormMetric&) = delete;
  NormMetric(NormMetric&&) noexcept = default;
  NormMetric& operator=(NormMetric&&) noexcept = default;

  /// Number of points (block rows); vectors have 3·rows() entries.
  Index rows() const { return m_matrix.rows(); }
  const BlockMatrix3& matrix() const { return m_matrix; }
  /// out = M s.
  void multiply(const VecX& s, VecX& out) const;
  /// out = M⁻¹ r (two triangular solves; no factorization).
  void solve(const VecX& r, VecX& out) const;
  /// ‖s‖_M = √(sᵀMs).
  double norm(const VecX& s) const;
  /// aᵀ M b.
  double dot(const VecX& a, const VecX& b) const;

 private:
  BlockMatrix3 m_matrix;
  std::unique_ptr<CholmodSolver> m_cholmod;
};

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
  double norm = 0.0;            ///< ‖s‖ in the subproblem's norm: ‖s‖_M with a metric, ‖s‖₂ without
};

/// The Cauchy point: the model's minimizer along the steepest-descent direction d inside the ball (Nocedal-Wright
/// eq. 4.11-4.12); along d to the boundary when dᵀHd ≤ 0. d = −g in ‖·‖₂; d = −M⁻¹g, the steepest descent of
/// ‖·‖_M, with a metric (one M solve).
QpResult cauchy_point(const BlockMatrix3& H, const VecX& g, double delta, const NormMetric* metric = nullptr);

/// Steihaug-Toint truncated CG (Nocedal-Wright Alg. 7.2) from s = 0: stops at ‖r‖ ≤ rel_tol·‖g‖, at the boundary,
/// at negative curvature (then goes to the boundary point along d with the lower model) or after max_iters
/// iterations (≤ 0: 3·dofs). Its first iterate is the Cauchy point (of the metric's norm, with one), and a final
/// step that lost model decrease to round-off against it is replaced by the Cauchy point, so SDC holds in floating
/// point too. With a metric the constraint is ‖s‖_M ≤ Δ and the CG is preconditioned by M (Conn-Gould-Toint Alg. 7.5.1): the
/// iterates' M-norms grow monotonically, so the first crossing of ‖s‖_M = Δ ends it as in ℓ2; each iteration adds
/// one M solve and one M product. The stopping test stays ‖r‖₂ ≤ rel_tol·‖g‖₂ in both cases.
QpResult steihaug_cg(const BlockMatrix3& H, const VecX& g, double delta, int max_iters, double rel_tol,
                     const NormMetric* metric = nullptr);

/// A smoothing step for the subproblem (beyond Kopaničáková 2019; the smoother of Wang 2018 §4.3): `sweeps`
/// symmetric multi-color block Gauss-Seidel sweeps on H s = −g from s = 0, then the model's minimizer along that
/// direction inside the ball (‖·‖_M with a metric). Unlike a few CG iterations, which reduce the error components of
/// the largest eigenvalues first, Gauss-Seidel damps the locally oscillatory ones whatever their eigenvalue, the
/// job of a multigrid smoother. Where the sweeps give no descent direction (H indefinite) or less decrease than the
/// Cauchy point, the Cauchy point is returned, so SDC holds. `gs` must hold H (set_matrix); `iterations` reports
/// the sweeps.
QpResult gauss_seidel_step(const BlockMatrix3& H, const VecX& g, double delta, int sweeps,
                           const class MultiColorGaussSeidel& gs, const NormMetric* metric = nullptr);
/// The same with `sweeps` symmetric multiplicative Schwarz sweeps over overlapping patches (PatchSmoother).
QpResult patch_step(const BlockMatrix3& H, const VecX& g, double delta, int sweeps, const class PatchSmoother& patches,
                    const NormMetric* metric = nullptr);

/// What a shifted Cholesky factorization needed.
struct ShiftedFactorization {
  double shift = 0.0;   ///< λ of the factorization that succeeded (0: H itself is positive definite)
  int attempts = 0;     ///< numeric factorizations tried
  double failed = -1.0; ///< the largest λ tried that did not factorize (0: only H itself; −1: none failed)
};

/// Factorizes H, or H + λI when CHOLMOD reports H not positive definite, with λ from max(1e-8·max|diag H|,
/// start / 10), then ×10 per failed attempt, until the factorization succeeds (`start`: the shift a previous,
/// similar matrix needed; 0 for none). Throws SolveError after `max_attempts` failures.
/// `bisections` > 0 then narrows λ between the last failed and the first successful shift by that many
/// geometric bisections (each one factorization, plus one where the last one failed), so that λ is within a
/// factor 10^(2^-bisections) of the smallest shift that factorizes.
/// With `not_definite` non-null, an H that is not positive definite returns at once with *not_definite = true.
ShiftedFactorization factorize_shifted(CholmodSolver& solver, const BlockMatrix3& H, int max_attempts = 40,
                                       double start = 0.0, int bisections = 0, bool* not_definite = nullptr);

/// Powell's dogleg (Nocedal-Wright §4.1) on the exact Hessian. prepare() factorizes once per point x and computes
/// the Cauchy and Newton points; step() then returns the dogleg point for any radius without refactoring, so a
/// rejected trust-region step (smaller Δ at the same x) costs no factorization. An H that is not positive definite
/// gives the Newton point of H + λI (factorize_shifted); the step's model decrease is always that of the true H.
/// The symbolic analysis of CHOLMOD is reused for every H with the same pattern.
/// With a metric the constraint is ‖s‖_M ≤ Δ: the Newton point is unchanged, the first leg runs to the Cauchy point
/// along −M⁻¹g, and the path meets ‖·‖_M = Δ where the M-inner products of prepare() say. The metric is used again
/// by step() (to measure the step), so it must outlive the prepare()d state, i.e. every step() until the next
/// prepare().
/// With set_radius_shift(true) an indefinite H gets the λ of the exact trust-region step instead (beyond the
/// paper): step(Δ) solves ‖(H + λI)⁻¹g‖ = Δ for λ, a few factorizations per radius, so that Δ, not the smallest
/// shift that factorizes, decides how far the step goes along the soft and negative-curvature directions.
class Dogleg {
 public:
  void prepare(const BlockMatrix3& H, const VecX& g, const NormMetric* metric = nullptr);
  /// The dogleg point for radius Δ. With set_radius_shift(true) and an H that was not positive definite, it first
  /// moves λ so that the Newton point of H + λI lies on the boundary (radius_shift), which refactorizes; H and g of
  /// prepare() must then still be alive and unchanged.
  QpResult step(double delta);
  /// prepare() that factorizes H itself only: returns false, and leaves the dogleg unprepared, where H is not
  /// positive definite (one failed factorization), so that the caller can choose another model.
  bool prepare_definite(const BlockMatrix3& H, const VecX& g, const NormMetric* metric = nullptr) {
    return prepare_model(H, g, metric, /*definite_only=*/true);
  }
  /// Geometric bisections of the shift of an indefinite H (factorize_shifted); 0: the first decade that works.
  void set_shift_bisections(int n) { m_bisections = n; }
  /// Where H is indefinite, choose λ by the radius (the secular equation ‖(H + λI)⁻¹g‖ = Δ) instead of by the
  /// factorization alone.
  void set_radius_shift(bool on) { m_radius_shift = on; }

  /// Numeric factorizations done by every prepare() and step() so far.
  int factorizations() const { return m_factorizations; }
  /// prepare() calls whose H was not positive definite and needed a shift.
  int fallbacks() const { return m_fallbacks; }
  /// λ of the current Newton point (0 when H was positive definite).
  double shift() const { return m_shift; }
  /// The shift an indefinite H's search starts from in the next prepare() (it starts a decade below the last
  /// shift): a checkpoint's shift() given back, so that a resumed run factorizes as the uninterrupted one.
  void set_start_shift(double shift) { m_shift = shift; }
  /// Symbolic analyses of the CHOLMOD solver (one per Hessian pattern).
  int analyses() const { return m_cholmod.analyses(); }
  /// ‖p_B‖ (‖p_B‖_M with a metric) of the current Newton point: the radius beyond which step() returns it.
  double newton_norm() const { return m_newton_norm; }

 private:
  /// prepare(); with definite_only, false (and unprepared) where H itself does not factorize.
  bool prepare_model(const BlockMatrix3& H, const VecX& g, const NormMetric* metric, bool definite_only);
  /// Model decrease −(gᵀs + ½ sᵀHs) of s = a·y + b·p_B, from the scalar products computed in prepare().
  double decrease(double a, double b) const;
  /// p_B = −(H + λI)⁻¹g from the factor the solver holds, and the scalars of p_B. Where the solve overflows:
  /// false, and p_B = 0 with keep_overflow, else the Newton point unchanged.
  bool newton_point(double shift, bool keep_overflow);
  void set_newton(VecX p, double shift);
  /// Safeguarded Newton on the secular equation 1/‖p(λ)‖ = 1/Δ (Moré-Sorensen 1983; Nocedal-Wright Alg. 4.3),
  /// λ bracketed by shifts that failed to factorize or gave ‖p‖ > Δ below and ‖p‖ < Δ above. Leaves the Newton
  /// point at the λ whose ‖p(λ)‖ ≤ 1.1Δ came closest to Δ.
  void radius_shift(double delta);
  int m_bisections = 0;
  bool m_radius_shift = false;

  CholmodSolver m_cholmod;
  const NormMetric* m_metric = nullptr;
  const BlockMatrix3* m_H = nullptr;
  VecX m_g;
  /// y = M⁻¹g (g itself in ℓ2), so that −y is the steepest descent of the norm, and the Newton point
  /// p_B = −(H + λI)⁻¹g. The scalars are in terms of y: m_gg = gᵀy = ‖y‖²_M, m_gHg = yᵀHy, m_gp = gᵀp_B
  /// = yᵀMp_B, m_gHp = yᵀHp_B, m_pHp = p_BᵀHp_B, m_g_norm = ‖y‖_M, m_newton_norm = ‖p_B‖_M.
  VecX m_y, m_newton;
  double m_gg = 0.0, m_gHg = 0.0, m_gp = 0.0, m_gHp = 0.0, m_pHp = 0.0;
  double m_g_norm = 0.0, m_newton_norm = 0.0;
  double m_shift = 0.0;
  /// Shifts tried since prepare(), as (λ, ‖p(λ)‖), ‖p‖ = ∞ where H + λI did not factorize: the bracket of every
  /// later radius.
  std::vector<std::pair<double, double>> m_tried;
  bool m_shift_on_sphere = false;  ///< step(): the radius shift put ‖p_B‖ within 10% of Δ
  bool m_factor_holds = false;  ///< the solver holds the factor of H + m_shift·I
  int m_factorizations = 0;
  int m_fallbacks = 0;
  bool m_prepared = false;
};

}  // namespace mgcloth::linalg
