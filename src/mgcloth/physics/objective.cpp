#include <mgcloth/core/error.hpp>
#include <mgcloth/physics/objective.hpp>

namespace mgcloth::physics {

void Objective::finalize() {
  std::vector<std::pair<Index, Index>> pairs;
  for (const auto& t : m_terms) t->collect_pattern(pairs);
  m_pattern = linalg::BlockMatrix3(m_n, std::move(pairs));
  for (auto& t : m_terms) t->bind(m_pattern);
  m_finalized = true;
}

void Objective::require_finalized() const {
  if (!m_finalized) throw_error("Objective used before finalize()");
}

double Objective::value(const VecX& x) const {
  double e = 0.0;
  for (const auto& t : m_terms) e += t->value(x);
  return e;
}

void Objective::gradient(const VecX& x, VecX& g) const {
  g.setZero(x.size());
  for (const auto& t : m_terms) t->add_gradient(x, g);
}

void Objective::hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const {
  require_finalized();
  if (!H.same_pattern(m_pattern)) H = m_pattern;
  H.set_zero();
  for (const auto& t : m_terms) t->add_hessian(x, H, project_psd);
}

const linalg::BlockMatrix3& Objective::hessian_pattern() const {
  require_finalized();
  return m_pattern;
}

std::vector<std::pair<std::string, double>> Objective::term_values(const VecX& x) const {
  std::vector<std::pair<std::string, double>> out;
  for (const auto& t : m_terms) out.emplace_back(t->name(), t->value(x));
  return out;
}

}  // namespace mgcloth::physics
