#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/block_jacobi.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/linalg/pcg.hpp>
#include <mgcloth/solvers/newton_linear.hpp>

namespace mgcloth::solvers {

std::vector<std::string> linear_methods() { return {"cholmod", "pcg-mg", "mg", "pcg-amg", "pcg-jacobi"}; }
bool needs_hierarchy(const std::string& method) { return method == "pcg-mg" || method == "mg"; }

void NewtonLinearSolver::restore(const std::vector<double>& values) {
  if (!values.empty()) throw_input_error("{} values of linear solver state for a solver that keeps none", values.size());
}

namespace {

class Direct final : public NewtonLinearSolver {
 public:
  bool compute(const linalg::BlockMatrix3& A, double shift) override { return m_chol.factorize(A, shift); }
  bool solve(const VecX& b, VecX& x, double) override {
    m_chol.solve(b, x);
    m_iterations = 1;
    return true;
  }

 private:
  linalg::CholmodSolver m_chol;
};

/// Shared by the iterative methods: the matrix (a shifted copy when shift > 0) and CG around a preconditioner.
class Iterative : public NewtonLinearSolver {
 public:
  explicit Iterative(int max_iters) : m_max_iters(max_iters) {}
  bool compute(const linalg::BlockMatrix3& A, double shift) override {
    m_A = &A;
    if (shift > 0.0) {
      m_shifted = A;
      for (Index i = 0; i < A.rows(); ++i) m_shifted.block(m_shifted.diagonal(i)) += shift * Mat3::Identity();
      m_A = &m_shifted;
    }
    try {
      return setup(*m_A);
    } catch (const SolveError&) {
      return false;
    }
  }
  bool solve(const VecX& b, VecX& x, double rel_tol) override {
    x = VecX::Zero(b.size());
    try {
      m_iterations = iterate(b, x, rel_tol);
    } catch (const SolveError&) {
      return false;  // pᵀAp <= 0: not positive definite
    }
    return x.allFinite();
  }

 protected:
  virtual bool setup(const linalg::BlockMatrix3& A) = 0;
  virtual void precondition(const VecX& r, VecX& z) = 0;
  virtual int iterate(const VecX& b, VecX& x, double rel_tol) {
    return linalg::pcg(*m_A, b, x, [this](const VecX& r, VecX& z) { precondition(r, z); }, rel_tol, m_max_iters);
  }

  const linalg::BlockMatrix3* m_A = nullptr;
  linalg::BlockMatrix3 m_shifted;
  int m_max_iters;
};

class Multigrid final : public Iterative {
 public:
  Multigrid(const LinearSolveParams& p, const std::vector<const linalg::StencilTable*>& prolongations,
            const linalg::BlockMatrix3& pattern, bool krylov)
      : Iterative(p.max_iters), m_mg(prolongations, pattern, p.multigrid), m_krylov(krylov) {}

 protected:
  bool setup(const linalg::BlockMatrix3& A) override {
    m_mg.set_matrix(A);  // throws SolveError when the coarsest Galerkin matrix is not positive definite
    return true;
  }
  void precondition(const VecX& r, VecX& z) override { m_mg.precondition(r, z); }
  std::vector<double> carried() const override { return m_mg.smoother_rhos(); }
  void restore(const std::vector<double>& values) override { m_mg.set_smoother_rhos(values); }
  int iterate(const VecX& b, VecX& x, double rel_tol) override {
    if (m_krylov) return Iterative::iterate(b, x, rel_tol);
    const double target = rel_tol * b.norm();
    for (int k = 1; k <= m_max_iters; ++k) {
      m_mg.vcycle(b, x);
      const double r = (b - *m_A * x).norm();
      if (!std::isfinite(r)) throw SolveError("multigrid V-cycles diverged");
      if (r <= target) return k;
    }
    return m_max_iters;
  }

 private:
  LinearMultigrid m_mg;
  bool m_krylov;
};

class JacobiPcg final : public Iterative {
 public:
  using Iterative::Iterative;

 protected:
  bool setup(const linalg::BlockMatrix3& A) override {
    m_jacobi.set_matrix(A);
    return true;
  }
  void precondition(const VecX& r, VecX& z) override { m_jacobi.apply(r, z); }

 private:
  linalg::BlockJacobi m_jacobi;
};

class AmgPcg final : public Iterative {
 public:
  AmgPcg(const LinearSolveParams& p) : Iterative(p.max_iters), m_amg(p.amg) {}

 protected:
  bool setup(const linalg::BlockMatrix3& A) override {
    m_amg.set_matrix(A);
    return true;
  }
  void precondition(const VecX& r, VecX& z) override { m_amg.apply(r, z); }

 private:
  linalg::HypreAmg m_amg;
};

}  // namespace

std::unique_ptr<NewtonLinearSolver> make_newton_linear_solver(const LinearSolveParams& p,
                                                              const std::vector<const linalg::StencilTable*>& prolongations,
                                                              const linalg::BlockMatrix3& pattern) {
  if (p.method == "cholmod") return std::make_unique<Direct>();
  if (p.method == "pcg-jacobi") return std::make_unique<JacobiPcg>(p.max_iters);
  if (p.method == "pcg-amg") return std::make_unique<AmgPcg>(p);
  if (needs_hierarchy(p.method)) {
    // Without prolongations (a mesh at or below the coarsest size) the "hierarchy" is one level: a direct solve.
    return std::make_unique<Multigrid>(p, prolongations, pattern, p.method == "pcg-mg");
  }
  throw_input_error("unknown linear solver \"{}\" (available: {})", p.method, fmt::join(linear_methods(), ", "));
}

}  // namespace mgcloth::solvers
