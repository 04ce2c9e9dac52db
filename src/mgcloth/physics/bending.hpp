#pragma once
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/element_kernels.hpp>
#include <mgcloth/physics/element_term.hpp>
#include <mgcloth/physics/material.hpp>

namespace mgcloth::physics {

using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;

/// Signed dihedral angle of a hinge (x0, x1 the edge, x2 and x3 the opposite vertices, see mesh::Hinge):
/// θ = atan2((N1 × N2)·ê, N1·N2), N1 = e × (x2 − x0), N2 = (x3 − x0) × e; zero when flat (hd::dihedral_angle).
double dihedral_angle(const Vec12& x);

/// Exact ∇²θ by forward-mode differentiation of dihedral_angle_gradient.
Mat12 dihedral_angle_hessian(const Vec12& x);

/// Hinge bending: E = k_b |ē|²/(2(Ā1 + Ā2)) (θ − θ̄)² per interior edge, with rest quantities from the flat
/// material state (θ̄ = 0); the discrete-shells form of Grinspun et al. 2003. The weight is calibrated so that the
/// sum equals ∫ k_b/2 κ² dA on a cylinder of curvature κ for regular grids (and is within 15% of it on
/// quasi-uniform Delaunay meshes), making k_b the bending rigidity in N·m.
class HingeBending final : public ElementTerm<4> {
 public:
  HingeBending(const mesh::TriMesh& mesh, const mesh::Topology& topology, const Material& material);
  std::string name() const override { return "bending_hinge"; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;
  /// Gauss-Newton: 2c ∇θ∇θᵀ, dropping the 2cθ∇²θ part, which is indefinite for any θ ≠ 0 and whose projection
  /// would need a 12x12 eigendecomposition per hinge. Exact at the flat rest state.
  void element_psd_hessian(Index e, const Local& xe, LocalHessian& H) const override;
  /// c of each hinge.
  const std::vector<double>& weights() const { return m_weight; }

 private:
  std::vector<double> m_weight;
};

/// The quadratic (isometric) bending model of Bergou et al. 2006: E = k_b/(2(Ā1 + Ā2)) |Σ_i K_i x_i|² with the
/// cotangent weights K = (c03 + c04, c01 + c02, −c01 − c03, −c02 − c04) of the rest hinge. Its Hessian is
/// constant and positive semi-definite; for small angles it agrees with HingeBending.
class QuadraticBending final : public ElementTerm<4> {
 public:
  QuadraticBending(const mesh::TriMesh& mesh, const mesh::Topology& topology, const Material& material);
  std::string name() const override { return "bending_quadratic"; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;
  /// The Hessian is constant and PSD already: no projection.
  void element_psd_hessian(Index e, const Local& xe, LocalHessian& H) const override {
    Local g;
    element(e, xe, &g, &H);
  }

  const std::vector<Eigen::Vector4d>& cotangent_weights() const { return m_k; }
  const std::vector<double>& weights() const { return m_weight; }

 private:
  std::vector<Eigen::Vector4d> m_k;
  std::vector<double> m_weight;
};

}  // namespace mgcloth::physics
