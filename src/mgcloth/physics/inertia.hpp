#pragma once
#include <mgcloth/physics/element_term.hpp>

namespace mgcloth::physics {

/// Σ m_i / (2h²) |x_i − y_i|² with y = x_t + h v_t the inertial prediction: the kinetic part of Wang 2018, eq. (2).
class InertiaTerm final : public ElementTerm<1> {
 public:
  bool describe_device(DeviceObjective& out) const override;
  void describe_device_step(DeviceStep& out) const override;
  explicit InertiaTerm(VecX lumped_mass);
  std::string name() const override { return "inertia"; }
  void set_prediction(const VecX& y, double h);
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;
  /// m_i/h² I is positive semi-definite as it is: no projection.
  void element_psd_hessian(Index e, const Local& xe, LocalHessian& H) const override { element(e, xe, nullptr, &H); }
  const VecX& mass() const { return m_mass; }
  const VecX& prediction() const { return m_y; }
  double inv_h2() const { return m_inv_h2; }

 private:
  VecX m_mass, m_y;
  double m_inv_h2 = 0.0;
};

/// −Σ m_i g·x_i: the potential of a uniform gravity field.
class GravityTerm final : public ElementTerm<1> {
 public:
  bool describe_device(DeviceObjective& out) const override;
  GravityTerm(VecX lumped_mass, const Vec3& gravity);
  std::string name() const override { return "gravity"; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;
  /// The energy is linear: its Hessian adds nothing.
  void add_hessian(const VecX&, linalg::BlockMatrix3&, bool) const override {}
  const VecX& mass() const { return m_mass; }
  const Vec3& gravity() const { return m_gravity; }

 private:
  VecX m_mass;
  Vec3 m_gravity;
};

}  // namespace mgcloth::physics
