#pragma once
// Finite-difference checks shared by the tests of every term.
#include <mgcloth/physics/term.hpp>

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <random>

namespace mgcloth::physics {

/// Checks a term at x: central differences of value vs gradient and of gradient vs Hessian, symmetry of the
/// Hessian, and positive semi-definiteness of the projected Hessian.
inline void check_term(const Term& term, const VecX& x, double rel_tol = 1e-6) {
  const Index n = static_cast<Index>(x.size() / 3);
  std::vector<std::pair<Index, Index>> pairs;
  term.collect_pattern(pairs);
  linalg::BlockMatrix3 H(n, pairs);
  const_cast<Term&>(term).bind(H);
  VecX g = VecX::Zero(x.size());
  term.add_gradient(x, g);
  H.set_zero();
  term.add_hessian(x, H, false);
  const auto Hs = H.to_sparse();
  const Eigen::MatrixXd Hd(Hs);
  const double h = 1e-6;
  // Gradient: directional derivatives along random directions and along every coordinate.
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (int trial = 0; trial < 5; ++trial) {
    VecX d(x.size());
    for (Index i = 0; i < d.size(); ++i) d[i] = n01(rng);
    d *= 1e-3 / d.norm() * std::sqrt(static_cast<double>(x.size()));
    const double fd = (term.value(x + h * d) - term.value(x - h * d)) / (2 * h);
    const double an = g.dot(d);
    EXPECT_NEAR(fd, an, rel_tol * (std::abs(an) + g.norm() * d.norm()) + 1e-12) << term.name() << " gradient";
    VecX gp = VecX::Zero(x.size()), gm = VecX::Zero(x.size());
    term.add_gradient(x + h * d, gp);
    term.add_gradient(x - h * d, gm);
    const VecX hd_fd = (gp - gm) / (2 * h);
    const VecX hd = Hd * d;
    EXPECT_LE((hd_fd - hd).norm(), rel_tol * 10 * (hd.norm() + Hd.norm() * d.norm()) + 1e-12) << term.name() << " Hessian";
  }
  EXPECT_LE((Hd - Hd.transpose()).norm(), 1e-12 * (1.0 + Hd.norm())) << term.name() << " symmetry";
  H.set_zero();
  term.add_hessian(x, H, true);
  const Eigen::MatrixXd Hp(H.to_sparse());
  EXPECT_LE((Hp - Hp.transpose()).norm(), 1e-12 * (1.0 + Hp.norm()));
  const double min_eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Hp).eigenvalues().minCoeff();
  EXPECT_GE(min_eig, -1e-10 * (1.0 + Hp.norm())) << term.name() << " projected Hessian not PSD";
}


}  // namespace mgcloth::physics
