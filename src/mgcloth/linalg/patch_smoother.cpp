#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/linalg/patch_smoother.hpp>

#include <Eigen/Dense>
#include <algorithm>

namespace mgcloth::linalg {

PatchSmoother::PatchSmoother(std::vector<std::vector<Index>> patches) : m_patches(std::move(patches)) {
  for (auto& p : m_patches) std::sort(p.begin(), p.end());
}

void PatchSmoother::set_matrix(const BlockMatrix3& A) {
  m_A = &A;
  m_inverse.resize(m_patches.size());
  parallel_for(static_cast<Index>(m_patches.size()), [&](Index pi) {
    const auto& p = m_patches[static_cast<size_t>(pi)];
    const Index n = static_cast<Index>(p.size());
    MatX local = MatX::Zero(3 * n, 3 * n);
    for (Index a = 0; a < n; ++a) {
      const Index r = p[static_cast<size_t>(a)];
      for (Index k = A.row_offsets()[r]; k < A.row_offsets()[r + 1]; ++k) {
        const auto it = std::lower_bound(p.begin(), p.end(), A.col_indices()[k]);
        if (it == p.end() || *it != A.col_indices()[k]) continue;
        local.block<3, 3>(3 * a, 3 * (it - p.begin())) = A.block(k);
      }
    }
    // Most patches are positive definite: a Cholesky factorization is ~10x cheaper than the eigen-decomposition
    // and gives the same inverse there.
    Eigen::LLT<MatX> llt(local);
    const auto pivots = [&] {
      const VecX d = llt.matrixLLT().diagonal().cwiseAbs2();
      return d.minCoeff() > 1e-10 * d.maxCoeff();
    };
    if (llt.info() == Eigen::Success && pivots()) {
      m_inverse[static_cast<size_t>(pi)] = llt.solve(MatX::Identity(3 * n, 3 * n));
      if (m_inverse[static_cast<size_t>(pi)].allFinite()) return;
    }
    Eigen::SelfAdjointEigenSolver<MatX> eig(local);
    if (eig.info() != Eigen::Success)
      throw SolveError(fmt::format("patch smoother: eigen-decomposition of patch {} failed", pi));
    const double top = std::max(eig.eigenvalues().cwiseAbs().maxCoeff(), 1e-300);
    const VecX inv = eig.eigenvalues().cwiseAbs().cwiseMax(1e-10 * top).cwiseInverse();
    m_inverse[static_cast<size_t>(pi)] = eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose();
  });
}

void PatchSmoother::relax(size_t pi, const VecX& b, VecX& x) const {
  const BlockMatrix3& A = *m_A;
  const auto& p = m_patches[pi];
  const Index n = static_cast<Index>(p.size());
  VecX r(3 * n);
  for (Index a = 0; a < n; ++a) {
    const Index row = p[static_cast<size_t>(a)];
    Vec3 s = b.segment<3>(3 * row);
    for (Index k = A.row_offsets()[row]; k < A.row_offsets()[row + 1]; ++k)
      s -= A.block(k) * x.segment<3>(3 * A.col_indices()[k]);
    r.segment<3>(3 * a) = s;
  }
  const VecX dx = m_inverse[pi] * r;
  for (Index a = 0; a < n; ++a) x.segment<3>(3 * p[static_cast<size_t>(a)]) += dx.segment<3>(3 * a);
}

void PatchSmoother::symmetric_sweeps(const VecX& b, VecX& x, int sweeps) const {
  if (!m_A) throw Error("patch smoother: set_matrix() was not called");
  for (int s = 0; s < sweeps; ++s) {
    for (size_t p = 0; p < m_patches.size(); ++p) relax(p, b, x);
    for (size_t p = m_patches.size(); p-- > 0;) relax(p, b, x);
  }
}

}  // namespace mgcloth::linalg
