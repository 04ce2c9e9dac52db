#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/linalg/block_jacobi.hpp>

#include <Eigen/Cholesky>

namespace mgcloth::linalg {

void BlockJacobi::set_matrix(const BlockMatrix3& A) {
  const Index n = A.rows();
  m_inv.resize(n);
  std::vector<char> failed(n, 0);  // exceptions cannot leave an OpenMP region: flag here, throw after
  parallel_for(n, [&](Index i) {
    const Mat3& D = A.block(A.diagonal(i));
    const Eigen::LLT<Mat3> llt(D);
    if (llt.info() != Eigen::Success || !D.allFinite()) {
      failed[i] = 1;
      return;
    }
    const Mat3 inv = llt.solve(Mat3::Identity());
    m_inv[i] = 0.5 * (inv + inv.transpose());  // exactly symmetric, so M⁻¹ is too
  });
  for (Index i = 0; i < n; ++i)
    if (failed[i])
      throw_error<SolveError>("block-Jacobi: diagonal block of row {} is not positive definite (singular or indefinite)",
                              i);
}

void BlockJacobi::apply(const VecX& r, VecX& z) const {
  const Index n = rows();
  if (r.size() != 3 * n) throw_error("block-Jacobi: vector of size {} for a matrix with {} block rows", r.size(), n);
  z.resize(r.size());
  parallel_for(n, [&](Index i) { z.segment<3>(3 * i).noalias() = m_inv[i] * r.segment<3>(3 * i); }, 4096);
}

}  // namespace mgcloth::linalg
