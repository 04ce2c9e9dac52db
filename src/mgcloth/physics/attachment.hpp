#pragma once
#include <mgcloth/physics/element_term.hpp>

namespace mgcloth::physics {

/// Pins as stiff springs to (possibly moving) targets: E = Σ_p k_p/2 |x_{i_p} − target_p|².
class AttachmentTerm final : public ElementTerm<1> {
 public:
  bool describe_device(DeviceObjective& out) const override;
  void describe_device_step(DeviceStep& out) const override;
  /// `vertices` and `stiffness` (N/m) per pin; several pins may share a vertex.
  AttachmentTerm(std::vector<Index> vertices, std::vector<double> stiffness, Index num_vertices);
  std::string name() const override { return "attachment"; }
  void set_targets(const std::vector<Vec3>& targets);
  const std::vector<Vec3>& targets() const { return m_targets; }
  const std::vector<double>& stiffness() const { return m_stiffness; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;

 private:
  std::vector<double> m_stiffness;
  std::vector<Vec3> m_targets;
};

}  // namespace mgcloth::physics
