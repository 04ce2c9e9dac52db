#pragma once
#include <mgcloth/physics/term.hpp>

#include <vector>

namespace mgcloth::physics {

/// One sample of a linear functional of the control points, p(q) = Σ_k w_k q_{points[k]} (a limit-surface point or
/// derivative, or a control point itself), with a quadratic penalty towards a target and a linear load:
/// E_s(q) = c/2 |p(q) − b|² − f · p(q).
struct ShellSample {
  std::vector<Index> points;
  std::vector<double> w;
  double c = 0.0;          ///< penalty weight (β times the quadrature weight of the sample)
  Vec3 b = Vec3::Zero();   ///< target of the penalty
  Vec3 f = Vec3::Zero();   ///< load (force times the quadrature weight)
};

/// Penalty boundary conditions and external loads on a subdivision shell, as a sum of samples (each term of the
/// quadrature of a boundary or surface integral is one sample): the boundary penalty of Kopaničáková 2019,
/// eq. (3.6), β/2 ∫_∂ω |x − b|² ds (and the same on the cross-boundary derivative for clamped edges), point and
/// control-point penalties, point forces, edge forces per length, and pressure. Quadratic in q: the Hessian is
/// constant and positive semi-definite.
class ShellSampleTerm : public Term {
 public:
  explicit ShellSampleTerm(Index num_points) : m_num_points(num_points) {}

  std::string name() const override { return "shell_boundary_loads"; }
  /// Adds a sample; returns its index. Every point index must be in range.
  Index add(ShellSample sample);
  Index num_samples() const { return static_cast<Index>(m_samples.size()); }
  const ShellSample& sample(Index s) const { return m_samples[static_cast<size_t>(s)]; }
  void set_target(Index s, const Vec3& b) { m_samples[static_cast<size_t>(s)].b = b; }
  void set_load(Index s, const Vec3& f) { m_samples[static_cast<size_t>(s)].f = f; }
  /// p(q) of sample s.
  Vec3 evaluate(Index s, const VecX& q) const;

  double value(const VecX& x) const override;
  void add_gradient(const VecX& x, VecX& g) const override;
  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const override;
  void collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const override;
  void bind(const linalg::BlockMatrix3& pattern) override;

 private:
  Index m_num_points;
  std::vector<ShellSample> m_samples;
  std::vector<Index> m_slot_offsets{0};
  std::vector<Index> m_slots;
};

}  // namespace mgcloth::physics
