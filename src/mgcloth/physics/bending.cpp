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

double dihedral_angle(const Vec12& x) {
  const Vec3 x0 = x.segment<3>(0), x1 = x.segment<3>(3), x2 = x.segment<3>(6), x3 = x.segment<3>(9);
  const Vec3 e = x1 - x0;
  const Vec3 n1 = e.cross(x2 - x0), n2 = (x3 - x0).cross(e);
  return std::atan2(n1.cross(n2).dot(e.normalized()), n1.dot(n2));
}

Mat12 dihedral_angle_hessian(const Vec12& x) {
  using AD = Eigen::AutoDiffScalar<Vec12>;
  Eigen::Matrix<AD, 12, 1> xa;
  for (int i = 0; i < 12; ++i) xa[i] = AD(x[i], 12, i);
  const Eigen::Matrix<AD, 12, 1> ga = dihedral_angle_gradient(xa);
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
  const double theta = dihedral_angle(xe);
  const double c = m_weight[e];
  if (!g && !H) return c * theta * theta;
  // A hinge whose triangle collapsed in world space has no defined angle gradient; it contributes no force.
  const Vec3 e01 = xe.segment<3>(3) - xe.segment<3>(0);
  const double tiny = 1e-24 * e01.squaredNorm() * e01.squaredNorm();
  if (e01.cross(xe.segment<3>(6) - xe.segment<3>(0)).squaredNorm() <= tiny ||
      e01.cross(xe.segment<3>(9) - xe.segment<3>(0)).squaredNorm() <= tiny) {
    if (g) g->setZero();
    if (H) H->setZero();
    return c * theta * theta;
  }
  const Vec12 dtheta = dihedral_angle_gradient<double>(xe);
  if (g) *g = 2.0 * c * theta * dtheta;
  if (H) *H = 2.0 * c * (dtheta * dtheta.transpose() + theta * dihedral_angle_hessian(xe));
  return c * theta * theta;
}

void HingeBending::element_psd_hessian(Index e, const Local& xe, LocalHessian& H) const {
  const Vec3 e01 = xe.segment<3>(3) - xe.segment<3>(0);
  const double tiny = 1e-24 * e01.squaredNorm() * e01.squaredNorm();
  if (e01.cross(xe.segment<3>(6) - xe.segment<3>(0)).squaredNorm() <= tiny ||
      e01.cross(xe.segment<3>(9) - xe.segment<3>(0)).squaredNorm() <= tiny) {
    H.setZero();
    return;
  }
  const Vec12 dtheta = dihedral_angle_gradient<double>(xe);
  H = 2.0 * m_weight[e] * dtheta * dtheta.transpose();
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
  const auto& K = m_k[e];
  Vec3 s = Vec3::Zero();
  for (int i = 0; i < 4; ++i) s += K[i] * xe.segment<3>(3 * i);
  const double c = m_weight[e];
  if (g)
    for (int i = 0; i < 4; ++i) g->segment<3>(3 * i) = 2.0 * c * K[i] * s;
  if (H)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) H->block<3, 3>(3 * i, 3 * j) = 2.0 * c * K[i] * K[j] * Mat3::Identity();
  return c * s.squaredNorm();
}

}  // namespace mgcloth::physics
