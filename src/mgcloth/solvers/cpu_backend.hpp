#pragma once
#include <mgcloth/linalg/block_matrix.hpp>
#include <mgcloth/solvers/fmg_cycle.hpp>

#include <array>
#include <functional>

namespace mgcloth::solvers {

/// The FMG backend's vectors and objective on the CPU: VecX in memory, the objective's own energy and gradient,
/// the problem's projection, and A_0 products with a matrix the owner keeps (`model`, may be null: no model).
/// The multigrid half (update_matrix, correction, newton_step, counters) is the owner's (NonlinearFMG).
class CpuVectors : public FmgBackend {
 public:
  CpuVectors(const physics::Objective& objective, std::function<Index(VecX&)> project,
             const linalg::BlockMatrix3* model)
      : m_obj(objective), m_project(std::move(project)), m_model(model) {}
  VecX& operator[](Vec v) { return m_v[static_cast<size_t>(v)]; }

  double energy(Vec x) override { return m_obj.value((*this)[x]); }
  void gradient(Vec x, Vec g) override { m_obj.gradient((*this)[x], (*this)[g]); }
  double energy_and_gradient(Vec x, Vec g) override { return m_obj.value_and_gradient((*this)[x], (*this)[g]); }
  bool has_projection() const override { return static_cast<bool>(m_project); }
  Index project(Vec x) override { return m_project ? m_project((*this)[x]) : 0; }
  double max_step(Vec x, Vec d, double alpha_max) override { return m_obj.max_step((*this)[x], (*this)[d], alpha_max); }
  bool limits_steps() const override { return m_obj.limits_steps(); }
  double energy_magnitude(Vec x) override;
  bool at_roundoff_floor(Vec x, double gnorm, double* floor) override;
  double dot(Vec a, Vec b) override { return (*this)[a].dot((*this)[b]); }
  double norm(Vec a) override { return (*this)[a].norm(); }
  void combine(Vec out, double a, Vec u, double b, Vec w) override;
  void scale(Vec out, double a, Vec u) override { (*this)[out] = a * (*this)[u]; }
  void weight(Vec out, double omega, Vec u, Vec prev) override;
  void copy(Vec to, Vec from) override { (*this)[to] = (*this)[from]; }
  void take(Vec to, Vec from) override { (*this)[to].swap((*this)[from]); }
  void multiply(Vec in, Vec out) override;
  void mark(Vec x) override { m_mark = (*this)[x]; }
  double max_distance_from_mark(Vec x) override { return max_vertex_distance((*this)[x], m_mark); }

 protected:
  const physics::Objective& m_obj;
  std::function<Index(VecX&)> m_project;
  const linalg::BlockMatrix3* m_model;
  std::array<VecX, NumVecs> m_v;
  VecX m_mark;
};

}  // namespace mgcloth::solvers
