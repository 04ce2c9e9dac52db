#include <mgcloth/physics/bending.hpp>

#include <mgcloth/core/parallel.hpp>

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <span>

namespace mgcloth::physics {

namespace {
std::vector<std::array<Index, 4>> hinge_elements(const mesh::Topology& topo) {
  std::vector<std::array<Index, 4>> els(topo.hinges.size());
  for (size_t h = 0; h < els.size(); ++h) els[h] = topo.hinges[h].v;
  return els;
}
double rest_weight(const mesh::TriMesh& mesh, const mesh::Hinge& h, double kb) {
  const double e2 = (mesh.u.col(h.v[1]) - mesh.u.col(h.v[0])).squaredNorm();
  const double a = std::abs(mesh.material_area(h.tri[0])) + std::abs(mesh.material_area(h.tri[1]));
  return 0.5 * kb * e2 / a;
}
double cot(const Vec2& a, const Vec2& b) {
  const double cross = a.x() * b.y() - a.y() * b.x();
  return a.dot(b) / std::abs(cross);
}
// A quadratic's monomials at a point in coordinates centred on the fit's midpoint and scaled by an edge length, so
// that the fit's conditioning measures the geometry, not the units.
Eigen::Matrix<double, 1, 6> monomials(const Vec2& p) {
  return (Eigen::Matrix<double, 1, 6>() << 1.0, p.x(), p.y(), p.x() * p.x(), p.x() * p.y(), p.y() * p.y()).finished();
}

// Smallest over largest singular value of the fit's rows: below this a point is nearly on a conic through the others
// and would make the slope ill-conditioned.
constexpr double kFitConditioning = 1e-3;

// The slope at the midpoint of edge (a, b) of the quadratic through a, b, the opposite vertices c, d and the two
// nearest vertices (1-ring of a and b, then 2-ring) that keep the fit well conditioned: weights on six vertices for
// the gradient's x and y. False when the neighbourhood has no such six (a tiny mesh).
struct EdgeSlope {
  std::array<Index, 6> v{};
  Eigen::Matrix<double, 6, 1> gx, gy;
};
bool edge_slope(const mesh::TriMesh& mesh, const mesh::Topology& topo, Index a, Index b, Index c, Index d, EdgeSlope& out) {
  const Vec2 mid = 0.5 * (mesh.u.col(a) + mesh.u.col(b));
  const double h = (mesh.u.col(b) - mesh.u.col(a)).norm();
  const auto local = [&](Index v) { return Vec2((mesh.u.col(v) - mid) / h); };
  const auto neighbours = [&](Index v) {
    return std::span<const Index>(topo.adjacency.data() + topo.adjacency_offsets[v],
                                  topo.adjacency.data() + topo.adjacency_offsets[v + 1]);
  };
  std::vector<Index> ids{a, b, c, d};
  Eigen::Matrix<double, Eigen::Dynamic, 6> V(6, 6);
  for (int i = 0; i < 4; ++i) V.row(i) = monomials(local(ids[i]));
  const auto try_candidates = [&](std::vector<Index> cand) {
    std::sort(cand.begin(), cand.end());
    cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
    std::erase_if(cand, [&](Index v) { return std::find(ids.begin(), ids.end(), v) != ids.end(); });
    std::stable_sort(cand.begin(), cand.end(), [&](Index p, Index q) { return local(p).squaredNorm() < local(q).squaredNorm(); });
    for (Index v : cand) {
      if (ids.size() == 6) return;
      const Index k = static_cast<Index>(ids.size());
      V.row(k) = monomials(local(v));
      Eigen::JacobiSVD<Eigen::MatrixXd> svd(V.topRows(k + 1));
      const auto& sv = svd.singularValues();
      if (sv(k) > kFitConditioning * sv(0)) ids.push_back(v);
    }
  };
  std::vector<Index> ring;
  for (Index v : {a, b})
    for (Index w : neighbours(v)) ring.push_back(w);
  try_candidates(ring);
  if (ids.size() < 6) {
    std::vector<Index> ring2;
    for (Index v : ring)
      for (Index w : neighbours(v)) ring2.push_back(w);
    try_candidates(ring2);
  }
  if (ids.size() < 6) return false;
  const Eigen::Matrix<double, 6, 6> inv = Eigen::Matrix<double, 6, 6>(V).inverse();
  std::copy(ids.begin(), ids.end(), out.v.begin());
  out.gx = inv.row(1).transpose() / h;
  out.gy = inv.row(2).transpose() / h;
  return true;
}

// Gradient of the linear interpolant on triangle t: column j is ∇λ_j.
Eigen::Matrix<double, 2, 3> linear_gradients(const mesh::TriMesh& mesh, const Tri& t) {
  Mat2 D;
  D.col(0) = mesh.u.col(t[1]) - mesh.u.col(t[0]);
  D.col(1) = mesh.u.col(t[2]) - mesh.u.col(t[0]);
  const Mat2 Di = D.inverse();  // rows: ∇λ1, ∇λ2
  Eigen::Matrix<double, 2, 3> G;
  G.col(1) = Di.row(0).transpose();
  G.col(2) = Di.row(1).transpose();
  G.col(0) = -G.col(1) - G.col(2);
  return G;
}
}  // namespace

TriangleCurvature recovered_curvature(const mesh::TriMesh& mesh, const mesh::Topology& topo) {
  const Index ne = topo.num_edges(), nt = mesh.num_triangles();
  // The slope stencil of each interior edge, from its two triangles' opposite vertices.
  std::vector<EdgeSlope> slope(static_cast<size_t>(ne));
  std::vector<char> has_fit(static_cast<size_t>(ne), 0), interior(static_cast<size_t>(ne), 0);
  TriangleCurvature out;
  const auto opposite = [&](Index t, Index e) {
    for (Index v : mesh.tris[t])
      if (v != topo.edges[e][0] && v != topo.edges[e][1]) return v;
    return Index{-1};
  };
  for (Index e = 0; e < ne; ++e) {
    const auto [t0, t1] = topo.edge_tris[e];
    if (t0 < 0 || t1 < 0) continue;
    interior[e] = 1;
    has_fit[e] = edge_slope(mesh, topo, topo.edges[e][0], topo.edges[e][1], opposite(t0, e), opposite(t1, e), slope[e]);
    if (!has_fit[e]) ++out.fallback_edges;
  }
  const Eigen::Vector3d metric(1.0, 2.0, 1.0);  // |S|² = S_xx² + 2 S_xy² + S_yy²
  out.area.resize(static_cast<size_t>(nt));
  std::vector<std::pair<Index, Eigen::Vector3d>> acc;
  for (Index t = 0; t < nt; ++t) {
    const Tri& tri = mesh.tris[t];
    const double signed_area = mesh.material_area(t), A = std::abs(signed_area);
    out.area[t] = A;
    const Eigen::Matrix<double, 2, 3> G = linear_gradients(mesh, tri);
    acc.clear();
    const auto add = [&](Index v, const Eigen::Vector3d& w) {
      for (auto& [u, x] : acc)
        if (u == v) return void(x += w);
      acc.emplace_back(v, w);
    };
    Eigen::Matrix<double, 3, 3> free_sides;
    int nfree = 0;
    for (int k = 0; k < 3; ++k) {
      const Index a = tri[k], b = tri[(k + 1) % 3];
      const Vec2 e = mesh.u.col(b) - mesh.u.col(a);
      const double len = e.norm();
      Vec2 nu = Vec2(e.y(), -e.x()) / len;  // outward for a counter-clockwise triangle
      if (signed_area < 0) nu = -nu;
      const Eigen::Vector3d nn = Eigen::Vector3d(nu.x() * nu.x(), nu.x() * nu.y(), nu.y() * nu.y()) * (len / A);
      const Index edge = topo.tri_edges[t][k];
      if (!interior[edge]) {
        free_sides.col(nfree++) = nn;
        continue;
      }
      // Slope excess at the midpoint: the shared recovered slope minus this triangle's own linear slope.
      if (has_fit[edge]) {
        const EdgeSlope& s = slope[edge];
        for (int j = 0; j < 6; ++j) add(s.v[j], nn * (nu.x() * s.gx[j] + nu.y() * s.gy[j]));
      } else {
        for (Index side_tri : topo.edge_tris[edge]) {  // bisector: the mean of the two triangles' linear slopes
          const Eigen::Matrix<double, 2, 3> Gs = linear_gradients(mesh, mesh.tris[side_tri]);
          for (int j = 0; j < 3; ++j) add(mesh.tris[side_tri][j], nn * (0.5 * nu.dot(Gs.col(j))));
        }
      }
      for (int j = 0; j < 3; ++j) add(tri[j], -nn * nu.dot(G.col(j)));
    }
    // A free side's slope is its own unknown, touching this triangle only: minimizing |S|² over it removes S's
    // component along that side's ν νᵀ (in the energy's metric), the discrete M_νν = 0.
    Eigen::Matrix3d P = Eigen::Matrix3d::Identity();
    if (nfree > 0) {
      const auto B = free_sides.leftCols(nfree);
      const Eigen::MatrixXd BtMB = B.transpose() * metric.asDiagonal() * B;
      P -= B * BtMB.completeOrthogonalDecomposition().solve(Eigen::MatrixXd(B.transpose() * metric.asDiagonal()));
    }
    for (const auto& [v, w] : acc) {
      out.vertices.push_back(v);
      out.weights.push_back(P * w);
    }
    out.offsets.push_back(static_cast<Index>(out.vertices.size()));
  }
  return out;
}

IsometricBending::IsometricBending(const mesh::TriMesh& mesh, const mesh::Topology& topo, const Material& m) {
  m_S = recovered_curvature(mesh, topo);
  m_kb = m.bending_stiffness;
  const TriangleCurvature& S = m_S;
  const Eigen::Vector3d metric(1.0, 2.0, 1.0);
  std::vector<Eigen::Triplet<double>> entries;
  for (Index t = 0; t < mesh.num_triangles(); ++t) {
    const double c = m.bending_stiffness * S.area[t];
    for (Index i = S.offsets[t]; i < S.offsets[t + 1]; ++i)
      for (Index j = S.offsets[t]; j < S.offsets[t + 1]; ++j)
        entries.emplace_back(S.vertices[i], S.vertices[j], c * S.weights[i].dot(metric.cwiseProduct(S.weights[j])));
  }
  m_K.resize(mesh.num_vertices(), mesh.num_vertices());
  m_K.setFromTriplets(entries.begin(), entries.end());
  m_K.makeCompressed();
}

double IsometricBending::value(const VecX& x) const {
  // Per triangle |D²x|², so that a planar state is zero to the square of round-off and the energy is never negative.
  const Index nt = static_cast<Index>(m_S.area.size());
  return 0.5 * m_kb * parallel_sum(nt, [&](Index t) {
    Eigen::Matrix3d D = Eigen::Matrix3d::Zero();  // column c: (S_xx, S_xy, S_yy) of coordinate c
    for (Index k = m_S.offsets[t]; k < m_S.offsets[t + 1]; ++k) D += m_S.weights[k] * x.segment<3>(3 * m_S.vertices[k]).transpose();
    return m_S.area[t] * (D.row(0).squaredNorm() + 2.0 * D.row(1).squaredNorm() + D.row(2).squaredNorm());
  });
}

void IsometricBending::add_gradient(const VecX& x, VecX& g) const {
  parallel_for(m_K.rows(), [&](Index i) {
    Vec3 Kx = Vec3::Zero();
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(m_K, i); it; ++it)
      Kx += it.value() * x.segment<3>(3 * it.col());
    g.segment<3>(3 * i) += Kx;
  });
}

