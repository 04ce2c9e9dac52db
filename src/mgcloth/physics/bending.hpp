#pragma once
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/element_kernels.hpp>
#include <mgcloth/physics/element_term.hpp>
#include <mgcloth/physics/material.hpp>

#include <Eigen/SparseCore>
#include <memory>

namespace mgcloth::physics {

using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;

/// Signed dihedral angle of a hinge (x0, x1 the edge, x2 and x3 the opposite vertices, see mesh::Hinge):
/// θ = atan2((N1 × N2)·ê, N1·N2), N1 = e × (x2 − x0), N2 = (x3 − x0) × e; zero when flat (hd::dihedral_angle).
double dihedral_angle(const Vec12& x);

/// Exact ∇²θ, derived by hand (hd::dihedral_angle_hessian), symmetrized.
Mat12 dihedral_angle_hessian(const Vec12& x);

/// Hinge bending: E = k_b |ē|²/(2(Ā1 + Ā2)) (θ − θ̄)² per interior edge, with rest quantities from the flat
/// material state (θ̄ = 0); the discrete-shells form of Grinspun et al. 2003. The weight is calibrated so that the
/// sum equals ∫ k_b/2 κ² dA on a cylinder of curvature κ for regular grids (and is within 15% of it on
/// quasi-uniform Delaunay meshes), making k_b the bending rigidity in N·m.
class HingeBending final : public ElementTerm<4> {
 public:
  bool describe_device(DeviceObjective& out) const override;
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

/// Curvature of every triangle as a linear function of one scalar field w on the vertices: S_T = Σ_j W_Tj w_j, the
/// weights W_Tj = (xx, xy, yy) in material coordinates. S_T = (1/A_T) Σ_e |e| (s_e − ∇w_T·ν_e) ν_e ν_eᵀ over the
/// triangle's sides (ν_e the outward side normal, ∇w_T the gradient of the linear interpolant): the Hessian of the
/// Morley quadratic on T whose normal slopes at the side midpoints are s_e. Each interior edge's s_e is the slope at
/// its midpoint of the quadratic through six vertices around it (the edge's two triangles and the two vertices
/// nearest the midpoint that keep the fit well posed), shared by both triangles. So S_T is exact for quadratic w on
/// any mesh, and, the slopes being shared, Σ_T A_T S_T depends on boundary values only (the Morley element's patch
/// test): a quadratic w is the exact minimizer of the energy below for its own boundary values, where the discrete-
/// shells hinge energy relaxes below it by up to 16% and depends on the edges' directions (bench/RESULTS.md). On a
/// boundary side the slope is free, eliminated per triangle (the moment normal to a free edge vanishes).
struct TriangleCurvature {
  std::vector<Index> offsets{0};          ///< triangle t's weights are [offsets[t], offsets[t + 1])
  std::vector<Index> vertices;
  std::vector<Eigen::Vector3d> weights;   ///< (S_xx, S_xy, S_yy) per unit w of that vertex
  std::vector<double> area;               ///< material area of each triangle
  Index fallback_edges = 0;               ///< interior edges without a well-posed 6-point fit (bisector slope)
};
TriangleCurvature recovered_curvature(const mesh::TriMesh& mesh, const mesh::Topology& topology);

/// Consistent quadratic bending: E = k_b/2 Σ_T A_T |D²x|²_T, |D²x|² = Σ_c (S_xx² + 2 S_xy² + S_yy²) with S_T of each
/// coordinate c of x (TriangleCurvature). For an isometric deformation of the flat material state D²x = II n, so E
/// is the Kirchhoff bending energy k_b/2 ∫ |II|² dA for any rotation, not only small deflections (the idea of Bergou
/// et al. 2006), while the discretization is exact on quadratic surfaces and passes the patch test on every mesh.
/// E = ½ Σ_c x_cᵀ K x_c with one constant scalar matrix K; its Hessian K ⊗ I₃ is positive semi-definite.
class IsometricBending final : public Term {
 public:
  bool describe_device(DeviceObjective& out) const override;
  IsometricBending(const mesh::TriMesh& mesh, const mesh::Topology& topology, const Material& material);
  std::string name() const override { return "bending_quadratic"; }
  double value(const VecX& x) const override;
  void add_gradient(const VecX& x, VecX& g) const override;
  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const override;
  bool hessian_is_constant() const override { return true; }
  void collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const override;
  void bind(const linalg::BlockMatrix3& pattern) override;
  /// K, symmetric, both triangles stored.
  const Eigen::SparseMatrix<double, Eigen::RowMajor>& matrix() const { return m_K; }
  const TriangleCurvature& curvature() const { return m_S; }
  double stiffness() const { return m_kb; }

 private:
  Eigen::SparseMatrix<double, Eigen::RowMajor> m_K;
  std::vector<Index> m_slots;  ///< block of each stored entry of K
  TriangleCurvature m_S;       ///< for the value as a sum of squares (½ xᵀKx would carry round-off ∝ |K||x|²)
  double m_kb = 0.0;
};

/// The quadratic (isometric) bending model of Bergou et al. 2006: E = k_b/(2(Ā1 + Ā2)) |Σ_i K_i x_i|² with the
/// cotangent weights K = (c03 + c04, c01 + c02, −c01 − c03, −c02 − c04) of the rest hinge. Its Hessian is
/// constant and positive semi-definite; for small angles it agrees with HingeBending.
class QuadraticBending final : public ElementTerm<4> {
 public:
  bool describe_device(DeviceObjective& out) const override;
  QuadraticBending(const mesh::TriMesh& mesh, const mesh::Topology& topology, const Material& material);
  std::string name() const override { return "bending_quadratic"; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;
  bool hessian_is_constant() const override { return true; }
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

/// The bending term of a material's model (none for BendingModel::None). The Projective Dynamics form needs a
/// constant matrix: it takes the quadratic model for the hinge, whose matrix changes with x.
std::unique_ptr<Term> make_bending(const mesh::TriMesh& mesh, const mesh::Topology& topology, const Material& material,
                                   bool projective);

}  // namespace mgcloth::physics
