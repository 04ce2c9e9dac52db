#include <mgcloth/solvers/line_search.hpp>

#include <cmath>

namespace mgcloth::solvers {

LineSearchResult backtracking(const std::function<double(const VecX&)>& energy, const VecX& x, double e0,
                              const VecX& d, double slope, double alpha0, const LineSearchParams& p, VecX& trial,
                              double model_decrease) {
  LineSearchResult r;
  double alpha = alpha0;
  for (int k = 0; k < p.max_steps; ++k, alpha *= p.shrink) {
    trial = x + alpha * d;
    const double e = energy(trial);
    // A non-finite trial energy (an inverted or exploded state) is treated as "too far", never accepted.
    if (std::isfinite(e) && e <= e0 + p.armijo * alpha * slope) {
      r.alpha = alpha;
      r.energy = e;
      r.success = true;
      if (k == 0 && model_decrease > 0.0 && p.expand_ratio > 0.0 && e0 - e > p.expand_ratio * model_decrease * alpha) {
        VecX longer;
        for (double a = 2.0 * alpha; a <= p.max_alpha; a *= 2.0) {
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
  }
  return r;
}

}  // namespace mgcloth::solvers