void IsometricBending::add_hessian(const VecX&, linalg::BlockMatrix3& H, bool) const {
  // K ⊗ I₃ is positive semi-definite as a whole (a sum of A_T WᵀMW), so there is nothing to project.
  const Index* outer = m_K.outerIndexPtr();
  const double* val = m_K.valuePtr();
  parallel_for(m_K.rows(), [&](Index i) {
    for (Index k = outer[i]; k < outer[i + 1]; ++k) H.block(m_slots[k]).diagonal().array() += val[k];
  });
}

void IsometricBending::collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const {
  for (Index i = 0; i < m_K.rows(); ++i)
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(m_K, i); it; ++it)
      if (i <= it.col()) pairs.emplace_back(i, static_cast<Index>(it.col()));
}

void IsometricBending::bind(const linalg::BlockMatrix3& pattern) {
  m_slots.resize(static_cast<size_t>(m_K.nonZeros()));
  const Index* outer = m_K.outerIndexPtr();
  const Index* inner = m_K.innerIndexPtr();
  for (Index i = 0; i < m_K.rows(); ++i)
    for (Index k = outer[i]; k < outer[i + 1]; ++k) m_slots[static_cast<size_t>(k)] = pattern.find(i, inner[k]);
}

std::unique_ptr<Term> make_bending(const mesh::TriMesh& mesh, const mesh::Topology& topo, const Material& m,
                                   bool projective) {
  switch (m.bending) {
    case BendingModel::Hinge:
      if (projective) return std::make_unique<IsometricBending>(mesh, topo, m);
      return std::make_unique<HingeBending>(mesh, topo, m);
    case BendingModel::Quadratic: return std::make_unique<IsometricBending>(mesh, topo, m);
    case BendingModel::QuadraticBergou: return std::make_unique<QuadraticBending>(mesh, topo, m);
    case BendingModel::None: break;
  }
  return nullptr;
}

