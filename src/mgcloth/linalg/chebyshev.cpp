#include <mgcloth/core/error.hpp>
#include <mgcloth/linalg/chebyshev.hpp>

#include <cmath>
#include <random>

namespace mgcloth::linalg {

void chebyshev_gauss_seidel(const MultiColorGaussSeidel& gs, const VecX& b, VecX& x, int iterations, double rho,
                            const std::vector<char>* mask) {
  if (!(rho >= 0.0 && rho < 1.0)) throw Error(fmt::format("Chebyshev: spectral radius {} outside [0, 1)", rho));
  VecX previous = x;
  double omega = 1.0;
  for (int k = 1; k <= iterations; ++k) {
    const VecX current = x;
    gs.symmetric_sweeps(b, x, 1, mask);
    omega = k == 1 ? 1.0 : k == 2 ? 2.0 / (2.0 - rho * rho) : 4.0 / (4.0 - rho * rho * omega);
    if (k > 1) x = omega * (x - previous) + previous;
    previous = current;
  }
}

double estimate_gauss_seidel_rho(const BlockMatrix3& A, const MultiColorGaussSeidel& gs, int sweeps) {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  VecX e(3 * A.rows());
  for (Index i = 0; i < e.size(); ++i) e[i] = u(rng);
  const VecX zero = VecX::Zero(e.size());
  double start = 0.0;
  for (int s = 0; s < sweeps; ++s) {
    if (s == sweeps / 2) start = e.norm();
    gs.symmetric_sweeps(zero, e, 1);
  }
  if (start == 0.0) return 0.0;
  return std::min(0.9999, std::pow(e.norm() / start, 1.0 / (sweeps - sweeps / 2)));
}

}  // namespace mgcloth::linalg
