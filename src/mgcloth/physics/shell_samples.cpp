#include <mgcloth/core/error.hpp>
#include <mgcloth/physics/shell_samples.hpp>

namespace mgcloth::physics {

Index ShellSampleTerm::add(ShellSample sample) {
  if (sample.points.size() != sample.w.size() || sample.points.empty())
    throw_error("ShellSampleTerm::add: {} points and {} weights", sample.points.size(), sample.w.size());
  for (Index p : sample.points)
    if (p < 0 || p >= m_num_points) throw_error("ShellSampleTerm::add: control point {} out of range ({})", p, m_num_points);
  if (!(sample.c >= 0.0) || !std::isfinite(sample.c)) throw_error("ShellSampleTerm::add: penalty weight {}", sample.c);
  m_samples.push_back(std::move(sample));
  return num_samples() - 1;
}

Vec3 ShellSampleTerm::evaluate(Index s, const VecX& q) const {
  const ShellSample& S = m_samples[static_cast<size_t>(s)];
  Vec3 p = Vec3::Zero();
  for (size_t k = 0; k < S.points.size(); ++k) p += S.w[k] * q.segment<3>(3 * S.points[k]);
  return p;
}

double ShellSampleTerm::value(const VecX& x) const {
  double e = 0.0;
  for (Index s = 0; s < num_samples(); ++s) {
    const ShellSample& S = m_samples[static_cast<size_t>(s)];
    const Vec3 p = evaluate(s, x);
    e += 0.5 * S.c * (p - S.b).squaredNorm() - S.f.dot(p);
  }
  return e;
}

void ShellSampleTerm::add_gradient(const VecX& x, VecX& g) const {
  for (Index s = 0; s < num_samples(); ++s) {
    const ShellSample& S = m_samples[static_cast<size_t>(s)];
    const Vec3 dp = S.c * (evaluate(s, x) - S.b) - S.f;
    for (size_t k = 0; k < S.points.size(); ++k) g.segment<3>(3 * S.points[k]) += S.w[k] * dp;
  }
}

void ShellSampleTerm::add_hessian(const VecX&, linalg::BlockMatrix3& H, bool) const {
  for (Index s = 0; s < num_samples(); ++s) {
    const ShellSample& S = m_samples[static_cast<size_t>(s)];
    if (S.c == 0.0) continue;
    const size_t K = S.points.size();
    const Index* slots = &m_slots[m_slot_offsets[s]];
    for (size_t a = 0; a < K; ++a)
      for (size_t b = 0; b < K; ++b) H.block(slots[a * K + b]).diagonal().array() += S.c * S.w[a] * S.w[b];
  }
}

void ShellSampleTerm::collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const {
  for (const auto& S : m_samples) {
    if (S.c == 0.0) continue;
    for (Index a : S.points)
      for (Index b : S.points)
        if (a <= b) pairs.emplace_back(a, b);
  }
}

void ShellSampleTerm::bind(const linalg::BlockMatrix3& pattern) {
  m_slot_offsets.assign(1, 0);
  m_slots.clear();
  for (const auto& S : m_samples) {
    if (S.c != 0.0)
      for (Index a : S.points)
        for (Index b : S.points) m_slots.push_back(pattern.find(a, b));
    m_slot_offsets.push_back(static_cast<Index>(m_slots.size()));
  }
}

}  // namespace mgcloth::physics
