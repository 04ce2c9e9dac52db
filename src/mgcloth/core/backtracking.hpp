#pragma once
#include <algorithm>
#include <cmath>

namespace mgcloth {

/// The next trial of a backtracking line search after α failed the Armijo test with energy `trial_energy` (start
/// energy `energy`, directional derivative `slope` < 0): the minimizer of the quadratic through E(0), E'(0) and
/// E(α), safeguarded to [0.1α, 0.5α]; shrink·α where the trial energy is not finite or that quadratic is not convex.
inline double backtracking_step(double alpha, double trial_energy, double energy, double slope, double shrink) {
  if (!std::isfinite(trial_energy)) return shrink * alpha;
  const double curvature = trial_energy - energy - slope * alpha;
  if (!(curvature > 0.0)) return shrink * alpha;
  return std::clamp(-slope * alpha * alpha / (2.0 * curvature), 0.1 * alpha, 0.5 * alpha);
}

}  // namespace mgcloth