double dihedral_angle(const Vec12& x) { return hd::dihedral_angle(x.data()); }

Mat12 dihedral_angle_hessian(const Vec12& x) {
  Eigen::Matrix<double, 12, 12, Eigen::RowMajor> H;
  hd::dihedral_angle_hessian(x.data(), H.data());
  return 0.5 * (H + H.transpose());
}

HingeBending::HingeBending(const mesh::TriMesh& mesh, const mesh::Topology& topo, const Material& m) {
  m_weight.resize(topo.hinges.size());
  for (size_t h = 0; h < topo.hinges.size(); ++h) m_weight[h] = rest_weight(mesh, topo.hinges[h], m.bending_stiffness);
  set_elements(hinge_elements(topo), mesh.num_vertices());
}

double HingeBending::element(Index e, const Local& xe, Local* g, LocalHessian* H) const {
  const double c = m_weight[e];
  if (!H) return hd::hinge_bending_psd(xe.data(), c, g ? g->data() : nullptr, nullptr);
  const double energy = hd::hinge_bending_psd(xe.data(), c, g ? g->data() : nullptr, H->data());
  // The exact Hessian adds 2cθ∇²θ to the Gauss-Newton part (none for a collapsed hinge, whose ∇θ is set to 0).
  if (!hd::hinge_degenerate(xe.data())) *H += 2.0 * c * hd::dihedral_angle(xe.data()) * dihedral_angle_hessian(xe);
  return energy;
}

