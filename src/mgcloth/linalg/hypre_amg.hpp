#pragma once
#include <mgcloth/linalg/block_matrix.hpp>

#include <memory>

namespace mgcloth::linalg {

/// BoomerAMG options for the 3x3-block systems of cloth (3 unknowns per vertex, interleaved xyz). The defaults
/// gave the lowest setup + PCG time to a 1e-6 relative residual on projected cloth Hessians (StVK membrane, hinge
/// bending, inertia at Δt = 1/30 s; 10K and 40K vertices): nodal coarsening on block sums of |a|, θ = 0.5, HMIS
/// with one aggressive level, extended+i interpolation with 4 weights, one forward/backward l1-GS sweep. The
/// aggressive level doubles the iterations but halves the setup and makes each V-cycle cheaper; both cloth sizes
/// came out ahead. bench/RESULTS.md has the measurements.
struct HypreAmgParams {
  enum class Coarsening { HMIS = 10, PMIS = 8 };
  /// Smoothers that keep the V-cycle symmetric, as PCG needs (hypre relax types in parentheses).
  enum class Smoother {
    ForwardBackwardGS,    ///< l1 Gauss-Seidel forward on the way down (13), backward on the way up (14)
    SymmetricGS,          ///< hybrid symmetric Gauss-Seidel both ways (6)
    L1SymmetricGS,        ///< l1-scaled hybrid symmetric Gauss-Seidel both ways (8)
    L1Jacobi,             ///< l1-scaled Jacobi (18)
  };

  /// Systems AMG: 0 coarsens each of x, y, z on its own (unknown approach, num_functions = 3); k > 0 coarsens
  /// vertices, with the strength of a 3x3 block measured by a norm (1 Frobenius, 2 sum of |a|, 3 largest entry, 4
  /// row sum, 6 sum of entries) — hypre's nodal coarsening.
  int nodal = 2;
  /// θ: a_ij is a strong connection when −a_ij >= θ max_k(−a_ik) (with nodal > 0, on the block norms). 0.25 suits
  /// 2D Laplacians; 0.5-0.9 is common for 3D elasticity.
  double strong_threshold = 0.5;
  Coarsening coarsening = Coarsening::HMIS;
  /// Levels (from the finest) coarsened aggressively: cheaper setup and cycles, slower convergence. 0 = off.
  int aggressive_levels = 1;
  /// Interpolation (hypre numbering): 6 = extended+i, truncated to at most `p_max_elements` weights per row.
  int interp_type = 6;
  int p_max_elements = 4;
  Smoother smoother = Smoother::ForwardBackwardGS;
  int sweeps = 1;  ///< smoothing sweeps per level on each of the down and up legs
  int max_levels = 25;
  int print_level = 0;  ///< > 0 makes hypre print its setup statistics to stdout (diagnostics only)
};

/// BoomerAMG (hypre's parallel algebraic multigrid) as a preconditioner for SPD BlockMatrix3 systems: one V-cycle
/// from zero per application, a fixed symmetric positive definite operator when the smoother is symmetric
/// (every HypreAmgParams::Smoother is). The baseline that geometric multigrid is compared against.
/// Runs on one process (MPI_COMM_SELF); hypre's MPI is started on first use when the program has not done so.
class HypreAmg {
 public:
  explicit HypreAmg(HypreAmgParams params = {});
  ~HypreAmg();
  HypreAmg(const HypreAmg&) = delete;
  HypreAmg& operator=(const HypreAmg&) = delete;

  /// Copies A into hypre's CSR form and runs the BoomerAMG setup (coarsening, interpolation, Galerkin products).
  /// Throws SolveError for a non-positive diagonal entry (naming its row) or a failed setup.
  void set_matrix(const BlockMatrix3& A);
  /// z = M⁻¹ r: one V-cycle for A z = r from z = 0. Not thread-safe (uses the object's hypre vectors).
  void apply(const VecX& r, VecX& z) const;

  const HypreAmgParams& params() const { return m_params; }
  /// Wall time of the last set_matrix(): copying the matrix into hypre, and the BoomerAMG setup.
  double copy_seconds() const { return m_copy_seconds; }
  double setup_seconds() const { return m_setup_seconds; }

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
  HypreAmgParams m_params;
  double m_copy_seconds = 0.0;
  double m_setup_seconds = 0.0;
};

}  // namespace mgcloth::linalg
