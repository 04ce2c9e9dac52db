#pragma once
#include <mgcloth/core/types.hpp>
#include <mgcloth/linalg/block_matrix.hpp>
#include <mgcloth/physics/device_data.hpp>

#include <string>
#include <utility>
#include <vector>

namespace mgcloth::physics {

/// One additive term of the per-step objective (ARCHITECTURE.md). Elements are small stencils of vertices.
class Term {
 public:
  virtual ~Term() = default;
  virtual std::string name() const = 0;
  virtual double value(const VecX& x) const = 0;
  virtual void add_gradient(const VecX& x, VecX& g) const = 0;
  /// value(x), with the gradient added into g: one pass over the elements where a term can fuse them. The value and
  /// g must be bitwise those of value() and add_gradient(), so that a solver may use either.
  virtual double value_and_gradient(const VecX& x, VecX& g) const {
    add_gradient(x, g);
    return value(x);
  }
  /// Adds this term's Hessian into H (whose pattern contains this term's stencils); each element block is
  /// projected to be positive semi-definite when asked.
  virtual void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const = 0;
  /// Whether add_hessian adds the same values at every x (with either project_psd): the quadratic bending models.
  /// The objective then assembles this term's share once per pattern (Objective::hessian_reusing_constant).
  virtual bool hessian_is_constant() const { return false; }
  /// The (row, col) vertex pairs this term couples, for building the Hessian pattern once.
  virtual void collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const = 0;
  /// Called once the global pattern exists (and again whenever it is rebuilt), so that scatter maps are computed
  /// once per pattern, not per assembly.
  virtual void bind(const linalg::BlockMatrix3& /*pattern*/) {}
  /// Terms whose stencils follow the iterate (contact pairs that appear and disappear) update them here; called by
  /// Objective::hessian before each assembly. Returns true when the stencils changed, after which collect_pattern
  /// gives the new ones and the objective rebuilds its pattern. The value and gradient must not depend on the
  /// stencils chosen (a pair outside them contributes nothing there). Most terms' stencils are fixed.
  virtual bool update_stencils(const VecX& /*x*/) { return false; }
  /// The largest α in [0, alpha_max] such that the whole motion x + [0, α]·d stays where this term's energy is
  /// finite (cloth contact: no pair reaches zero distance, by continuous collision detection). Solvers limit every
  /// trial point with it, so that no step jumps over an infinite wall. Terms that are finite everywhere do not limit.
  virtual double max_step(const VecX& /*x*/, const VecX& /*d*/, double alpha_max) const { return alpha_max; }
  /// Whether max_step() can ever return less than alpha_max.
  virtual bool limits_steps() const { return false; }
  /// Terms with a device implementation write their data for the device pipeline here and return true; false: the
  /// pipeline cannot evaluate this term (it then refuses the objective, naming the term).
  virtual bool describe_device(DeviceObjective& /*out*/) const { return false; }
  /// Per time step, the data of describe_device() that changes (prediction, targets, obstacle poses).
  virtual void describe_device_step(DeviceStep& /*out*/) const {}
};

}  // namespace mgcloth::physics
