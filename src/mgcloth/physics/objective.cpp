#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/physics/objective.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <random>

namespace mgcloth::physics {

void Objective::build_pattern() const {
  std::vector<std::pair<Index, Index>> pairs;
  // The variable terms' pairs first, so that the blocks they reach can be told from the constant terms' ones.
  for (const auto& t : m_terms)
    if (!t->hessian_is_constant()) t->collect_pattern(pairs);
  const size_t variable_pairs = pairs.size();
  for (const auto& t : m_terms)
    if (t->hessian_is_constant()) t->collect_pattern(pairs);
  const bool any_constant = pairs.size() > variable_pairs;
  std::vector<std::pair<Index, Index>> variable;
  if (any_constant) variable.assign(pairs.begin(), pairs.begin() + static_cast<std::ptrdiff_t>(variable_pairs));
  m_pattern = linalg::BlockMatrix3(m_n, std::move(pairs));
  m_constant_blocks.assign(static_cast<size_t>(m_pattern.num_blocks()), any_constant ? 1 : 0);
  if (any_constant) {
    for (Index r = 0; r < m_n; ++r) m_constant_blocks[m_pattern.diagonal(r)] = 0;
    for (const auto& [r, c] : variable) {
      m_constant_blocks[m_pattern.find(r, c)] = 0;
      m_constant_blocks[m_pattern.find(c, r)] = 0;
    }
  }
  m_variable_blocks.clear();
  for (Index k = 0; k < m_pattern.num_blocks(); ++k)
    if (!m_constant_blocks[k]) m_variable_blocks.push_back(k);
  for (const auto& t : m_terms) t->bind(m_pattern);
  ++m_pattern_version;
  static std::atomic<long> stamps{0};
  m_pattern_stamp = ++stamps;
}

void Objective::finalize() {
  build_pattern();
  m_finalized = true;
}

bool Objective::update_stencils(const VecX& x) const {
  require_finalized();
  bool changed = false;
  for (const auto& t : m_terms) changed = t->update_stencils(x) || changed;
  if (changed) build_pattern();
  return changed;
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

double Objective::value_and_gradient(const VecX& x, VecX& g) const {
  g.setZero(x.size());
  double e = 0.0;
  for (const auto& t : m_terms) e += t->value_and_gradient(x, g);
  return e;
}

void Objective::hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const {
  update_stencils(x);
  if (!H.same_pattern(m_pattern)) H = m_pattern;
  H.set_zero();
  for (const auto& t : m_terms) t->add_hessian(x, H, project_psd);
}

void Objective::hessian_reusing_constant(const VecX& x, linalg::BlockMatrix3& H, bool project_psd,
                                         ConstantHessian& cache) const {
  update_stencils(x);
  const bool same = H.same_pattern(m_pattern);  // compares the whole pattern: once
  const bool fresh = !same || cache.version != m_pattern_stamp || cache.project_psd != project_psd;
  if (!same) H = m_pattern;
  const Index nv = static_cast<Index>(m_variable_blocks.size());
  if (fresh) {
    H.set_zero();
    for (const auto& t : m_terms)
      if (t->hessian_is_constant()) t->add_hessian(x, H, project_psd);
    cache.values.resize(static_cast<size_t>(nv));
    parallel_for(nv, [&](Index j) { cache.values[j] = H.block(m_variable_blocks[j]); }, 4096);
    cache.version = m_pattern_stamp;
    cache.project_psd = project_psd;
  } else {
    parallel_for(nv, [&](Index j) { H.block(m_variable_blocks[j]) = cache.values[j]; }, 4096);
  }
  for (const auto& t : m_terms)
    if (!t->hessian_is_constant()) t->add_hessian(x, H, project_psd);
}

double Objective::max_step(const VecX& x, const VecX& d, double alpha_max) const {
  double a = alpha_max;
  for (const auto& t : m_terms)
    if (t->limits_steps()) a = std::min(a, t->max_step(x, d, a));
  return a;
}

bool Objective::limits_steps() const {
  return std::any_of(m_terms.begin(), m_terms.end(), [](const auto& t) { return t->limits_steps(); });
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

std::vector<GradientRoundoff> gradient_roundoff(const Objective& objective, const VecX& x, int samples,
                                                unsigned seed) {
  if (samples < 1) throw_error("gradient_roundoff: {} samples (at least 1)", samples);
  if (x.size() != objective.num_dofs())
    throw_error("gradient_roundoff: x has {} entries, the objective {} dofs", x.size(), objective.num_dofs());
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> step(-1, 1);
  constexpr double inf = std::numeric_limits<double>::infinity();
  std::vector<VecX> moved(static_cast<size_t>(samples), x);
  for (VecX& xp : moved)
    for (Index i = 0; i < xp.size(); ++i)
      if (const int d = step(rng); d != 0) xp[i] = std::nextafter(xp[i], d > 0 ? inf : -inf);
  const auto& terms = objective.terms();
  std::vector<GradientRoundoff> rows;
  for (size_t t = 0; t <= terms.size(); ++t) {
    const auto grad = [&](const VecX& at) {
      VecX g;
      if (t == terms.size()) {
        objective.gradient(at, g);
      } else {
        g.setZero(at.size());
        terms[t]->add_gradient(at, g);
      }
      return g;
    };
    const VecX g = grad(x);
    std::vector<double> change;
    for (const VecX& xp : moved) change.push_back((grad(xp) - g).norm());
    std::sort(change.begin(), change.end());
    rows.push_back({t == terms.size() ? std::string("total") : terms[t]->name(), g.norm(),
                    change[change.size() / 2], change.back()});
  }
  return rows;
}

bool at_roundoff_floor(const Objective& objective, const VecX& x, double grad_norm, double* floor) {
  const auto rows = gradient_roundoff(objective, x, 4);
  const double f = rows.back().change_max;
  if (floor) *floor = f;
  return grad_norm <= kRoundoffFloorFactor * f;
}

}  // namespace mgcloth::physics
