#pragma once
#include <Eigen/Eigenvalues>

namespace mgcloth::physics {

/// Projects a symmetric element Hessian onto the positive semi-definite cone by clamping negative eigenvalues to
/// zero (Teran et al. 2005-style per-element projection): the nearest PSD matrix in the Frobenius norm.
template <class Matrix>
void project_psd(Matrix& H) {
  Eigen::SelfAdjointEigenSolver<Matrix> eig(H);
  auto lambda = eig.eigenvalues();
  if (lambda.minCoeff() >= 0.0) return;
  H = eig.eigenvectors() * lambda.cwiseMax(0.0).asDiagonal() * eig.eigenvectors().transpose();
}

}  // namespace mgcloth::physics
