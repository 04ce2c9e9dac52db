#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/physics/sub_objective.hpp>

namespace mgcloth::physics {

double SubObjectiveTerm::value(const VecX& x) const { return m_objective->value(local(x)); }

void SubObjectiveTerm::add_gradient(const VecX& x, VecX& g) const {
  VecX gl;
  m_objective->gradient(local(x), gl);
  g.segment(3 * m_offset, gl.size()) += gl;
}

double SubObjectiveTerm::value_and_gradient(const VecX& x, VecX& g) const {
  VecX gl;
  const double e = m_objective->value_and_gradient(local(x), gl);
  g.segment(3 * m_offset, gl.size()) += gl;
  return e;
}

void SubObjectiveTerm::add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const {
  if (m_slots.size() != static_cast<size_t>(m_objective->hessian_pattern().num_blocks()))
    throw_error("{}: the joint objective was not finalized after the term was added", m_name);
  m_objective->hessian(local(x), m_local, project_psd);
  const auto& blocks = m_local.blocks();
  parallel_for(static_cast<Index>(blocks.size()), [&](Index k) { H.block(m_slots[k]) += blocks[k]; }, 4096);
}

void SubObjectiveTerm::collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const {
  const linalg::BlockMatrix3& P = m_objective->hessian_pattern();
  for (Index r = 0; r < P.rows(); ++r)
    for (Index k = P.row_offsets()[r]; k < P.row_offsets()[r + 1]; ++k)
      if (r <= P.col_indices()[k]) pairs.emplace_back(m_offset + r, m_offset + P.col_indices()[k]);
}

void SubObjectiveTerm::bind(const linalg::BlockMatrix3& pattern) {
  const linalg::BlockMatrix3& P = m_objective->hessian_pattern();
  m_slots.resize(static_cast<size_t>(P.num_blocks()));
  for (Index r = 0; r < P.rows(); ++r)
    for (Index k = P.row_offsets()[r]; k < P.row_offsets()[r + 1]; ++k)
      m_slots[static_cast<size_t>(k)] = pattern.find(m_offset + r, m_offset + P.col_indices()[k]);
}


bool SubObjectiveTerm::describe_device(DeviceObjective& /*out*/) const {
  throw InputError("fmg-cuda: the device pipeline solves one body at a time (its data come from a body's own terms); "
                   "for a scene of several bodies set \"solve_bodies\": \"separately\" or use \"fmg\"");
}

}  // namespace mgcloth::physics
