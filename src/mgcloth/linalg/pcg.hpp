#pragma once
#include <mgcloth/linalg/block_matrix.hpp>

#include <functional>

namespace mgcloth::linalg {

/// z = M⁻¹ r for a symmetric positive definite M (z is resized by the callee).
using Preconditioner = std::function<void(const VecX& r, VecX& z)>;

/// Preconditioned conjugate gradients for SPD A from the given x; returns the iterations used (max_iters when it
/// did not converge). Stops when the recursively updated residual satisfies |r| <= rel_tol |b|. Throws SolveError
/// when pᵀAp <= 0, i.e. when A (or M) is not positive definite. Vector operations run in parallel over fixed
/// chunks whose partial dot products are added in order, so results do not depend on the thread count.
int pcg(const BlockMatrix3& A, const VecX& b, VecX& x, const Preconditioner& precondition, double rel_tol,
        int max_iters);

}  // namespace mgcloth::linalg
