#pragma once
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/solvers/line_search.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

namespace mgcloth::solvers {

/// The comparison solvers of Kopaničáková 2019, §7.4.1, all on the exact Hessian.
enum class ExactNewtonMode {
  LineSearch,  ///< "newton-ls": backtracking (Armijo) line-search Newton (Nocedal-Wright ch. 3)
  Damped,      ///< "newton-damped": x += α·p with constant α, no line search and no convergence control
  Linearized,  ///< "linearized": the "linearized equation" of Baraff-Witkin 1998, one linear solve per time step
};

struct ExactNewtonParams {
  ExactNewtonMode mode = ExactNewtonMode::LineSearch;
  double alpha = 0.3;  ///< the damped step (§7.4.1: α = 0.3)
  /// Plain backtracking: no expansion of steps the model underestimated (the paper's LS Newton).
  LineSearchParams line_search = {.expand_ratio = 0.0};
};

/// Newton's method on the exact Hessian ∇²E (never PSD-projected): p = −H⁻¹∇E by CHOLMOD, with H + λI
/// (linalg::factorize_shifted) where H is not positive definite, and −∇E where p is not a descent direction.
/// The three modes differ only in how p is used (ExactNewtonMode). "linearized" ignores Stop::max_iters: it
/// takes one step (none when the start already meets the gradient target) and reports status "converged" when
/// the step met the target, "linearized" when not. "newton-damped" may diverge: a non-finite energy or gradient
/// is a SolveError.
class ExactNewton final : public NonlinearSolver {
 public:
  /// An empty name is the mode's: "newton-ls", "newton-damped" or "linearized".
  explicit ExactNewton(ExactNewtonParams params = {}, std::string name = "");
  std::string name() const override { return m_name; }
  bool supports_step_limits() const override { return true; }
  /// −∇E·p of its Newton direction (the exact Hessian, shifted where it is not positive definite).
  bool estimates_decrement() const override { return true; }
  /// Report counters: hessian_assemblies, factorizations, cholmod_fallbacks, max_shift, steepest_descent_steps,
  /// line_search_evaluations.
  SolveReport minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) override;
  /// The last Levenberg shift, where the next shifted factorization starts its search.
  std::string carried_state() const override;
  void restore_carried_state(std::string_view state) override;

 private:
  /// p = −(H + λI)⁻¹g at x (the exact Hessian), −g when that is not a descent direction.
  void direction(const physics::Objective& objective, const VecX& x, const VecX& g, VecX& p);

  ExactNewtonParams m_params;
  std::string m_name;
  linalg::CholmodSolver m_cholmod;
  linalg::BlockMatrix3 m_hessian;
  int m_hessian_assemblies = 0, m_factorizations = 0, m_fallbacks = 0, m_steepest = 0;
  double m_last_shift = 0.0;
  double m_max_shift = 0.0;
};

}  // namespace mgcloth::solvers
