#pragma once
#include <mgcloth/core/types.hpp>

#include <functional>

namespace mgcloth::solvers {

struct LineSearchParams {
  double armijo = 1e-4;     ///< sufficient-decrease constant c1
  double shrink = 0.5;      ///< backtracking factor
  int max_steps = 40;
  /// After a failed trial: the minimizer of the quadratic through E(0), E'(0) and E(α), safeguarded to
  /// [0.1α, 0.5α] (Nocedal & Wright §3.5), instead of shrink·α. shrink·α is still taken where that quadratic is not
  /// convex or the trial energy is not finite.
  bool interpolate = false;
  /// When the full step decreases the energy by more than `expand_ratio` times what the quadratic model
  /// predicted (the model was too stiff, e.g. after clamping negative curvature), longer steps α = 2, 4, … up to
  /// max_alpha are tried while the energy keeps dropping. 0 disables.
  double expand_ratio = 1.5;
  double max_alpha = 16.0;
  /// After an acceptance that followed a rejected trial: up to `refine` bisections of [accepted, rejected], each
  /// midpoint kept when it lowers the energy (and meets the Armijo condition). Where a stiff wall lies along the line
  /// (cloth pairs entering their contact layer), the first trial lands past it and the safeguarded interpolation
  /// falls to a tenth of it, far short of the minimizer along the line. FMG sets 3 and refines only the searches
  /// that contact cut short (bench/RESULTS.md, "Refining line searches that contact cut short"). 0 disables.
  int refine = 0;
};

struct LineSearchResult {
  double alpha = 0.0;
  double energy = 0.0;
  bool success = false;
  int trials = 0;  ///< energy evaluations of the backtracking (the accepted one included)
  int refined = 0;  ///< energy evaluations of the refinement (params.refine)
};

/// The backtracking (Armijo) line search of the whole library: E(α) <= E(0) + c1 α slope, from alpha0 down.
/// `energy_at(α)` evaluates the objective at the trial point x + α d, which the caller forms (and may make
/// feasible) wherever its vectors live, and keeps: after a success it holds the accepted point. A non-finite trial
/// energy (an inverted or exploded state) counts as "too far". Expansion is not done here (see backtracking()).
/// With params.refine, `place(α)` (when given) forms the accepted trial point again without evaluating it, where the
/// refinement's last trial was not kept; without it, energy_at(α) is called once more.
LineSearchResult backtrack(const std::function<double(double alpha)>& energy_at, double e0, double slope, double alpha0,
                           const LineSearchParams& params, const std::function<void(double alpha)>& place = {});

/// backtrack() along d from x for vectors in memory, the accepted point in `trial`. `model_decrease` (> 0,
/// optional) is the decrease the quadratic model predicts for α = 1: a first trial that beats it by expand_ratio
/// tries longer steps. No trial goes beyond `alpha_limit` (the objective's max_step along d, where it limits steps).
LineSearchResult backtracking(const std::function<double(const VecX&)>& energy, const VecX& x, double e0,
                              const VecX& d, double slope, double alpha0, const LineSearchParams& params,
                              VecX& trial, double model_decrease = 0.0, double alpha_limit = kInf);

}  // namespace mgcloth::solvers
