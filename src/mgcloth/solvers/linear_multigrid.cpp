#include <mgcloth/core/error.hpp>
#include <mgcloth/solvers/linear_multigrid.hpp>

namespace mgcloth::solvers {

LinearMultigrid::LinearMultigrid(std::vector<const hierarchy::TransferTable*> p, const linalg::BlockMatrix3& fine_pattern,
                                 MultigridParams params)
    : m_p(std::move(p)), m_levels(m_p.size() + 1), m_params(params) {
  const linalg::BlockMatrix3* pattern = &fine_pattern;
  for (size_t l = 0; l < m_p.size(); ++l) {
    const auto& t = *m_p[l];
    if (t.num_fine != pattern->rows())
      throw Error(fmt::format("multigrid: level {} has {} vertices but its prolongation expects {}", l, pattern->rows(), t.num_fine));
    m_levels[l].smoother = linalg::MultiColorGaussSeidel(*pattern);
    m_levels[l].rap = linalg::GalerkinProduct(*pattern, t.num_coarse, t.offsets, t.indices, t.weights);
    m_levels[l + 1].A = m_levels[l].rap.coarse_pattern();
    pattern = &m_levels[l + 1].A;
  }
}

const linalg::BlockMatrix3& LinearMultigrid::matrix(Index l) const { return l == 0 ? *m_fine : m_levels[l].A; }

void LinearMultigrid::set_matrix(const linalg::BlockMatrix3& A) {
  m_fine = &A;
  for (size_t l = 0; l + 1 < m_levels.size(); ++l) {
    const auto& Al = matrix(static_cast<Index>(l));
    m_levels[l].smoother.set_matrix(Al);
    m_levels[l].rap.compute(Al, m_levels[l + 1].A);  // Wang 2018 §3.1: A_{h+1} = Iᵀ A_h I
  }
  if (!m_coarse_solver.factorize(matrix(num_levels() - 1)))
    throw SolveError("multigrid: the coarsest Galerkin matrix is not positive definite");
}

void LinearMultigrid::cycle(Index l, const VecX& b, VecX& x) const {
  if (l == num_levels() - 1) {
    m_coarse_solver.solve(b, x);
    return;
  }
  const auto& A = matrix(l);
  const auto& smoother = m_levels[l].smoother;
  smoother.symmetric_sweeps(b, x, m_params.pre_smooth);
  const VecX r = b - A * x;
  VecX rc, ec = VecX::Zero(3 * matrix(l + 1).rows()), correction;
  m_p[l]->apply_transpose(r, rc);
  cycle(l + 1, rc, ec);
  m_p[l]->apply(ec, correction);
  x += correction;
  smoother.symmetric_sweeps(b, x, m_params.post_smooth);
}

void LinearMultigrid::vcycle(const VecX& b, VecX& x) const {
  if (!m_fine) throw Error("multigrid used before set_matrix()");
  cycle(0, b, x);
}

void LinearMultigrid::precondition(const VecX& r, VecX& z) const {
  z = VecX::Zero(r.size());
  vcycle(r, z);
}

int pcg(const linalg::BlockMatrix3& A, const VecX& b, VecX& x, const std::function<void(const VecX&, VecX&)>& M,
        double rel_tol, int max_iters) {
  VecX r = b - A * x, z, p, Ap;
  const double target = rel_tol * b.norm();
  if (r.norm() <= target) return 0;
  M(r, z);
  p = z;
  double rz = r.dot(z);
  for (int k = 1; k <= max_iters; ++k) {
    A.multiply(p, Ap);
    const double pAp = p.dot(Ap);
    if (!(pAp > 0.0)) throw SolveError(fmt::format("PCG: matrix not positive definite (pᵀAp = {})", pAp));
    const double alpha = rz / pAp;
    x += alpha * p;
    r -= alpha * Ap;
    if (r.norm() <= target) return k;
    M(r, z);
    const double rz_new = r.dot(z);
    p = z + (rz_new / rz) * p;
    rz = rz_new;
  }
  return max_iters;
}

}  // namespace mgcloth::solvers
