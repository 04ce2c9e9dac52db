#include <mgcloth/solvers/line_search.hpp>

#include <cmath>

namespace mgcloth::solvers {

LineSearchResult backtracking(const std::function<double(const VecX&)>& energy, const VecX& x, double e0,
                              const VecX& d, double slope, double alpha0, const LineSearchParams& p, VecX& trial) {
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
      return r;
    }
  }
  return r;
}

}  // namespace mgcloth::solvers
