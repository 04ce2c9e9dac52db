#pragma once
#include <mgcloth/core/types.hpp>

#include <array>
#include <string>
#include <vector>

namespace mgcloth::physics {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

/// The nonlinear response functions of the woven-cloth model (Kopaničáková 2019, eq. 3.4; Clyde et al. 2017):
/// φ_j(u) = Σ_i μ_ji / α_ji ((u + 1)^α_ji − 1), j = 1..4. With Σ_i μ_ji = 1, φ_j'(0) = 1 and the model is linear
/// orthotropic at small strain.
struct WovenResponse {
  std::vector<double> mu, alpha;
  /// φ(u), φ'(u), φ''(u); +inf value when u <= -1 with a non-integer exponent (outside the model's domain).
  void evaluate(double u, double& f, double& df, double& ddf) const;
};

/// A Kirchhoff-Love shell material. Strains are the reduced Green-Lagrange strain Ẽ = Oᵀ E O in the orthonormal
/// material frame (o1 warp, o2 weft) of the reference surface, as (Ẽ11, Ẽ22, Ẽ12) with Ẽ12 the tensor component.
struct ShellMaterial {
  enum class Model { stvk, woven };
  Model model = Model::stvk;
  /// Isotropic St. Venant-Kirchhoff in plane stress: ψ = Y / (2 (1 − ν²)) [(1 − ν) tr Ẽ² + ν (tr Ẽ)²].
  double young = 1.0e7;   ///< Pa
  double poisson = 0.3;
  /// Woven (eq. 3.3): ψ = k1/2 φ1(Ẽ11²) + k2 φ2(Ẽ11 Ẽ22) + k3/2 φ3(Ẽ22²) + k4 φ4(Ẽ12²).
  std::array<double, 4> k{1.0e7, 3.0e6, 1.0e7, 7.0e6};  ///< Pa
  std::array<WovenResponse, 4> phi;  ///< empty response: φ(u) = u
  /// Woven only, beyond the paper: ψ is kept at or above this fraction of the small-strain energy ½ Ẽᵀ C₀ Ẽ
  /// (C₀ = ∂²ψ/∂Ẽ²(0)), since fitted responses can make ψ negative or unbounded below at moderate strains (the
  /// denim fit does). 0 keeps the fit as published.
  double woven_energy_floor = 0.1;
  double thickness = 0.5e-3;        ///< τ, m
  double density = 0.2;             ///< kg/m² of reference area
  double warp_angle_deg = 0.0;      ///< warp direction o1 in material (u, v) space, from the u axis
  int thickness_points = 3;         ///< Gauss-Legendre points through the thickness, 2-5
  /// How the energy density is integrated through the thickness (eq. 3.2):
  /// gauss: ∫ ψ(ε + ξ³ κ) dξ³ by Gauss-Legendre, the nonlinear law at every fibre;
  /// split: τ ψ(ε) + τ³/12 · ½ κᵀ C₀ κ, the nonlinear law for the membrane and its small-strain tangent
  /// C₀ = ∂²ψ/∂Ẽ²(0) for bending, the usual split for cloth (bending strains ξ³κ of tight folds would otherwise
  /// leave the woven fit's stable range, a few percent of strain, although the midsurface barely stretches).
  /// The two agree exactly for St. Venant-Kirchhoff.
  enum class Integration { gauss, split };
  Integration integration = Integration::gauss;

  std::string model_name() const { return model == Model::stvk ? "stvk" : "woven"; }
  /// Throws InputError naming the field for non-finite or out-of-range values.
  void validate() const;
};

/// Denim of Kopaničáková 2019, Table 1 (k in MPa, τ = 0.66 mm, ρ = 0.4 kg/m²). The table omits μ_j1; they follow
/// from φ_j'(0) = 1 (Clyde et al. 2017), i.e. μ_j1 = 1 − Σ_{i≥2} μ_ji. Integrated by the split rule.
ShellMaterial denim_material();

/// ψ(Ẽ) per unit volume, with gradient and Hessian in (Ẽ11, Ẽ22, Ẽ12) when g, H are non-null. The woven model
/// is +∞ outside its range of validity: where a response's slope φ_j' is not positive (the fit no longer
/// describes a material, and the denim fit's φ3 is unbounded below there).
double shell_energy_density(const ShellMaterial& m, const Vec3& e, Vec3* g, Mat3* H);

/// Energy per unit reference area of the membrane strain ε and the curvature change κ (frame components), the
/// density integrated through the thickness (eq. 3.2 with r = x + ξ³ a3: Ẽ(ξ³) = ε + ξ³ κ) by Gauss-Legendre in
/// ξ³ ∈ [−τ/2, τ/2]; gradient and Hessian in (ε, κ).
double shell_area_density(const ShellMaterial& m, const Vec3& eps, const Vec3& kappa, Vec6* g, Mat6* H);

}  // namespace mgcloth::physics
