#pragma once
#include <mgcloth/physics/objective.hpp>

#include <string>

namespace mgcloth::physics {

/// Another objective as one term of a larger one: its points are points offset .. offset + n − 1 of the larger
/// objective's unknown. This is how the objective of a step over several bodies is the sum of the bodies' own
/// objectives (each body keeps and updates its terms in its own numbering) plus the terms that couple bodies, which
/// are written in the joint numbering. The Hessian pattern is the body's, shifted: a block-diagonal part of the
/// joint pattern. The sub-objective must be finalized and outlive this term.
class SubObjectiveTerm final : public Term {
 public:
  bool describe_device(DeviceObjective& out) const override;
  SubObjectiveTerm(std::string name, const Objective& objective, Index offset)
      : m_name(std::move(name)), m_objective(&objective), m_offset(offset) {}

  std::string name() const override { return m_name; }
  const Objective& objective() const { return *m_objective; }
  Index offset() const { return m_offset; }

  double value(const VecX& x) const override;
  void add_gradient(const VecX& x, VecX& g) const override;
  double value_and_gradient(const VecX& x, VecX& g) const override;
  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const override;
  void collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const override;
  void bind(const linalg::BlockMatrix3& pattern) override;
  /// The sub-objective's stencils at its part of x: when its pattern changes, so does the joint one.
  bool update_stencils(const VecX& x) override { return m_objective->update_stencils(local(x)); }
  double max_step(const VecX& x, const VecX& d, double alpha_max) const override {
    return m_objective->max_step(local(x), local(d), alpha_max);
  }
  bool limits_steps() const override { return m_objective->limits_steps(); }

 private:
  VecX local(const VecX& x) const { return x.segment(3 * m_offset, m_objective->num_dofs()); }

  std::string m_name;
  const Objective* m_objective;
  Index m_offset;
  std::vector<Index> m_slots;  ///< joint-pattern position of each block of the sub-objective's pattern
  mutable linalg::BlockMatrix3 m_local;  ///< the sub-objective's Hessian, assembled then scattered
};

}  // namespace mgcloth::physics
