#include <mgcloth/physics/element_kernels.hpp>
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
  return hd::point_spring(xe.data(), m_y.data() + 3 * i, m_mass[i] * m_inv_h2, g ? g->data() : nullptr,
                          H ? H->data() : nullptr);
}

GravityTerm::GravityTerm(VecX m, const Vec3& gravity) : m_mass(std::move(m)), m_gravity(gravity) {
  set_elements(every_vertex(static_cast<Index>(m_mass.size())), static_cast<Index>(m_mass.size()));
}

double GravityTerm::element(Index i, const Local& xe, Local* g, LocalHessian* H) const {
  if (g) *g = -m_mass[i] * m_gravity;
  if (H) H->setZero();
  return -m_mass[i] * m_gravity.dot(xe);
}


bool InertiaTerm::describe_device(DeviceObjective& out) const {
  out.claim(out.inertia, name());
  out.mass.assign(m_mass.data(), m_mass.data() + m_mass.size());
  return true;
}

void InertiaTerm::describe_device_step(DeviceStep& out) const {
  out.y = m_y;
  out.inv_h2 = m_inv_h2;
}

bool GravityTerm::describe_device(DeviceObjective& out) const {
  out.claim(out.gravity, name());
  out.g = m_gravity;
  out.gravity_mass.assign(m_mass.data(), m_mass.data() + m_mass.size());
  return true;
}

}  // namespace mgcloth::physics
