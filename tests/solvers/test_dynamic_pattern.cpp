// A Hessian pattern that changes between iterations (issue 27, deliverable 3): a term whose stencils follow the
// iterate, as contact pairs will. The objective rebuilds its pattern only when a term's stencils changed; the
// multigrid hierarchy, colorings and factorizations follow; every solver still reaches the minimizer it reaches
// with the same energy on a fixed pattern.
#include "solvers/hanging_fixture.hpp"

#include <mgcloth/core/json.hpp>
#include <mgcloth/solvers/factory.hpp>
#include <mgcloth/solvers/linear_multigrid.hpp>

#include <gtest/gtest.h>

using namespace mgcloth;

namespace {

/// Springs between vertex pairs that pull only once a pair is farther apart than its length L:
/// E = k/2 Σ max(0, d − L)², d = |x_i − x_j| (C¹). With `dynamic` the stencils are the stretched pairs only, found
/// again before every assembly; otherwise every pair is always in the pattern. Both give the same energy.
class Tethers final : public physics::Term {
 public:
  Tethers(std::vector<std::array<Index, 2>> pairs, std::vector<double> length, double k, bool dynamic)
      : m_pairs(std::move(pairs)), m_length(std::move(length)), m_k(k), m_dynamic(dynamic) {
    if (!dynamic)
      for (size_t p = 0; p < m_pairs.size(); ++p) m_active.push_back(p);
  }
  std::string name() const override { return "tethers"; }
  double value(const VecX& x) const override {
    double e = 0.0;
    for (size_t p = 0; p < m_pairs.size(); ++p) {
      const double s = std::max(0.0, stretch(x, p));
      e += 0.5 * m_k * s * s;
    }
    return e;
  }
  void add_gradient(const VecX& x, VecX& g) const override {
    for (size_t p = 0; p < m_pairs.size(); ++p) {
      const double s = stretch(x, p);
      if (s <= 0.0) continue;
      const Vec3 f = m_k * s * direction(x, p);
      g.segment<3>(3 * m_pairs[p][0]) += f;
      g.segment<3>(3 * m_pairs[p][1]) -= f;
    }
  }
  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool) const override {
    for (size_t a = 0; a < m_active.size(); ++a) {
      const size_t p = m_active[a];
      const double s = stretch(x, p);
      if (s <= 0.0) continue;
      const Vec3 n = direction(x, p);
      const double d = s + m_length[p];
      const Mat3 K = m_k * (n * n.transpose() + (s / d) * (Mat3::Identity() - n * n.transpose()));
      H.block(m_slots[4 * a]) += K;
      H.block(m_slots[4 * a + 1]) -= K;
      H.block(m_slots[4 * a + 2]) -= K;
      H.block(m_slots[4 * a + 3]) += K;
    }
  }
  void collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const override {
    for (size_t p : m_active) pairs.emplace_back(std::min(m_pairs[p][0], m_pairs[p][1]), std::max(m_pairs[p][0], m_pairs[p][1]));
  }
  void bind(const linalg::BlockMatrix3& pattern) override {
    m_slots.clear();
    for (size_t p : m_active) {
      const Index i = m_pairs[p][0], j = m_pairs[p][1];
      for (auto [r, c] : {std::pair{i, i}, std::pair{i, j}, std::pair{j, i}, std::pair{j, j}}) m_slots.push_back(pattern.find(r, c));
    }
  }
  bool update_stencils(const VecX& x) override {
    if (!m_dynamic) return false;
    std::vector<size_t> active;
    for (size_t p = 0; p < m_pairs.size(); ++p)
      if (stretch(x, p) > 0.0) active.push_back(p);
    if (active == m_active) return false;
    m_active = std::move(active);
    ++updates;
    return true;
  }
  int updates = 0;

 private:
  double stretch(const VecX& x, size_t p) const {
    return (x.segment<3>(3 * m_pairs[p][0]) - x.segment<3>(3 * m_pairs[p][1])).norm() - m_length[p];
  }
  Vec3 direction(const VecX& x, size_t p) const {
    return (x.segment<3>(3 * m_pairs[p][0]) - x.segment<3>(3 * m_pairs[p][1])).normalized();
  }

  std::vector<std::array<Index, 2>> m_pairs;
  std::vector<double> m_length;
  double m_k;
  bool m_dynamic;
  std::vector<size_t> m_active;
  std::vector<Index> m_slots;
};

/// The hanging cloth (static: it stretches under its weight) with tethers from top-row vertices to the vertices
/// farthest below them, each exactly as long as the pair is at the start: no tether pulls at x0, they engage
/// as the cloth stretches, so their stencils appear during the solve.
struct Tethered {
  std::unique_ptr<test::Hanging> cloth;
  Tethers* tethers = nullptr;
};
Tethered tethered(bool dynamic) {
  Tethered t;
  t.cloth = test::hanging(400, 0.0, physics::BendingModel::Quadratic);
  const auto& u = t.cloth->mesh.u;
  std::vector<std::array<Index, 2>> pairs;
  std::vector<double> length;
  for (double s : {0.1, 0.2, 0.3}) {
    Index top = 0, bottom = 0;
    (u.colwise() - Vec2(s, 0.0)).colwise().squaredNorm().minCoeff(&top);
    (u.colwise() - Vec2(s, 0.4)).colwise().squaredNorm().minCoeff(&bottom);
    pairs.push_back({top, bottom});
    length.push_back((t.cloth->x0.segment<3>(3 * top) - t.cloth->x0.segment<3>(3 * bottom)).norm());
  }
  t.tethers = &t.cloth->objective.add(std::make_unique<Tethers>(pairs, length, 50.0, dynamic));
  t.cloth->objective.finalize();
  return t;
}

