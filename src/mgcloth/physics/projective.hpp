#pragma once
#include <mgcloth/physics/contact.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/objective.hpp>

#include <cstdint>

namespace mgcloth::physics {

// The Projective Dynamics (PD) form of the cloth energy (Liu et al. 2013, Bouaziz et al. 2014): every elastic and
// contact term is a constraint energy E_i = w_i/2 |A_i S_i x − p_i|², p_i = the projection of A_i S_i x onto the
// constraint set C_i. Each term here returns the exact E and its exact gradient Σ w SᵀAᵀ(A S x − p(x)) (the
// envelope theorem: p minimizes the distance, so its dependence on x drops out), but its add_hessian() adds the
// CONSTANT PD global matrix Σ w SᵀAᵀA S, not the exact Hessian. Together with the inertia M/h² and the quadratic
// terms (pins, seams, QuadraticBending), a Newton step x ← x − L⁻¹∇E with this matrix L is exactly the
// local/global iteration of PD. The project_psd flag is ignored: the matrix is positive semi-definite already.

using Mat32 = Eigen::Matrix<double, 3, 2>;

/// The strain constraint set of Bouaziz et al. 2014 §5: {U diag(σ̂) Vᵀ : σ̂ ∈ [sigma_min, sigma_max]²}, and the
/// projection P(F) = U diag(clamp(σ, sigma_min, sigma_max)) Vᵀ of F = U Σ Vᵀ onto it (the closest point in the
/// Frobenius norm). sigma_min = sigma_max = 1: P(F) is the rotation of F's polar decomposition (as-rigid-as-
/// possible). A collapsed F (σ = 0) gets some valid U, V: finite, though not unique.
Mat32 project_strain(const Mat32& F, double sigma_min, double sigma_max);

/// One triangle's PD strain energy E = wA/2 |F − P(F)|²_F = wA/2 Σ_k (σ_k − clamp(σ_k))², F = [x1−x0, x2−x0] Dm⁻¹;
/// `weight_area` = wA. Exact gradient ∂E/∂x_a = wA (F − P(F)) b_a (b_1, b_2 the rows of Dm⁻¹, b_0 = −b_1 − b_2);
/// H (when non-null) receives the constant PD matrix wA (b_a·b_b) I₃, i.e. wA GᵀG ⊗ I₃ with G = ∂F/∂x per axis.
double pd_strain_triangle(const Vec9& xe, const Mat2& dm_inv, double weight_area, double sigma_min, double sigma_max,
                          Vec9* g, Mat9* H);

/// The PD strain membrane: E = Σ_t w A_t/2 |F_t − P(F_t)|²_F over all triangles, rest shape from the material
/// coordinates, strain limits [Material::pd_strain_min, Material::pd_strain_max]. w = 2μ·t (shear modulus times
/// thickness): for a small strain F = R(I + ε), |F − R|² = tr(ε²), so wA/2 |F − P(F)|² = A t μ tr(ε²), the StVK
/// membrane's shear part. The constraint has no area (λ) part, so its Poisson ratio is 0 and its uniaxial stretch
/// stiffness is 2μt = E t/(1 + ν), not the StVK plane-stress E t/(1 − ν²). add_hessian() adds the constant PD
/// matrix (see the note above), not the exact Hessian.
class PDStrainMembrane final : public ElementTerm<3> {
 public:
  /// Throws InputError for a triangle of non-positive material area or limits outside 0 <= min <= 1 <= max.
  PDStrainMembrane(const mesh::TriMesh& mesh, const Material& material);
  std::string name() const override { return "membrane_pd_strain"; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;
  /// The PD matrix, the same for every x; project_psd is ignored (it is PSD already, and so stays bitwise constant).
  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool /*project_psd*/) const override {
    ElementTerm::add_hessian(x, H, false);
  }
  /// w = 2μt (N/m).
  double weight() const { return m_weight; }

 private:
  std::vector<TriangleRest> m_rest;
  double m_weight, m_sigma_min, m_sigma_max;
};

/// PD obstacle contact: E = Σ_i Σ_o w_i/2 max(0, d − φ_o(x_i))², w_i = stiffness · A_i (ContactParams; A_i the
/// lumped vertex area), i.e. the constraint "x_i outside the layer φ_o ≥ d" with A = I, whose projection moves x_i by
/// d − φ_o along ∇φ_o. With the same `stiffness` as ObstacleContact its force w_i (d − φ) equals the cubic penalty's
/// at the obstacle surface and is larger everywhere inside the layer, so the PD form is never softer.
/// The PD matrix must stay constant during a step, so it uses an active set fixed per step by set_active(): pair
/// (i, o) is active when φ_o(y_i) < d + margin at the step's predicted positions y. Active pairs add w_i I₃ whether or
/// not x_i is in the layer at the current iterate; inactive pairs add nothing to the matrix but still contribute
/// their exact energy and gradient if x_i enters the layer.
class PDObstacleContact final : public ObstaclePenalty {
 public:
  /// `active_margin` (m, >= 0): how far outside the layer a predicted position still activates a pair.
  PDObstacleContact(VecX vertex_area, std::vector<geometry::Obstacle> obstacles, const ContactParams& params,
                    double active_margin);
  std::string name() const override { return "contact_pd"; }
  /// Fixes the active set for the following evaluations from positions y (the step's prediction), with the
  /// obstacles at the time of the last set_time(). Bumps active_set_version() when the set changed.
  void set_active(const VecX& y);
  bool active(Index i, size_t obstacle) const { return m_active[static_cast<size_t>(i) * obstacles().size() + obstacle]; }
  Index num_active() const;
  /// Incremented by every set_active() that changed the active set: the PD matrix (for fixed h) changes only then,
  /// so a solver may keep its factorization while this is unchanged.
  std::uint64_t active_set_version() const { return m_version; }
  double active_margin() const { return m_margin; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;
  /// The PD matrix of the active set; project_psd is ignored (the matrix is PSD already).
  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool /*project_psd*/) const override {
    ElementTerm::add_hessian(x, H, false);
  }
  double normal_force(Index i, double gap) const override { return vertex_stiffness(i) * gap; }

 private:
  std::vector<char> m_active;  ///< per (vertex, obstacle), vertex-major
  std::uint64_t m_version = 0;
  double m_margin;
};

/// Sum of the active-set versions of an objective's PD contact terms: for a fixed step size the PD matrix of the
/// objective changes only when this number does (0 for an objective without PD contact).
std::uint64_t pd_matrix_version(const Objective& objective);

}  // namespace mgcloth::physics
