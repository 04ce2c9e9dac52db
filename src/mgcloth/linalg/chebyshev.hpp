#pragma once
#include <mgcloth/linalg/gauss_seidel.hpp>

namespace mgcloth::linalg {

/// Chebyshev semi-iterative acceleration of symmetric Gauss-Seidel (Wang 2015, "A Chebyshev semi-iterative
/// approach for accelerating projective and position-based dynamics"): with ρ the spectral radius of one
/// symmetric sweep's iteration matrix, ω_1 = 1, ω_2 = 2/(2 − ρ²), ω_{k+1} = 4/(4 − ρ² ω_k), and
/// x_{k+1} = ω_{k+1} (x̂_{k+1} − x_{k−1}) + x_{k−1}, where x̂_{k+1} is one symmetric sweep from x_k.
/// From x = 0 the result is still an SPD operator applied to b (Wang 2018, Theorem 4.1).
void chebyshev_gauss_seidel(const MultiColorGaussSeidel& gs, const VecX& b, VecX& x, int iterations, double rho,
                            const std::vector<char>* mask = nullptr);

/// Estimates ρ of one symmetric sweep by running `sweeps` of them on A e = 0 from a random start and taking the
/// geometric mean of the error reduction of the last half.
double estimate_gauss_seidel_rho(const BlockMatrix3& A, const MultiColorGaussSeidel& gs, int sweeps = 30);

}  // namespace mgcloth::linalg
