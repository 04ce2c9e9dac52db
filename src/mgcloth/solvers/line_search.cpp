#include <mgcloth/solvers/line_search.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth::solvers {

namespace {
double next_trial(double alpha, double trial_energy, double energy, double slope, const LineSearchParams& p) {
  if (!p.interpolate || !std::isfinite(trial_energy)) return p.shrink * alpha;
  const double curvature = trial_energy - energy - slope * alpha;
  if (!(curvature > 0.0)) return p.shrink * alpha;
  return std::clamp(-slope * alpha * alpha / (2.0 * curvature), 0.1 * alpha, 0.5 * alpha);
}
}  // namespace

LineSearchResult backtrack(const std::function<double(double)>& energy_at, double e0, double slope, double alpha0,
                           const LineSearchParams& p, const std::function<void(double)>& place) {
  LineSearchResult r;
  double alpha = alpha0, rejected = 0.0;
  for (int k = 0; k < p.max_steps; ++k) {
    const double e = energy_at(alpha);
    r.trials = k + 1;
    if (std::isfinite(e) && e <= e0 + p.armijo * alpha * slope) {
      r.alpha = alpha;
      r.energy = e;
      r.success = true;
      break;
    }
    rejected = alpha;
    alpha = next_trial(alpha, e, e0, slope, p);
  }
  if (!r.success || r.trials == 1 || p.refine <= 0) return r;
  // Every midpoint lies between two trials, so within whatever limit alpha0 respected (contact's max_step).
  double lo = r.alpha, hi = rejected;
  bool last_kept = true;
  for (int k = 0; k < p.refine; ++k) {
    const double mid = 0.5 * (lo + hi);
    const double e = energy_at(mid);
    ++r.refined;
    last_kept = std::isfinite(e) && e < r.energy && e <= e0 + p.armijo * mid * slope;
    if (last_kept) {
      r.alpha = lo = mid;
      r.energy = e;
    } else {
      hi = mid;
    }
  }
  if (!last_kept) {
    if (place) {
      place(r.alpha);
    } else {
      energy_at(r.alpha);
      ++r.refined;
    }
  }
  return r;
}

LineSearchResult backtracking(const std::function<double(const VecX&)>& energy, const VecX& x, double e0,
                              const VecX& d, double slope, double alpha0, const LineSearchParams& p, VecX& trial,
                              double model_decrease, double alpha_limit) {
  alpha0 = std::min(alpha0, alpha_limit);
  if (!(alpha0 > 0.0)) return {};
  LineSearchResult r = backtrack(
      [&](double alpha) {
        trial = x + alpha * d;
        return energy(trial);
      },
      e0, slope, alpha0, p, [&](double alpha) { trial = x + alpha * d; });
  if (r.success && r.trials == 1 && model_decrease > 0.0 && p.expand_ratio > 0.0 &&
      e0 - r.energy > p.expand_ratio * model_decrease * r.alpha) {
    VecX longer;
    for (double a = 2.0 * r.alpha; a <= std::min(p.max_alpha, alpha_limit); a *= 2.0) {
      longer = x + a * d;
      const double el = energy(longer);
      if (!(std::isfinite(el) && el < r.energy && el <= e0 + p.armijo * a * slope)) break;
      r.alpha = a;
      r.energy = el;
      trial.swap(longer);
    }
  }
  return r;
}

}  // namespace mgcloth::solvers
