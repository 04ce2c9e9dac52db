#pragma once
#include <mgcloth/linalg/stencil_table.hpp>
#include <mgcloth/linalg/hypre_amg.hpp>
#include <mgcloth/solvers/linear_multigrid.hpp>

#include <memory>
#include <string>
#include <vector>

namespace mgcloth::solvers {

/// How Newton's method solves H d = −g.
struct LinearSolveParams {
  /// cholmod: sparse Cholesky (exact). pcg-mg: CG preconditioned by one multigrid V-cycle (Wang 2018 §3.1 on the
  /// mesh hierarchy). mg: multigrid V-cycles as the solver. pcg-amg: CG with hypre BoomerAMG. pcg-jacobi: CG with
  /// block Jacobi. The iterative ones stop at |r| <= rel_tol |b|.
  std::string method = "cholmod";
  /// Iterative methods: 0 picks the inexact-Newton forcing term min(0.01, |g_k| / |g_0|) per iteration, which keeps
  /// Newton's quadratic local convergence (the forcing falls like the gradient) while not over-solving the early,
  /// far-from-minimum systems. Looser forcing (0.1 or sqrt of the ratio) saved linear iterations but cost more
  /// Newton iterations, each of which pays a Hessian assembly and a line search.
  double rel_tol = 0.0;
  int max_iters = 1000;  ///< per linear solve (CG iterations or V-cycles)
  MultigridParams multigrid;
  linalg::HypreAmgParams amg;
};

std::vector<std::string> linear_methods();
/// Whether `method` needs Problem::prolongations.
bool needs_hierarchy(const std::string& method);

/// A linear solver for the (possibly shifted) Newton systems.
class NewtonLinearSolver {
 public:
  virtual ~NewtonLinearSolver() = default;
  /// Prepares for solves with A + shift·I (A must outlive the solves). False when that matrix is found not
  /// positive definite (a direct factorization, or the coarsest multigrid level, fails).
  virtual bool compute(const linalg::BlockMatrix3& A, double shift) = 0;
  /// x = (A + shift·I)⁻¹ b to |r| <= rel_tol |b| (exactly for a direct method). False when the iteration finds the
  /// matrix not positive definite.
  virtual bool solve(const VecX& b, VecX& x, double rel_tol) = 0;
  /// Iterations of the last solve (1 for a direct solve).
  int iterations() const { return m_iterations; }
  /// What the next compute() depends on besides its matrix (multigrid: the Chebyshev radii estimated on the first
  /// matrix), for checkpoints; empty when nothing.
  virtual std::vector<double> carried() const { return {}; }
  /// Throws InputError when `values` do not fit this solver.
  virtual void restore(const std::vector<double>& values);

 protected:
  int m_iterations = 0;
};

/// Builds the solver; multigrid methods take the hierarchy's prolongations (finest first; none means a single
/// level, solved directly) and the pattern of the finest matrices. Throws InputError for an unknown method.
std::unique_ptr<NewtonLinearSolver> make_newton_linear_solver(const LinearSolveParams& params,
                                                              const std::vector<const linalg::StencilTable*>& prolongations,
                                                              const linalg::BlockMatrix3& pattern);

}  // namespace mgcloth::solvers
