#pragma once
#include <mgcloth/linalg/block_matrix.hpp>

#include <memory>

namespace mgcloth::linalg {

/// Sparse Cholesky (CHOLMOD, supernodal LLᵀ) of a symmetric BlockMatrix3. The symbolic analysis (fill-reducing
/// ordering, elimination tree) depends only on the pattern, so it runs once and is reused by every factorize()
/// with the same pattern: across Newton iterations and time steps.
class CholmodSolver {
 public:
  CholmodSolver();
  ~CholmodSolver();
  CholmodSolver(const CholmodSolver&) = delete;
  CholmodSolver& operator=(const CholmodSolver&) = delete;

  /// Numeric factorization of A + shift·I. Returns false when the matrix is not positive definite.
  bool factorize(const BlockMatrix3& A, double shift = 0.0);
  /// x = A⁻¹ b with the last successful factorization.
  void solve(const VecX& b, VecX& x) const;
  /// Number of symbolic analyses done so far (tests check it stays at one per pattern).
  int analyses() const { return m_analyses; }

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
  int m_analyses = 0;
};

}  // namespace mgcloth::linalg
