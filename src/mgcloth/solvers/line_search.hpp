#pragma once
#include <mgcloth/core/types.hpp>

#include <functional>

namespace mgcloth::solvers {

struct LineSearchParams {
  double armijo = 1e-4;     ///< sufficient-decrease constant c1
  double shrink = 0.5;      ///< backtracking factor
  int max_steps = 40;
};

struct LineSearchResult {
  double alpha = 0.0;
  double energy = 0.0;
  bool success = false;
};

/// Backtracking (Armijo) line search along d from x, E(x + αd) <= E(x) + c1 α ∇E·d, starting at alpha0.
/// `energy` evaluates the objective at a trial point; `trial` receives the accepted point.
LineSearchResult backtracking(const std::function<double(const VecX&)>& energy, const VecX& x, double e0,
                              const VecX& d, double slope, double alpha0, const LineSearchParams& params,
                              VecX& trial);

}  // namespace mgcloth::solvers
