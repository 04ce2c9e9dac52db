#include <mgcloth/core/error.hpp>
#include <mgcloth/physics/seam.hpp>

#include <cmath>

namespace mgcloth::physics {

SeamTerm::SeamTerm(const std::vector<std::vector<Index>>& groups, double stiffness, Index n) : m_stiffness(stiffness) {
  if (!(stiffness > 0.0) || !std::isfinite(stiffness)) throw_input_error("seam stiffness must be positive (got {})", stiffness);
  std::vector<Element> els;
  for (size_t g = 0; g < groups.size(); ++g)
    for (size_t k = 1; k < groups[g].size(); ++k) {
      const Index a = groups[g][0], b = groups[g][k];
      if (a < 0 || b < 0 || a >= n || b >= n || a == b)
        throw_input_error("seam group {}: bad vertex pair ({}, {}) for {} vertices", g, a, b, n);
      els.push_back({a, b});
    }
  set_elements(std::move(els), n);
}

double SeamTerm::element(Index, const Local& xe, Local* g, LocalHessian* H) const {
  const Vec3 d = xe.head<3>() - xe.tail<3>();
  const double k = m_stiffness;
  if (g) *g << k * d, -k * d;
  if (H) {
    H->setZero();
    for (int i = 0; i < 3; ++i) {
      (*H)(i, i) = (*H)(i + 3, i + 3) = k;
      (*H)(i, i + 3) = (*H)(i + 3, i) = -k;
    }
  }
  return 0.5 * k * d.squaredNorm();
}

}  // namespace mgcloth::physics
