#pragma once
#include <mgcloth/physics/term.hpp>

#include <memory>

namespace mgcloth::physics {

/// E(x) = Σ terms: the incremental potential of one implicit-Euler step (Wang 2018, eq. 2) when the terms are
/// inertia, gravity, elasticity, attachments and contact. The Hessian pattern is built once, at finalize().
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
  /// Assembles into H, which must have this objective's pattern (see hessian_pattern()).
  void hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd = true) const;
  /// An empty matrix with the pattern, to be filled by hessian().
  const linalg::BlockMatrix3& hessian_pattern() const;
  /// Values of each term, for diagnostics and statistics.
  std::vector<std::pair<std::string, double>> term_values(const VecX& x) const;

 private:
  void require_finalized() const;

  Index m_n;
  std::vector<std::unique_ptr<Term>> m_terms;
  linalg::BlockMatrix3 m_pattern;
  bool m_finalized = false;
};

}  // namespace mgcloth::physics