std::unique_ptr<solvers::NonlinearSolver> solver(const std::string& name) {
  solvers::SolverConfig c;
  c.name = name;
  return solvers::make_solver(c, "test", "solver.params");
}

}  // namespace

TEST(DynamicPattern, TheObjectiveRebuildsItsPatternOnlyWhenAStencilChanged) {
  Tethered t = tethered(true);
  const physics::Objective& E = t.cloth->objective;
  const long v0 = E.pattern_version();
  const Index blocks0 = E.hessian_pattern().num_blocks();
  linalg::BlockMatrix3 H;
  E.hessian(t.cloth->x0, H, true);
  EXPECT_EQ(E.pattern_version(), v0) << "nothing is stretched at the start";
  // Pull the bottom row down by 1 cm: every tether engages, its blocks appear.
  VecX x = t.cloth->x0;
  for (Index i = 0; i < x.size() / 3; ++i) x[3 * i + 2] -= 0.025 * t.cloth->mesh.u(1, i);
  E.hessian(x, H, true);
  EXPECT_EQ(E.pattern_version(), v0 + 1);
  EXPECT_EQ(H.num_blocks(), blocks0 + 3 * 2) << "three tethers, two off-diagonal blocks each";
  E.hessian(x, H, true);
  EXPECT_EQ(E.pattern_version(), v0 + 1) << "the same stencils: no rebuild";
  // The Hessian with the new stencils is the one of the fixed-pattern twin.
  Tethered fixed = tethered(false);
  linalg::BlockMatrix3 Hf;
  fixed.cloth->objective.hessian(x, Hf, true);
  EXPECT_LT((H.to_sparse() - Hf.to_sparse()).norm(), 1e-12 * Hf.to_sparse().norm());
  E.hessian(t.cloth->x0, H, true);
  EXPECT_EQ(E.pattern_version(), v0 + 2) << "back at rest the tethers' blocks disappear";
  EXPECT_EQ(H.num_blocks(), blocks0);
}

TEST(DynamicPattern, TheMultigridHierarchyIsRebuiltOnlyForANewPattern) {
  Tethered t = tethered(true);
  const physics::Objective& E = t.cloth->objective;
  const auto h = test::small_hierarchy(*t.cloth);
  solvers::LinearMultigrid mg(h.levels_for_solvers().prolongations(), E.hessian_pattern());
  linalg::BlockMatrix3 H;
  E.hessian(t.cloth->x0, H, true);
  mg.set_matrix(H);
  EXPECT_EQ(mg.symbolic_builds(), 1);
  VecX x = t.cloth->x0;
  for (Index i = 0; i < x.size() / 3; ++i) x[3 * i + 2] -= 0.025 * t.cloth->mesh.u(1, i);
  E.hessian(x, H, true);
  mg.set_matrix(H);
  EXPECT_EQ(mg.symbolic_builds(), 2);
  mg.set_matrix(H);
  EXPECT_EQ(mg.symbolic_builds(), 2);
  // The rebuilt hierarchy is the one built afresh for the new pattern: the same V-cycles, and they converge.
  solvers::LinearMultigrid fresh(h.levels_for_solvers().prolongations(), H);
  fresh.set_matrix(H);
  const VecX b = VecX::Ones(H.rows() * 3);
  VecX y = VecX::Zero(b.size()), z = y;
  for (int k = 0; k < 30; ++k) {
    mg.vcycle(b, y);
    fresh.vcycle(b, z);
  }
  EXPECT_EQ(y, z);
  EXPECT_LT((b - H * y).norm(), 1e-5 * b.norm());
}

TEST(DynamicPattern, EverySolverReachesTheFixedPatternMinimizer) {
  solvers::Stop stop;
  stop.rel_grad = 1e-9;
  stop.max_iters = 2000;
  Tethered ref = tethered(false);
  VecX xstar = ref.cloth->x0;
  solvers::Problem rp;
  rp.objective = &ref.cloth->objective;
  ASSERT_TRUE(solver("newton-direct")->minimize(rp, xstar, stop, nullptr).converged);
  for (const std::string name : {"newton-direct", "newton-mg", "fmg"}) {
    Tethered t = tethered(true);
    const auto h = test::small_hierarchy(*t.cloth);
    auto s = solver(name);
    solvers::Problem p;
    p.objective = &t.cloth->objective;
    if (s->needs_hierarchy()) p.hierarchy = h.levels_for_solvers();
    VecX x = t.cloth->x0;
    const auto rep = s->minimize(p, x, stop, nullptr);
    EXPECT_TRUE(rep.converged) << name << ": " << rep.status << " at " << rep.grad_norm / rep.initial_grad_norm;
    EXPECT_GT(t.tethers->updates, 0) << name << ": the stencils never changed, the test would be vacuous";
    EXPECT_LT((x - xstar).norm(), 1e-6 * xstar.norm()) << name;
  }
}
