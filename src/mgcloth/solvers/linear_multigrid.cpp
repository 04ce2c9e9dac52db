#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/chebyshev.hpp>
#include <mgcloth/solvers/linear_multigrid.hpp>

#include <cmath>

namespace mgcloth::solvers {

LinearMultigrid::LinearMultigrid(std::vector<const linalg::StencilTable*> p, const linalg::BlockMatrix3& fine_pattern,
                                 MultigridParams params)
    : m_p(std::move(p)), m_levels(m_p.size() + 1), m_params(params) {
  build_symbolic(fine_pattern);
}

void LinearMultigrid::build_symbolic(const linalg::BlockMatrix3& fine_pattern) {
  m_fine_offsets = fine_pattern.row_offsets();
  m_fine_cols = fine_pattern.col_indices();
  ++m_symbolic_builds;
  m_sizes.clear();
  const linalg::BlockMatrix3* pattern = &fine_pattern;
  m_sizes.push_back(fine_pattern.rows());
  for (size_t l = 0; l < m_p.size(); ++l) {
    const auto& t = *m_p[l];
    if (t.num_rows != pattern->rows())
      throw Error(fmt::format("multigrid: level {} has {} vertices but its prolongation expects {}", l, pattern->rows(), t.num_rows));
    m_levels[l].smoother = linalg::MultiColorGaussSeidel(*pattern, smoother_precision());
    m_levels[l].rap = linalg::GalerkinProduct(*pattern, t);
    m_levels[l + 1].A = m_levels[l].rap.coarse_pattern();
    pattern = &m_levels[l + 1].A;
    m_sizes.push_back(pattern->rows());
  }
  if (!m_params.factorize_coarsest) m_levels.back().smoother = linalg::MultiColorGaussSeidel(*pattern, smoother_precision());
}

const linalg::BlockMatrix3& LinearMultigrid::matrix(Index l) const { return l == 0 ? *m_fine : m_levels[l].A; }

void LinearMultigrid::set_matrix(const linalg::BlockMatrix3& A, const std::vector<char>* constant, long constant_version) {
  // A fine pattern other than the one the hierarchy was built for (contact stencils appeared or disappeared):
  // colorings, Galerkin maps and coarse patterns are redone; the coarsest factorization re-analyses by itself.
  const bool rebuilt = A.row_offsets() != m_fine_offsets || A.col_indices() != m_fine_cols;
  if (rebuilt) {
    build_symbolic(A);
    m_constant_version = -1;
  }
  m_fine = &A;
  if (m_levels.size() > 1) {
    // The constant blocks' share of A_1 is not summed apart on a matrix whose pattern made the hierarchy rebuild
    // (contact can change the pattern at every matrix, and then it would only add a pass), but on the next one.
    linalg::GalerkinProduct& rap = m_levels[0].rap;
    if (!constant) {
      if (rap.has_constant_blocks()) rap.clear_constant_blocks();
      m_constant_version = -1;
    } else if (!rebuilt && m_constant_version != constant_version) {
      rap.set_constant_blocks(*constant);
      rap.compute_constant(A);
      m_constant_version = constant_version;
    }
  }
  for (size_t l = 0; l + 1 < m_levels.size(); ++l) {
    const auto& Al = matrix(static_cast<Index>(l));
    m_levels[l].smoother.set_matrix(Al);
    if (m_params.chebyshev && m_levels[l].rho == 0.0)
      m_levels[l].rho = linalg::estimate_gauss_seidel_rho(Al, m_levels[l].smoother);
    m_levels[l].rap.compute(Al, m_levels[l + 1].A);  // Wang 2018 §3.1: A_{h+1} = Iᵀ A_h I
  }
  const Index last = num_levels() - 1;
  if (!m_params.factorize_coarsest) {
    m_levels[last].smoother.set_matrix(matrix(last));
    if (m_params.chebyshev && m_levels[last].rho == 0.0)
      m_levels[last].rho = linalg::estimate_gauss_seidel_rho(matrix(last), m_levels[last].smoother);
  } else if (!m_coarse_solver.factorize(matrix(last))) {
    throw SolveError("multigrid: the coarsest Galerkin matrix is not positive definite");
  }
}

void LinearMultigrid::multiply(Index l, const VecX& x, VecX& y) const {
  const bool has_smoother = l + 1 < num_levels() || !m_params.factorize_coarsest;
  if (has_smoother && m_levels[l].smoother.can_multiply()) m_levels[l].smoother.multiply(x, y);
  else matrix(l).multiply(x, y);
}

std::vector<double> LinearMultigrid::smoother_rhos() const {
  std::vector<double> out;
  for (const auto& level : m_levels) out.push_back(level.rho);
  return out;
}

void LinearMultigrid::set_smoother_rhos(const std::vector<double>& rhos) {
  if (rhos.size() != m_levels.size())
    throw_input_error("{} smoother spectral radii for a multigrid of {} levels", rhos.size(), m_levels.size());
  for (double rho : rhos)
    if (!(rho >= 0.0 && rho < 1.0)) throw_input_error("smoother spectral radius {} is not in [0, 1)", rho);
  for (size_t l = 0; l < rhos.size(); ++l) m_levels[l].rho = rhos[l];
}

void LinearMultigrid::cycle(Index l, const VecX& b, VecX& x) const {
  if (l == num_levels() - 1) {
    coarse_solve(b, x);
    return;
  }
  const auto& A = matrix(l);
  const bool adaptive = m_params.adaptive_threshold > 0.0;
  std::vector<char> mask;
  // Adaptive smoothing (Wang 2018 §4.3): vertices whose residual is below the threshold times the level's RMS
  // residual are skipped by the sweeps. The pre-smoothing residual is b itself for a correction started from 0.
  const auto masked = [&](const VecX& res, int sweeps) {
    const Index n = A.rows();
    const double rms = res.norm() / std::sqrt(static_cast<double>(std::max<Index>(1, n)));
    const Index active = linalg::adaptive_mask(res, m_params.adaptive_threshold * rms, mask);
    m_rows_active += 2.0 * sweeps * static_cast<double>(active);
    m_rows_total += 2.0 * sweeps * static_cast<double>(n);
    return &mask;
  };
  VecX r;
  if (adaptive && !x.isZero(0.0)) {
    multiply(l, x, r);
    r = b - r;
  }
  smooth(l, b, x, m_params.pre_smooth, adaptive ? masked(x.isZero(0.0) ? b : r, m_params.pre_smooth) : nullptr);
  multiply(l, x, r);
  r = b - r;
  VecX rc, ec = VecX::Zero(3 * matrix(l + 1).rows()), correction;
  m_p[l]->apply_transpose(r, rc);
  cycle(l + 1, rc, ec);
  m_p[l]->apply(ec, correction);
  x += correction;
  if (adaptive) {
    multiply(l, x, r);
    r = b - r;
  }
  smooth(l, b, x, m_params.post_smooth, adaptive ? masked(r, m_params.post_smooth) : nullptr);
}

void LinearMultigrid::smooth(Index l, const VecX& b, VecX& x, int sweeps, const std::vector<char>* mask) const {
  const Level& level = m_levels[l];
  if (m_params.chebyshev && level.rho > 0.0) linalg::chebyshev_gauss_seidel(level.smoother, b, x, sweeps, level.rho, mask);
  else level.smoother.symmetric_sweeps(b, x, sweeps, mask);
}

void LinearMultigrid::vcycle(Index l, const VecX& b, VecX& x) const {
  if (!m_fine) throw Error("multigrid used before set_matrix()");
  cycle(l, b, x);
}

void LinearMultigrid::coarse_solve(const VecX& b, VecX& x) const {
  if (!m_fine) throw Error("multigrid used before set_matrix()");
  if (!m_params.factorize_coarsest) throw Error("multigrid: coarse solve without a coarse factorization");
  m_coarse_solver.solve(b, x);
}

double LinearMultigrid::contraction(const VecX& b) const {
  VecX x = VecX::Zero(b.size());
  double r3 = 0.0, r10 = 0.0;
  for (int k = 1; k <= 10; ++k) {
    vcycle(b, x);
    const double r = (b - matrix(0) * x).norm();
    if (k == 3) r3 = r;
    if (k == 10) r10 = r;
  }
  return std::pow(r10 / r3, 1.0 / 7.0);
}

void LinearMultigrid::fmg(const VecX& b, VecX& x) const {
  if (!m_fine) throw Error("multigrid used before set_matrix()");
  const Index L = num_levels();
  std::vector<VecX> rhs(L);
  rhs[0] = b;
  for (Index l = 0; l + 1 < L; ++l) m_p[l]->apply_transpose(rhs[l], rhs[l + 1]);
  VecX xc;
  m_coarse_solver.solve(rhs[L - 1], xc);
  for (Index l = L - 2; l >= 0; --l) {
    VecX xf;
    m_p[l]->apply(xc, xf);
    cycle(l, rhs[l], xf);
    xc.swap(xf);
  }
  x.swap(xc);
}

void LinearMultigrid::vcycle(const VecX& b, VecX& x) const {
  if (!m_fine) throw Error("multigrid used before set_matrix()");
  cycle(0, b, x);
}

void LinearMultigrid::precondition(const VecX& r, VecX& z) const {
  z = VecX::Zero(r.size());
  vcycle(r, z);
}

}  // namespace mgcloth::solvers
