#include <mgcloth/sim/solver_fit.hpp>

namespace mgcloth::sim {

void check_solver_fits(const Simulator& sim) {
  const Scene& s = sim.scene();
  // Both solve coarse levels of their own (rediscretized objectives), which a one-level hierarchy does not have.
  const bool multilevel = s.solver.name == "rmtr" || s.solver.name == "fas";
  if (!multilevel) return;
  for (size_t i = 0; s.solver.name == "rmtr" && i < sim.shells().size(); ++i) {
    const ShellBody& shell = *sim.shells()[i];
    if (shell.num_levels() < 2)
      throw_input_error("{}: shells[{}] (\"{}\"): solver rmtr needs at least two levels, the shell is subdivided to "
                        "level {}: raise shells[].level (or --level) to 2 or more, or use tr-dogleg on one level",
                        s.file, i, shell.name(), shell.num_levels());
  }
  for (size_t i = 0; i < sim.cloths().size(); ++i) {
    const ClothBody& cloth = *sim.cloths()[i];
    const Index n = cloth.mesh().num_vertices();
    if (n <= s.hierarchy.max_coarse_vertices)
      throw_input_error("{}: cloths[{}] (\"{}\"): solver {} needs a mesh hierarchy of at least two levels, but the "
                        "cloth's {} vertices are at most hierarchy.max_coarse_vertices ({}), so it has one level: "
                        "use more vertices or a smaller max_coarse_vertices, or a solver that works on one level "
                        "(fmg, newton-direct, tr-dogleg, ...)",
                        s.file, i, cloth.name(), s.solver.name, n, s.hierarchy.max_coarse_vertices);
  }
}

}  // namespace mgcloth::sim
