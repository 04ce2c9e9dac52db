#include <mgcloth/physics/inertia.hpp>

namespace mgcloth::physics {
namespace {
std::vector<std::array<Index, 1>> every_vertex(Index n) {
  std::vector<std::array<Index, 1>> v(n);
  for (Index i = 0; i < n; ++i) v[i] = {i};
  return v;
}
}  // namespace

InertiaTerm::InertiaTerm(VecX m) : m_mass(std::move(m)), m_y(VecX::Zero(3 * m_mass.size())) {
  set_elements(every_vertex(static_cast<Index>(m_mass.size())), static_cast<Index>(m_mass.size()));
}

void InertiaTerm::set_prediction(const VecX& y, double h) {
  m_y = y;
  m_inv_h2 = 1.0 / (h * h);
}

double InertiaTerm::element(Index i, const Local& xe, Local* g, LocalHessian* H) const {
  const double k = m_mass[i] * m_inv_h2;
  const Vec3 d = xe - m_y.segment<3>(3 * i);
  if (g) *g = k * d;
  if (H) *H = k * Mat3::Identity();
  return 0.5 * k * d.squaredNorm();
}

GravityTerm::GravityTerm(VecX m, const Vec3& gravity) : m_mass(std::move(m)), m_gravity(gravity) {
  set_elements(every_vertex(static_cast<Index>(m_mass.size())), static_cast<Index>(m_mass.size()));
}

double GravityTerm::element(Index i, const Local& xe, Local* g, LocalHessian* H) const {
  if (g) *g = -m_mass[i] * m_gravity;
  if (H) H->setZero();
  return -m_mass[i] * m_gravity.dot(xe);
}

}  // namespace mgcloth::physics
