#pragma once
#include <mgcloth/mesh/opensubdiv.hpp>
#include <mgcloth/mesh/tri_mesh.hpp>

#include <memory>
#include <vector>

namespace mgcloth::mesh {

/// Weights of one limit-surface point in terms of the control points: x = Σ_k w(k, 0) q_{points[k]}, and
/// column d of w holds the derivative d in the face's parameters (s, t) ∈ [0, 1]²:
/// 0 value, 1 ∂s, 2 ∂t, 3 ∂ss, 4 ∂st, 5 ∂tt.
struct LimitStencil {
  std::vector<Index> points;
  Eigen::Matrix<double, Eigen::Dynamic, 6> w;
  Index size() const { return static_cast<Index>(points.size()); }
  /// Σ_k w(k, d) q_k for 3 x N control points q.
  Vec3 apply(const Mat3X& q, int d) const;
  Vec2 apply(const Mat2X& u, int d) const;
};

/// The Catmull-Clark limit surface of a quad control mesh, evaluated through OpenSubdiv's Bfr surfaces in double
/// precision (Kopaničáková 2019, §5.2: bicubic B-spline patches on regular faces, the refined representation of
/// Bfr around extraordinary points). Face f's parameters (s, t) run from corner quads[f][0] along the edge to
/// quads[f][1] (s) and to quads[f][3] (t). Ghost faces are not parameterized (§5.2.1).
class LimitSurface {
 public:
  /// `approx_level`: Bfr's refinement level for irregular (extraordinary) regions.
  explicit LimitSurface(const QuadMesh& mesh, int approx_level = 4);
  ~LimitSurface();
  LimitSurface(LimitSurface&&) noexcept;
  LimitSurface& operator=(LimitSurface&&) noexcept;

  const QuadMesh& mesh() const { return m_mesh; }
  /// Real (not ghost) faces: the parameter domain.
  const std::vector<Index>& real_faces() const { return m_real_faces; }
  /// Whether face f is regular (a bicubic B-spline patch with 16 control points).
  bool is_regular(Index face) const;
  /// Stencil of the point (s, t) of face f with derivatives up to the second.
  void stencil(Index face, double s, double t, LimitStencil& out) const;
  /// The face and its parameters whose limit material coordinate is u (Newton on the limit material map from the
  /// face centres nearest first); false when no real face contains u.
  bool locate(const Vec2& u, Index& face, double& s, double& t) const;
  /// The limit surface as a triangle mesh for display: each real face sampled on an r x r grid of sub-quads, two
  /// triangles each, vertices shared along face edges; material coordinates are the limit material map.
  struct Tessellation;
  Tessellation tessellate(int r) const;

 private:
  struct Impl;
  QuadMesh m_mesh;
  std::vector<Index> m_real_faces;
  std::unique_ptr<Impl> m;
};

/// A display mesh of the limit surface and the weights that place its vertices from the control points (built
/// once, applied per frame).
struct LimitSurface::Tessellation {
  TriMesh mesh;                   ///< positions of the control mesh it was built from
  std::vector<Index> offsets{0};  ///< CSR rows: display vertex i = Σ weights[k] q[indices[k]]
  std::vector<Index> indices;
  std::vector<double> weights;
  Mat3X positions(const Mat3X& q) const;
};

}  // namespace mgcloth::mesh
