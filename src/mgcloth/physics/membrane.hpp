#pragma once
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/element_term.hpp>
#include <mgcloth/physics/material.hpp>

namespace mgcloth::physics {

using Vec9 = Eigen::Matrix<double, 9, 1>;
using Mat9 = Eigen::Matrix<double, 9, 9>;

/// Rest shape of triangle t from the material coordinates: Dm⁻¹ (Dm = [u1−u0, u2−u0]) and the material area.
/// Throws InputError for a triangle with non-positive material area.
struct TriangleRest {
  Mat2 dm_inv;
  double area = 0.0;
};
TriangleRest triangle_rest(const mesh::TriMesh& mesh, Index t);
/// triangle_rest of every triangle, in order.
std::vector<TriangleRest> triangle_rests(const mesh::TriMesh& mesh);

/// St. Venant-Kirchhoff energy of one triangle: W = A·t·(μ tr(E²) + λ/2 tr(E)²), with the deformation gradient
/// F = [x1−x0, x2−x0] Dm⁻¹ (3x2), Green strain E = (FᵀF − I)/2 and plane-stress Lamé parameters.
/// Gradient and Hessian are exact (the Hessian is indefinite under compression; callers project it), or with
/// clamp_stress the PSD form of StVKMembrane::element_psd_hessian.
double stvk_triangle(const Vec9& xe, const Mat2& dm_inv, double area_thickness, double mu, double lambda, Vec9* g,
                     Mat9* H, bool clamp_stress = false);

/// StVK membrane over all triangles of a mesh, rest shape from material coordinates.
class StVKMembrane final : public ElementTerm<3> {
 public:
  bool describe_device(DeviceObjective& out) const override;
  StVKMembrane(const mesh::TriMesh& mesh, const Material& material);
  std::string name() const override { return "membrane_stvk"; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;
  /// The exact Hessian with the second Piola-Kirchhoff stress S replaced by its positive part in the geometric
  /// term (b_aᵀ S b_c) I: the material term is a Gauss-Newton form JᵀCJ and always PSD, and the geometric term is
  /// what goes indefinite under compression (buckling). Equal to the exact Hessian wherever S ⪰ 0.
  void element_psd_hessian(Index e, const Local& xe, LocalHessian& H) const override;
  const std::vector<TriangleRest>& rest() const { return m_rest; }
  double thickness() const { return m_thickness; }
  double mu() const { return m_mu; }
  double lambda() const { return m_lambda; }

 private:
  std::vector<TriangleRest> m_rest;
  double m_thickness, m_mu, m_lambda;
};

/// Springs on mesh edges: E = k_e/2 (|x1−x0| − L)², with k_e = E·t·A_e/L² so that the energy density is that of
/// a uniaxial strain (A_e: a third of the adjacent triangles' material area). The exact Hessian has the
/// transverse part k(1 − L/l)(I − d̂d̂ᵀ), negative in compression; projection clamps it.
class MassSpringMembrane final : public ElementTerm<2> {
 public:
  MassSpringMembrane(const mesh::TriMesh& mesh, const mesh::Topology& topology, const Material& material);
  std::string name() const override { return "membrane_springs"; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;

 private:
  std::vector<double> m_rest, m_stiffness;
};

}  // namespace mgcloth::physics
