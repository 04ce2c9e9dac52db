#pragma once
#include <mgcloth/sim/simulator.hpp>

namespace mgcloth::sim {

/// Checks, once the bodies are built and before a step or an output, that the scene's solver can work on every
/// body. Today one rule: `rmtr` and `fas` need a hierarchy of at least two levels on every body, i.e. (rmtr) a shell
/// of level 2 or more, and a cloth of more than hierarchy.max_coarse_vertices vertices (coarsening stops at a level
/// that has at most that many). Otherwise InputError "<scene>: …" naming the body, what it has and what would fit;
/// without this check the first step failed after frame 0 was written, blaming "a shell of level 1" also for cloths
/// (rmtr) or naming missing "coarse objectives" (fas).
void check_solver_fits(const Simulator& sim);

}  // namespace mgcloth::sim
