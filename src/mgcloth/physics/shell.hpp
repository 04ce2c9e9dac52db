#pragma once
#include <mgcloth/mesh/limit_surface.hpp>
#include <mgcloth/physics/element_term.hpp>
#include <mgcloth/physics/shell_material.hpp>

#include <vector>

namespace mgcloth::physics {

/// Limit-surface data of one face at its Gauss points, computed once per level (Kopaničáková 2019, §5.2 and §6:
/// basis functions and their first and second derivatives at the quadrature points).
struct ShellFaceQuadrature {
  Index face = -1;
  std::vector<Index> points;  ///< control points of the face's stencil (K)
  /// Per Gauss point a K x 6 block (value, ∂s, ∂t, ∂ss, ∂st, ∂tt), Gauss points one after another.
  std::vector<double> basis;
  Index size() const { return static_cast<Index>(points.size()); }
};

/// Gauss-Legendre points and weights of an n-point rule on [0, 1] (n = 1..5).
void line_gauss_rule(int n, std::vector<double>& points, std::vector<double>& weights);
/// Gauss-Legendre points and weights of an n x n rule on the unit square.
void square_gauss_rule(int n, std::vector<Vec2>& points, std::vector<double>& weights);

/// Stencils of every real face of `surface` at the points of an n x n Gauss rule.
std::vector<ShellFaceQuadrature> shell_quadrature(const mesh::LimitSurface& surface, int n);

/// One level of a subdivision Kirchhoff-Love shell: the elastic energy of §3 (eqs. 3.2-3.4) from the first and
/// second fundamental forms of the limit surface, the implicit-Euler kinetic term with the consistent mass matrix
/// M = ∫ ρ N Nᵀ dA, and gravity, integrated over every real face by an n x n Gauss rule (eq. 5.9). Unknowns are
/// the control points (ghost points included, §5.2.1), 3 per point. The reference surface is the control mesh's
/// positions at construction. Elements are faces, of 16 points on regular faces and more around extraordinary
/// points; the exact Hessian may be indefinite (buckling, compression).
class ShellTerm : public Term {
 public:
  ShellTerm(const mesh::LimitSurface& surface, const ShellMaterial& material, const Vec3& gravity, int gauss = 3);

  std::string name() const override { return "shell"; }
  double value(const VecX& x) const override;
  void add_gradient(const VecX& x, VecX& g) const override;
  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const override;
  void collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const override;
  void bind(const linalg::BlockMatrix3& pattern) override;

  /// The kinetic term of the implicit-Euler step of size h towards the prediction y (control points):
  /// ρ / (2 h²) ∫ |x − y|² dA. h <= 0 removes it (static equilibrium).
  void set_inertia(double h, const VecX& y);
  /// Scales gravity (load stepping in static solves).
  void set_gravity_scale(double s) { m_gravity_scale = s; }
  /// Which parts contribute (tests and diagnostics).
  void set_parts(bool elastic, bool inertia, bool gravity);

  Index num_points() const { return m_num_points; }
  Index num_elements() const { return static_cast<Index>(m_faces.size()); }
  const std::vector<ShellFaceQuadrature>& faces() const { return m_faces; }
  /// Reference area (∫ dĀ over the real faces) and mass.
  double area() const { return m_area; }
  double mass() const { return m_area * m_material.density; }
  /// The consistent mass matrix times v, for kinetic energies (½ vᵀ M v).
  VecX mass_times(const VecX& v) const;
  /// Energy of face element e at x, with its gradient (3K) and Hessian (3K x 3K) when non-null.
  double element(Index e, const VecX& x, VecX* g, MatX* H) const;

 private:
  /// Reference data of one Gauss point.
  struct Reference {
    double dA = 0.0;   ///< Gauss weight × reference area element √det ā
    Vec3 abar;         ///< (ā11, ā22, ā12)
    Vec3 bbar;         ///< (b̄11, b̄22, b̄12)
    Mat3 T;            ///< covariant (E11, E22, E12) -> frame (Ẽ11, Ẽ22, Ẽ12)
  };
  ShellMaterial m_material;
  Vec3 m_gravity;
  double m_gravity_scale = 1.0;
  double m_inertia_coeff = 0.0;  ///< ρ / h²
  VecX m_prediction;
  bool m_elastic = true, m_inertia = true, m_gravity_on = true;
  Index m_num_points = 0;
  int m_gauss = 3;
  std::vector<ShellFaceQuadrature> m_faces;
  std::vector<Reference> m_ref;  ///< m_gauss² per element
  double m_area = 0.0;
  ElementColors m_colors;
  std::vector<Index> m_slot_offsets;  ///< element e's K² block slots start here
  std::vector<Index> m_slots;
};

}  // namespace mgcloth::physics
