#pragma once
#include <mgcloth/linalg/block_matrix.hpp>

#include <memory>
#include <string>

namespace mgcloth::linalg {

/// A solver for the symmetric positive definite systems of Newton's method.
class LinearSolver {
 public:
  virtual ~LinearSolver() = default;
  virtual std::string name() const = 0;
  /// Prepares for solves with A + shift·I; false when that matrix turned out not positive definite.
  virtual bool compute(const BlockMatrix3& A, double shift) = 0;
  virtual void solve(const VecX& b, VecX& x) = 0;
};

/// Builds a linear solver by name: "cholmod".
std::unique_ptr<LinearSolver> make_linear_solver(const std::string& name);

}  // namespace mgcloth::linalg
