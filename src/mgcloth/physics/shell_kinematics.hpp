#pragma once
#include <mgcloth/core/types.hpp>

namespace mgcloth::physics {

using Mat18 = Eigen::Matrix<double, 18, 18>;
using Vec18 = Eigen::Matrix<double, 18, 1>;
using ShellJacobian = Eigen::Matrix<double, 6, 18>;

/// Surface quantities at one point of a Kirchhoff-Love shell, from z = (x, a1, a2, x,11, x,12, x,22) (the limit
/// point and its first and second parameter derivatives, 18 numbers, the order of mesh::LimitStencil columns):
/// s = (a11, a22, a12, b11, b22, b12), the first fundamental form a_αβ = a_α · a_β and the second fundamental form
/// b_αβ = x,αβ · a3 with the unit normal a3 = a1 × a2 / |a1 × a2| (Kopaničáková 2019, §3; Kiendl et al. 2009).
/// J = ∂s/∂z when non-null. Returns false when a1 × a2 vanishes (a degenerate surface point).
bool shell_fundamental_forms(const Vec18& z, Eigen::Matrix<double, 6, 1>& s, ShellJacobian* J);

/// Adds Σ_i λ_i ∂²s_i/∂z² to Hz (the second-derivative part of the chain rule for W(s(z))).
void add_fundamental_form_curvature(const Vec18& z, const Eigen::Matrix<double, 6, 1>& lambda, Mat18& Hz);

}  // namespace mgcloth::physics
