#include <mgcloth/physics/bending.hpp>

#include <unsupported/Eigen/AutoDiff>

#include <cmath>

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
}  // namespace

double dihedral_angle(const Vec12& x) { return hd::dihedral_angle(x.data()); }

Mat12 dihedral_angle_hessian(const Vec12& x) {
  using AD = Eigen::AutoDiffScalar<Vec12>;
  std::array<AD, 12> xa, ga;
  for (int i = 0; i < 12; ++i) xa[i] = AD(x[i], 12, i);
  hd::dihedral_angle_gradient(xa.data(), ga.data());
  Mat12 H;
  for (int i = 0; i < 12; ++i) H.row(i) = ga[i].derivatives().transpose();
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

}  // namespace mgcloth::physics