void HingeBending::element_psd_hessian(Index e, const Local& xe, LocalHessian& H) const {
  hd::hinge_bending_psd(xe.data(), m_weight[e], nullptr, H.data());
}

QuadraticBending::QuadraticBending(const mesh::TriMesh& mesh, const mesh::Topology& topo, const Material& m) {
  m_k.resize(topo.hinges.size());
  m_weight.resize(topo.hinges.size());
  for (size_t h = 0; h < topo.hinges.size(); ++h) {
    const auto& v = topo.hinges[h].v;
    // Bergou et al. 2006: e0 = x1 − x0, e1 = x2 − x0, e2 = x3 − x0, e3 = x2 − x1, e4 = x3 − x1; c0k = cot∠(e0, ek).
    const Vec2 u0 = mesh.u.col(v[0]), u1 = mesh.u.col(v[1]), u2 = mesh.u.col(v[2]), u3 = mesh.u.col(v[3]);
    const Vec2 e0 = u1 - u0, e1 = u2 - u0, e2 = u3 - u0, e3 = u2 - u1, e4 = u3 - u1;
    const double c01 = cot(e0, e1), c02 = cot(e0, e2), c03 = cot(-e0, e3), c04 = cot(-e0, e4);
    m_k[h] = Eigen::Vector4d(c03 + c04, c01 + c02, -c01 - c03, -c02 - c04);
    const double a = std::abs(mesh.material_area(topo.hinges[h].tri[0])) + std::abs(mesh.material_area(topo.hinges[h].tri[1]));
    m_weight[h] = 0.5 * m.bending_stiffness / a;
  }
  set_elements(hinge_elements(topo), mesh.num_vertices());
}

double QuadraticBending::element(Index e, const Local& xe, Local* g, LocalHessian* H) const {
  return hd::quadratic_bending(xe.data(), m_k[e].data(), m_weight[e], g ? g->data() : nullptr, H ? H->data() : nullptr);
}


namespace {
void claim_bending(DeviceObjective& out, DeviceObjective::Bending model) {
  bool described = out.bending != DeviceObjective::Bending::None;
  out.claim(described, "bending");
  out.bending = model;
}
}  // namespace

bool HingeBending::describe_device(DeviceObjective& out) const {
  claim_bending(out, DeviceObjective::Bending::Hinge);
  out.hinges.assign(elements().begin(), elements().end());
  out.hinge_c = m_weight;
  return true;
}

bool QuadraticBending::describe_device(DeviceObjective& out) const {
  claim_bending(out, DeviceObjective::Bending::Quadratic);
  out.hinges.assign(elements().begin(), elements().end());
  out.hinge_c = m_weight;
  out.hinge_k.clear();
  for (const Eigen::Vector4d& k : m_k) out.hinge_k.push_back({k[0], k[1], k[2], k[3]});
  return true;
}

bool IsometricBending::describe_device(DeviceObjective& out) const {
  claim_bending(out, DeviceObjective::Bending::Isometric);
  out.bend_matrix = &m_K;
  out.curvature = &m_S;
  out.bend_stiffness = m_kb;
  return true;
}

}  // namespace mgcloth::physics
