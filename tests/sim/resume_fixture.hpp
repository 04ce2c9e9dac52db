// A simulator resumed from another's state, as `mgcloth run --resume` restores it from checkpoint.bin.
#pragma once
#include <mgcloth/sim/simulator.hpp>

#include <memory>
#include <vector>

namespace mgcloth::sim::fixtures {

/// A fresh simulator of `scene` at `from`'s frame, step count, positions, velocities and solver states.
inline std::unique_ptr<Simulator> resumed_from(const Scene& scene, const Simulator& from) {
  std::vector<VecX> x, v;
  for (const auto& b : from.bodies()) {
    x.push_back(b->x());
    v.push_back(b->v());
  }
  auto out = std::make_unique<Simulator>(scene);
  out->set_state(from.frame(), from.step_count(), x, v);
  for (size_t b = 0; b < from.bodies().size(); ++b) out->set_solver_state(b, from.solver_state(b));
  return out;
}

}  // namespace mgcloth::sim::fixtures
