#pragma once
#include <mgcloth/solvers/newton_linear.hpp>
#include <mgcloth/solvers/line_search.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

namespace mgcloth::solvers {

struct NewtonParams {
  LinearSolveParams linear;
  bool project_psd = true;  ///< per-element PSD projection of the Hessian
  /// Below this relative gradient, the exact (unprojected) Hessian is tried first and kept when it is positive
  /// definite: near a stable minimum it usually is, and exact Newton converges quadratically where the projected
  /// Hessian (which misrepresents compressed elements) only converges linearly. 0 disables.
  double exact_hessian_below = 1e-2;
  LineSearchParams line_search;
  /// Take the full step without a line search (Projective Dynamics' global step, whose local step keeps the
  /// iteration stable).
  bool use_line_search = true;
  /// The matrix does not depend on x (Projective Dynamics): it is assembled and factored on the first solve and
  /// later solves reassemble it only to refactor when it changed (a new contact set).
  bool constant_matrix = false;
  bool projective = false;  ///< a PD local/global preset: minimizes the Projective Dynamics form only
};

/// Newton's method with a backtracking line search: H d = −∇E with the (projected) Hessian, solved by a linear
/// solver (direct, or iterative to a forcing tolerance: inexact Newton); if H is not positive definite,
/// H + σI with growing σ (Levenberg) is used for that iteration.
/// Convergence is measured by the gradient norm relative to the start point's.
class Newton final : public NonlinearSolver {
 public:
  explicit Newton(NewtonParams params = {});
  explicit Newton(NewtonParams params, std::string name) : Newton(std::move(params)) { m_name = std::move(name); }
  std::string name() const override { return m_name; }
  /// The Projective Dynamics presets keep one constant matrix per step, which cannot hold a contact barrier whose
  /// stiffness grows without bound: they are refused with cloth contact.
  bool supports_step_limits() const override { return !m_params.projective; }
  std::vector<physics::EnergyForm> energy_forms() const override {
    if (m_params.projective) return {physics::EnergyForm::Projective};
    return NonlinearSolver::energy_forms();
  }
  bool needs_hierarchy() const override { return solvers::needs_hierarchy(m_params.linear.method); }
  /// −∇E·d with H d = −∇E solved to the forcing tolerance; not for Projective Dynamics' constant matrix.
  bool estimates_decrement() const override { return !m_params.constant_matrix && !m_params.projective; }
  /// Linear iterations (CG iterations or V-cycles; 1 per direct solve) summed over the last minimize().
  long linear_iterations() const { return m_linear_iterations; }
  SolveReport minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) override;
  /// The linear solver's (multigrid with Chebyshev smoothing: its radii); empty for the others.
  std::string carried_state() const override;
  void restore_carried_state(std::string_view state) override;

 private:
  NewtonParams m_params;
  std::unique_ptr<NewtonLinearSolver> m_linear;
  std::vector<const linalg::StencilTable*> m_linear_for;  ///< the hierarchy m_linear was built for
  std::string m_name = "newton";
  linalg::BlockMatrix3 m_hessian, m_scratch;
  bool m_have_constant = false;
  long m_linear_iterations = 0;
  std::vector<double> m_restore;  ///< restore_carried_state() for the linear solver, once it exists
};

}  // namespace mgcloth::solvers
