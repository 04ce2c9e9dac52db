#include <mgcloth/core/error.hpp>
#include <mgcloth/physics/attachment.hpp>
#include <mgcloth/physics/element_kernels.hpp>

namespace mgcloth::physics {

AttachmentTerm::AttachmentTerm(std::vector<Index> vertices, std::vector<double> stiffness, Index n)
    : m_stiffness(std::move(stiffness)), m_targets(vertices.size(), Vec3::Zero()) {
  if (m_stiffness.size() != vertices.size()) throw_error("AttachmentTerm: {} vertices but {} stiffnesses", vertices.size(), m_stiffness.size());
  std::vector<Element> els(vertices.size());
  for (size_t p = 0; p < vertices.size(); ++p) {
    if (vertices[p] < 0 || vertices[p] >= n) throw_input_error("pin {}: vertex {} out of range [0, {})", p, vertices[p], n);
    els[p] = {vertices[p]};
  }
  set_elements(std::move(els), n);
}

void AttachmentTerm::set_targets(const std::vector<Vec3>& targets) {
  if (targets.size() != m_targets.size()) throw_error("AttachmentTerm: {} targets for {} pins", targets.size(), m_targets.size());
  m_targets = targets;
}

double AttachmentTerm::element(Index e, const Local& xe, Local* g, LocalHessian* H) const {
  return hd::point_spring(xe.data(), m_targets[e].data(), m_stiffness[e], g ? g->data() : nullptr,
                          H ? H->data() : nullptr);
}


bool AttachmentTerm::describe_device(DeviceObjective& out) const {
  out.claim(out.pins, name());
  out.pin_vertex.clear();
  for (const auto& e : elements()) out.pin_vertex.push_back(e[0]);
  out.pin_k = m_stiffness;
  return true;
}

void AttachmentTerm::describe_device_step(DeviceStep& out) const { out.pin_targets = m_targets; }

}  // namespace mgcloth::physics
