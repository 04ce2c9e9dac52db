#pragma once
#include <mgcloth/physics/term.hpp>

#include <memory>

namespace mgcloth::physics {

/// E(x) = Σ terms: the incremental potential of one implicit-Euler step (Wang 2018, eq. 2) when the terms are
/// inertia, gravity, elasticity, attachments and contact. The Hessian pattern is built at finalize() and rebuilt
/// only when a term's stencils change (Term::update_stencils, asked before every Hessian assembly); its version
/// tells the users of the pattern (multigrid hierarchies, factorizations, colorings) when to rebuild what they
/// derived from it.
class Objective {
 public:
  explicit Objective(Index num_vertices) : m_n(num_vertices) {}

  template <class T>
  T& add(std::unique_ptr<T> term) {
    T& ref = *term;
    m_terms.push_back(std::move(term));
    m_finalized = false;
    return ref;
  }
  /// Builds the Hessian pattern from every term's stencils and lets terms precompute their scatter maps.
  void finalize();

  Index num_vertices() const { return m_n; }
  Index num_dofs() const { return 3 * m_n; }
  const std::vector<std::unique_ptr<Term>>& terms() const { return m_terms; }

  double value(const VecX& x) const;
  void gradient(const VecX& x, VecX& g) const;
  /// value(x) and gradient(x, g) in one pass where the terms can fuse them; bitwise the same results.
  double value_and_gradient(const VecX& x, VecX& g) const;
  /// Assembles into H (given this objective's pattern first if it has another one). Asks the terms to update
  /// their stencils at x first (update_stencils).
  void hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd = true) const;
  /// What hessian_reusing_constant() keeps per matrix: the constant terms' share of the blocks that other terms add
  /// to, and the pattern stamp and projection flag it was assembled for.
  struct ConstantHessian {
    long version = -1;
    bool project_psd = false;
    std::vector<Mat3> values;  ///< per variable block (variable_blocks())
  };
  /// As hessian(), for a matrix H that only hessian() and this function of this objective have written since the
  /// `cache`'s last use (one cache per matrix): terms whose Hessian is constant (Term::hessian_is_constant) are
  /// assembled once per pattern; afterwards the constant blocks keep their values and the variable blocks start
  /// from the cached constant share. Sums run in another order than hessian()'s: the two agree to round-off.
  void hessian_reusing_constant(const VecX& x, linalg::BlockMatrix3& H, bool project_psd, ConstantHessian& cache) const;
  /// Per block of the pattern: 1 where only terms with a constant Hessian add to it, so that its value is the same
  /// at every x (the quadratic bending model's couplings beyond the membrane's one-ring). All 0 when no term is
  /// constant. Valid for the current pattern_stamp().
  const std::vector<char>& constant_blocks() const { return m_constant_blocks; }
  /// The blocks that are not constant, ascending.
  const std::vector<Index>& variable_blocks() const { return m_variable_blocks; }
  /// Lets every term update its stencils at x; rebuilds the pattern (and rebinds the terms) when one changed.
  /// Returns whether the pattern changed. The pattern is a cache of the terms' stencils, hence const.
  bool update_stencils(const VecX& x) const;
  /// min over the terms of Term::max_step: the largest α <= alpha_max whose motion x + [0, α]·d every term admits.
  double max_step(const VecX& x, const VecX& d, double alpha_max = 1.0) const;
  /// Whether some term limits steps (max_step can return less than alpha_max): the solver must then use it on every
  /// trial point (docs/ARCHITECTURE.md).
  bool limits_steps() const;
  /// How many times the pattern was built (finalize() makes it 1); users of the pattern rebuild when it moves.
  long pattern_version() const { return m_pattern_version; }
  /// Unique over all objectives of the process and all their pattern builds: what caches of the constant blocks'
  /// values (which another objective with the same pattern would not share) are keyed by.
  long pattern_stamp() const { return m_pattern_stamp; }
  /// An empty matrix with the pattern, to be filled by hessian().
  const linalg::BlockMatrix3& hessian_pattern() const;
  /// Values of each term, for diagnostics and statistics.
  std::vector<std::pair<std::string, double>> term_values(const VecX& x) const;

 private:
  void require_finalized() const;

  void build_pattern() const;

  Index m_n;
  std::vector<std::unique_ptr<Term>> m_terms;
  mutable linalg::BlockMatrix3 m_pattern;
  mutable long m_pattern_version = 0;
  mutable long m_pattern_stamp = 0;
  mutable std::vector<char> m_constant_blocks;
  mutable std::vector<Index> m_variable_blocks;
  bool m_finalized = false;
};

/// One row of gradient_roundoff(): a term's (or, as "total", the whole objective's) gradient norm at x and the norm
/// of its change when x moves by at most one ulp per coordinate, the median and the largest over the draws.
struct GradientRoundoff {
  std::string term;
  double grad_norm = 0.0;
  double change_median = 0.0;
  double change_max = 0.0;
};

/// The round-off floor of ‖∇E‖ at x, the limiting accuracy of Kopaničáková 2019 §7.2: every coordinate of x moves
/// by −1, 0 or +1 ulp at random (`samples` draws from `seed`) and the gradient's change is measured, term by term
/// and in total (the last row). x is only known to an ulp, so no solver drives ‖∇E‖ below this change; a solve
/// stopped by (7.1)'s stagnation clause should stop near it. Throws Error for samples < 1 or a size mismatch.
std::vector<GradientRoundoff> gradient_roundoff(const Objective& objective, const VecX& x, int samples,
                                                unsigned seed = 1);

/// Whether a solve that can no longer decrease the energy has reached its limiting accuracy: ‖∇E(x)‖ within
/// kRoundoffFloorFactor times the gradient's round-off floor at x (gradient_roundoff, the largest change over a few
/// draws), where neither energy differences nor the gradient carry information. Costs a few gradient evaluations:
/// call it only once a solve is stuck. `floor` receives the floor. (Here rather than in solvers so that the device
/// pipeline, a module below solvers, uses the same test.)
inline constexpr double kRoundoffFloorFactor = 10.0;
bool at_roundoff_floor(const Objective& objective, const VecX& x, double grad_norm, double* floor = nullptr);

}  // namespace mgcloth::physics
