#pragma once
#include <mgcloth/linalg/cholmod_solver.hpp>
#include <mgcloth/linalg/gauss_seidel.hpp>
#include <mgcloth/solvers/line_search.hpp>
#include <mgcloth/solvers/nonlinear_solver.hpp>

namespace mgcloth::solvers {

struct FasParams {
  int pre_smooth = 1;    ///< nonlinear smoothing steps before the coarse correction
  int post_smooth = 1;   ///< and after
  int sweeps = 3;        ///< symmetric Gauss-Seidel sweeps on the Newton system per smoothing step
  int coarse_iters = 3;  ///< Newton iterations (CHOLMOD) on the coarsest level
  bool project_psd = true;
  LineSearchParams line_search;
};

/// The full approximation scheme (Brandt 1977; in the optimization form of Nash 2000, "MG/OPT"), the FAS baseline
/// of Wang 2018 Fig. 4: positions, not corrections, move between levels, and each coarse level minimizes the
/// objective rediscretized on its own mesh, E_c(y) − τᵀy, with τ = ∇E_c(x̂) − Pᵀ∇E_f(x) for x̂ the projected fine
/// iterate, so that the coarse problem is first-order consistent with the fine one. The coarse correction
/// P(y − x̂) is line-searched on the fine objective (which makes the cycle a descent method); smoothing is one
/// Newton step per smoothing iteration with the system relaxed by symmetric Gauss-Seidel and a line search; the
/// coarsest level takes a few Newton steps with CHOLMOD. One iteration = one V-cycle.
class Fas final : public NonlinearSolver {
 public:
  explicit Fas(FasParams params = {}) : m_params(params) {}
  std::string name() const override { return "fas"; }
  bool needs_hierarchy() const override { return true; }
  bool needs_level_objectives() const override { return true; }
  SolveReport minimize(Problem& problem, VecX& x, const Stop& stop, Trace* trace) override;

 private:
  struct Level {
    const physics::Objective* objective = nullptr;
    linalg::BlockMatrix3 H;
    linalg::MultiColorGaussSeidel gs;
  };
  void cycle(Index l, VecX& x, const VecX& tau);
  bool smooth(Index l, VecX& x, const VecX& tau, bool direct);
  double shifted_value(Index l, const VecX& x, const VecX& tau) const;
  void shifted_gradient(Index l, const VecX& x, const VecX& tau, VecX& g) const;

  FasParams m_params;
  std::vector<Level> m_levels;
  std::vector<const linalg::StencilTable*> m_p;
  linalg::CholmodSolver m_coarse;
  const Problem* m_problem = nullptr;
};

}  // namespace mgcloth::solvers
