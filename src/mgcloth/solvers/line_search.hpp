#pragma once
#include <mgcloth/core/types.hpp>

#include <functional>

namespace mgcloth::solvers {

struct LineSearchParams {
  double armijo = 1e-4;     ///< sufficient-decrease constant c1
  double shrink = 0.5;      ///< backtracking factor
  int max_steps = 40;
  /// When the full step decreases the energy by more than `expand_ratio` times what the quadratic model
  /// predicted (the model was too stiff, e.g. after clamping negative curvature), longer steps α = 2, 4, … up to
  /// max_alpha are tried while the energy keeps dropping. 0 disables.
  double expand_ratio = 1.5;
  double max_alpha = 16.0;
};

struct LineSearchResult {
  double alpha = 0.0;
  double energy = 0.0;
  bool success = false;
};

/// Backtracking (Armijo) line search along d from x, E(x + αd) <= E(x) + c1 α ∇E·d, starting at alpha0.
/// `model_decrease` (> 0, optional) is the decrease the quadratic model predicts for α = 1, used to decide on
/// expansion.
/// `energy` evaluates the objective at a trial point; `trial` receives the accepted point.
LineSearchResult backtracking(const std::function<double(const VecX&)>& energy, const VecX& x, double e0,
                              const VecX& d, double slope, double alpha0, const LineSearchParams& params,
                              VecX& trial, double model_decrease = 0.0);

}  // namespace mgcloth::solvers
