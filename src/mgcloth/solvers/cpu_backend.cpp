#include <mgcloth/core/error.hpp>
#include <mgcloth/solvers/cpu_backend.hpp>

#include <cmath>

namespace mgcloth::solvers {

double CpuVectors::energy_magnitude(Vec x) {
  double magnitude = 0.0;
  for (const auto& [name, value] : m_obj.term_values((*this)[x])) magnitude += std::abs(value);
  return magnitude;
}

bool CpuVectors::at_roundoff_floor(Vec x, double gnorm, double* floor) {
  return physics::at_roundoff_floor(m_obj, (*this)[x], gnorm, floor);
}

void CpuVectors::combine(Vec out, double a, Vec u, double b, Vec w) {
  VecX& o = (*this)[out];
  const VecX &U = (*this)[u], &W = (*this)[w];
  // x + α p is the common case (line-search trials): written so that it rounds as that expression.
  if (a == 1.0) o = U + b * W;
  else o = a * U + b * W;
}

void CpuVectors::weight(Vec out, double omega, Vec u, Vec prev) {
  (*this)[out] = omega * ((*this)[u] - (*this)[prev]) + (*this)[prev];
}

void CpuVectors::multiply(Vec in, Vec out) {
  if (!m_model) throw_error("multiply: this solve has no model matrix");
  m_model->multiply((*this)[in], (*this)[out]);
}

}  // namespace mgcloth::solvers
