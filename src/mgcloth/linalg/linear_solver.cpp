#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/linalg/linear_solver.hpp>

namespace mgcloth::linalg {
namespace {
class DirectSolver final : public LinearSolver {
 public:
  std::string name() const override { return "cholmod"; }
  bool compute(const BlockMatrix3& A, double shift) override { return m_chol.factorize(A, shift); }
  void solve(const VecX& b, VecX& x) override { m_chol.solve(b, x); }

 private:
  CholmodSolver m_chol;
};
}  // namespace

std::unique_ptr<LinearSolver> make_linear_solver(const std::string& name) {
  if (name == "cholmod") return std::make_unique<DirectSolver>();
  throw_input_error("unknown linear solver \"{}\" (available: cholmod)", name);
}

}  // namespace mgcloth::linalg
