#include <mgcloth/core/error.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/solvers/factory.hpp>
#include <mgcloth/solvers/newton_variants.hpp>
#include <mgcloth/solvers/trust_region.hpp>

#include <Eigen/Dense>
#include <gtest/gtest.h>

using namespace mgcloth;

namespace {

/// A small nonconvex energy on a few vertices, each piece with closed-form derivatives:
///  - per-vertex 3D Rosenbrock 100(y − x²)² + (1 − x)² + 100(z − y²)² + (1 − y)² (minimum 0 at (1, 1, 1)),
///  - springs k/2 (|xᵢ − xⱼ| − L)² (indefinite Hessian when compressed, L > 0),
///  - anchors k/2 |xᵢ − a|², quartic wells c/4 |xᵢ − p|⁴, and a constant load bᵀx.
class TestEnergy final : public physics::Term {
 public:
  struct Spring { Index i, j; double rest, k; };
  struct Anchor { Index i; Vec3 a; double k; };
  struct Quartic { Index i; Vec3 p; double c; };
  std::vector<Index> rosenbrock;
  std::vector<Spring> springs;
  std::vector<Anchor> anchors;
  std::vector<Quartic> quartics;
  VecX load;

  std::string name() const override { return "test"; }

  double value(const VecX& x) const override {
    double e = load.size() ? load.dot(x) : 0.0;
    for (Index v : rosenbrock) {
      const Vec3 p = vertex(x, v);
      e += 100 * std::pow(p[1] - p[0] * p[0], 2) + std::pow(1 - p[0], 2) + 100 * std::pow(p[2] - p[1] * p[1], 2) +
           std::pow(1 - p[1], 2);
    }
    for (const auto& s : springs) e += 0.5 * s.k * std::pow((vertex(x, s.i) - vertex(x, s.j)).norm() - s.rest, 2);
    for (const auto& a : anchors) e += 0.5 * a.k * (vertex(x, a.i) - a.a).squaredNorm();
    for (const auto& q : quartics) e += 0.25 * q.c * std::pow((vertex(x, q.i) - q.p).squaredNorm(), 2);
    return e;
  }

  void add_gradient(const VecX& x, VecX& g) const override {
    if (load.size()) g += load;
    for (Index v : rosenbrock) {
      const Vec3 p = vertex(x, v);
      const double a = p[1] - p[0] * p[0], b = p[2] - p[1] * p[1];
      vertex(g, v) += Vec3(-400 * p[0] * a - 2 * (1 - p[0]), 200 * a - 400 * p[1] * b - 2 * (1 - p[1]), 200 * b);
    }
    for (const auto& s : springs) {
      const Vec3 d = vertex(x, s.i) - vertex(x, s.j);
      const double l = d.norm();
      const Vec3 f = s.k * (l - s.rest) / l * d;
      vertex(g, s.i) += f;
      vertex(g, s.j) -= f;
    }
    for (const auto& a : anchors) vertex(g, a.i) += a.k * (vertex(x, a.i) - a.a);
    for (const auto& q : quartics) {
      const Vec3 r = vertex(x, q.i) - q.p;
      vertex(g, q.i) += q.c * r.squaredNorm() * r;
    }
  }

  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool /*project_psd*/) const override {
    const auto add = [&](Index i, Index j, const Mat3& b) { H.block(H.find(i, j)) += b; };
    for (Index v : rosenbrock) {
      const Vec3 p = vertex(x, v);
      Mat3 h = Mat3::Zero();
      h(0, 0) = 1200 * p[0] * p[0] - 400 * p[1] + 2;
      h(0, 1) = h(1, 0) = -400 * p[0];
      h(1, 1) = 1200 * p[1] * p[1] - 400 * p[2] + 202;
      h(1, 2) = h(2, 1) = -400 * p[1];
      h(2, 2) = 200;
      add(v, v, h);
    }
    for (const auto& s : springs) {
      const Vec3 d = vertex(x, s.i) - vertex(x, s.j);
      const double l = d.norm();
      const Mat3 P = d * d.transpose() / (l * l);
      const Mat3 K = s.k * (P + (1 - s.rest / l) * (Mat3::Identity() - P));
      add(s.i, s.i, K);
      add(s.j, s.j, K);
      add(s.i, s.j, -K);
      add(s.j, s.i, -K);
    }
    for (const auto& a : anchors) add(a.i, a.i, a.k * Mat3::Identity());
    for (const auto& q : quartics) {
      const Vec3 r = vertex(x, q.i) - q.p;
      add(q.i, q.i, q.c * (r.squaredNorm() * Mat3::Identity() + 2 * r * r.transpose()));
    }
  }

  void collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const override {
    for (const auto& s : springs) pairs.emplace_back(s.i, s.j);
  }
};

struct TestProblem {
  std::unique_ptr<physics::Objective> objective;
  TestEnergy* energy = nullptr;
  VecX x0;
  solvers::Problem problem() const {
    solvers::Problem p;
    p.objective = objective.get();
    return p;
  }
};

TestProblem make_problem(Index n, const std::function<void(TestEnergy&)>& fill) {
  TestProblem t;
  t.objective = std::make_unique<physics::Objective>(n);
  t.energy = &t.objective->add(std::make_unique<TestEnergy>());
  fill(*t.energy);
  t.objective->finalize();
  return t;
}

/// Four vertices, each a 3D Rosenbrock valley, coupled by zero-length springs: the unique minimizer is all ones
/// (every piece is ≥ 0 and vanishes there). The start sits where the Rosenbrock Hessian is indefinite.
TestProblem rosenbrock_chain() {
  auto t = make_problem(4, [](TestEnergy& e) {
    e.rosenbrock = {0, 1, 2, 3};
    for (Index i = 0; i + 1 < 4; ++i) e.springs.push_back({i, i + 1, 0.0, 1.0});
  });
  t.x0.resize(12);
  for (Index i = 0; i < 4; ++i) vertex(t.x0, i) = Vec3(-0.1 * i, 1.0 + 0.2 * i, 0.3 - 0.1 * i);
  return t;
}

/// A chain of six unit-length springs hanging from an anchored vertex under a load, started compressed in a
/// zigzag: compressed springs have an indefinite Hessian.
TestProblem hanging_chain() {
  const Index n = 6;
  auto t = make_problem(n, [](TestEnergy& e) {
    for (Index i = 0; i + 1 < n; ++i) e.springs.push_back({i, i + 1, 1.0, 100.0});
    e.anchors.push_back({0, Vec3::Zero(), 1e4});
    e.load = VecX::Zero(3 * n);
    for (Index i = 1; i < n; ++i) e.load[3 * i + 2] = 1.0;  // gravity along −z
  });
  t.x0.resize(3 * n);
  for (Index i = 0; i < n; ++i) vertex(t.x0, i) = Vec3(0.4 * i, 0.15 * (i % 2), 0.05 * i);
  return t;
}

/// Convex and nearly quadratic: zero-length springs, one anchor, and weak quartic wells.
TestProblem convex_chain() {
  const Index n = 5;
  auto t = make_problem(n, [](TestEnergy& e) {
    for (Index i = 0; i + 1 < n; ++i) e.springs.push_back({i, i + 1, 0.0, 10.0});
    e.anchors.push_back({0, Vec3(1, 0, 0), 50.0});
    for (Index i = 0; i < n; ++i) e.quartics.push_back({i, Vec3(0, 0.1 * i, 0), 0.5});
    e.load = VecX::LinSpaced(3 * n, -1.0, 1.0);
  });
  t.x0 = VecX::LinSpaced(3 * n, 0.5, -0.5);
  return t;
}

/// Quadratic: zero-length springs, anchors and a load.
TestProblem quadratic_chain() {
  const Index n = 5;
  auto t = make_problem(n, [](TestEnergy& e) {
    for (Index i = 0; i + 1 < n; ++i) e.springs.push_back({i, i + 1, 0.0, 10.0});
    e.anchors.push_back({0, Vec3(1, 0, 0), 50.0});
    e.anchors.push_back({4, Vec3(0, 2, 0), 5.0});
    e.load = VecX::LinSpaced(3 * n, -1.0, 1.0);
  });
  t.x0 = VecX::LinSpaced(3 * n, 0.5, -0.5);
  return t;
}

double min_eigenvalue(const physics::Objective& f, const VecX& x) {
  linalg::BlockMatrix3 H;
  f.hessian(x, H, false);
  const Eigen::MatrixXd D = Eigen::MatrixXd(H.to_sparse());
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(D).eigenvalues().minCoeff();
}

double counter(const solvers::SolveReport& r, const std::string& name) {
  for (const auto& [k, v] : r.counters)
    if (k == name) return v;
  ADD_FAILURE() << "no counter " << name;
  return -1.0;
}

solvers::Stop tight(int max_iters = 500) {
  solvers::Stop s;
  s.rel_grad = 1e-10;
  s.max_iters = max_iters;
  return s;
}

std::unique_ptr<solvers::NonlinearSolver> by_name(const std::string& name, Json params = Json::object()) {
  solvers::SolverConfig c;
  c.name = name;
  c.params = std::move(params);
  return solvers::make_solver(c, "test.json", "solver.params");
}

}  // namespace

TEST(TrustRegion, TestEnergyDerivativesMatchFiniteDifferences) {
  for (const auto& t : {rosenbrock_chain(), hanging_chain(), convex_chain()}) {
    const auto& f = *t.objective;
    VecX g, gp, gm;
    f.gradient(t.x0, g);
    linalg::BlockMatrix3 H;
    f.hessian(t.x0, H, false);
    const Eigen::MatrixXd D = Eigen::MatrixXd(H.to_sparse());
    const double h = 1e-6;
    for (Index k = 0; k < t.x0.size(); ++k) {
      VecX xp = t.x0, xm = t.x0;
      xp[k] += h;
      xm[k] -= h;
      EXPECT_NEAR(g[k], (f.value(xp) - f.value(xm)) / (2 * h), 1e-6 * std::max(1.0, std::abs(g[k]))) << k;
      f.gradient(xp, gp);
      f.gradient(xm, gm);
      const VecX column = (gp - gm) / (2 * h);
      EXPECT_LE((D.col(k) - column).norm(), 1e-5 * std::max(1.0, column.norm())) << k;
    }
  }
}

TEST(TrustRegion, DoglegAndSteihaugCgReachTheSameMinimizerFromAnIndefiniteStart) {
  auto t = rosenbrock_chain();
  ASSERT_LT(min_eigenvalue(*t.objective, t.x0), 0.0);
  const VecX ones = VecX::Ones(12);
  for (const std::string name : {"tr-dogleg", "tr-stcg"}) {
    auto solver = by_name(name);
    EXPECT_EQ(solver->name(), name);
    auto problem = t.problem();
    VecX x = t.x0;
    const auto rep = solver->minimize(problem, x, tight(), nullptr);
    EXPECT_TRUE(rep.converged) << name << ": " << rep.status << " after " << rep.iterations;
    EXPECT_LE((x - ones).norm(), 1e-8) << name;
    EXPECT_GT(counter(rep, "rejected"), 0) << name << ": the test should exercise rejections";
  }
}

TEST(TrustRegion, HangingChainMinimizersAgreeAcrossSolvers) {
  auto t = hanging_chain();
  ASSERT_LT(min_eigenvalue(*t.objective, t.x0), 0.0);
  VecX reference;
  for (const std::string name : {"tr-dogleg", "tr-stcg", "newton-ls"}) {
    auto solver = by_name(name);
    auto problem = t.problem();
    VecX x = t.x0;
    const auto rep = solver->minimize(problem, x, tight(), nullptr);
    EXPECT_TRUE(rep.converged) << name << ": " << rep.status;
    // A minimizer: positive definite Hessian, and the chain hangs straight down from the anchor.
    EXPECT_GT(min_eigenvalue(*t.objective, x), 0.0) << name;
    EXPECT_LT(vertex(x, 5)[2], -5.0) << name;
    if (reference.size() == 0) reference = x;
    else EXPECT_LE((x - reference).norm(), 1e-7) << name;
  }
}

TEST(TrustRegion, HybridHessianTakesTheProjectedModelOnlyWhereTheExactOneIsIndefinite) {
  // "hessian": "hybrid": the compressed start has an indefinite H, so the first models are the projected ones (this
  // test energy has no projection of its own, so they are shifted by the dogleg: the test covers the switching);
  // near the straight hanging state H is positive definite and the exact model's Newton steps finish the solve.
  auto t = hanging_chain();
  auto problem = t.problem();
  VecX exact = t.x0, hybrid = t.x0;
  const auto ref = by_name("tr-dogleg")->minimize(problem, exact, tight(), nullptr);
  ASSERT_TRUE(ref.converged) << ref.status;
  const auto rep = by_name("tr-dogleg", Json{{"hessian", "hybrid"}})->minimize(problem, hybrid, tight(), nullptr);
  ASSERT_TRUE(rep.converged) << rep.status;
  EXPECT_GT(counter(rep, "projected_models"), 0);
  EXPECT_LT(counter(rep, "projected_models"), counter(rep, "accepted"));
  EXPECT_EQ(counter(ref, "projected_models"), 0);
  EXPECT_LE((hybrid - exact).norm(), 1e-7);
  EXPECT_GT(min_eigenvalue(*t.objective, hybrid), 0.0);
}

TEST(TrustRegion, ExtrapolatedStepsKeepTheMinimizerAndTheEnergyDecreasing) {
  // "extrapolate": where the model was too stiff along an accepted step (ρ > 1, the hybrid model's projected
  // Hessian on the compressed chain), doublings of the step that lower the energy are kept: the same minimizer,
  // energies still decreasing, and the doublings counted.
  auto t = hanging_chain();
  auto problem = t.problem();
  VecX plain = t.x0, extrapolated = t.x0;
  const auto ref = by_name("tr-dogleg", Json{{"hessian", "hybrid"}})->minimize(problem, plain, tight(), nullptr);
  ASSERT_TRUE(ref.converged) << ref.status;
  solvers::Trace trace;
  const auto rep = by_name("tr-dogleg", Json{{"hessian", "hybrid"}, {"extrapolate", 4}})
                       ->minimize(problem, extrapolated, tight(), &trace);
  ASSERT_TRUE(rep.converged) << rep.status;
  EXPECT_EQ(counter(ref, "extrapolations"), 0);
  EXPECT_GT(counter(rep, "extrapolations"), 0) << "the test should exercise doublings";
  EXPECT_LE((extrapolated - plain).norm(), 1e-7);
  for (size_t k = 1; k < trace.size(); ++k)
    EXPECT_LE(trace[k].energy, trace[k - 1].energy + 1e-13 * std::abs(trace[k - 1].energy)) << k;
}

TEST(TrustRegion, AcceptedEnergiesDecreaseAndRejectionsShrinkTheRadius) {
  auto t = rosenbrock_chain();
  for (const auto qp : {solvers::TrQp::Dogleg, solvers::TrQp::SteihaugCg}) {
    solvers::TrustRegionParams params;
    params.qp = qp;
    params.delta0 = 10.0;  // too large at the start: the first steps get rejected
    solvers::TrustRegion tr(params);
    auto problem = t.problem();
    VecX x = t.x0;
    solvers::Trace trace;
    const auto rep = tr.minimize(problem, x, tight(), &trace);
    ASSERT_TRUE(rep.converged) << tr.name() << ": " << rep.status;
    const auto& hist = tr.history();
    ASSERT_EQ(trace.size(), hist.size() + 1);
    ASSERT_EQ(static_cast<int>(hist.size()), rep.iterations);
    int rejected = 0;
    for (size_t k = 0; k < hist.size(); ++k) {
      const auto& it = hist[k];
      // In the round-off regime ρ is noise: the step was judged by the gradient norm and Δ kept.
      const bool noise = it.predicted < params.roundoff_tol * std::abs(trace[k].energy);
      if (it.accepted && noise) {
        EXPECT_LT(trace[k + 1].grad_norm, trace[k].grad_norm) << k;
        EXPECT_LE(trace[k + 1].energy, trace[k].energy + 1e-13 * std::abs(trace[k].energy)) << k;
        EXPECT_EQ(it.next_radius, it.radius) << k;
      } else if (it.accepted) {
        EXPECT_LT(trace[k + 1].energy, trace[k].energy) << k;
        EXPECT_GT(it.rho, params.eta1) << k;
        if (it.rho > params.eta2) EXPECT_DOUBLE_EQ(it.next_radius, params.gamma2 * it.radius) << k;
        else EXPECT_EQ(it.next_radius, it.radius) << k;
      } else {
        ++rejected;
        EXPECT_FALSE(noise) << k;
        EXPECT_LE(it.rho, params.eta1) << k;
        EXPECT_EQ(trace[k + 1].energy, trace[k].energy) << k;
        EXPECT_DOUBLE_EQ(it.next_radius, params.gamma1 * it.radius) << k;
      }
      EXPECT_EQ(trace[k + 1].step, it.accepted ? it.step_norm : 0.0) << k;
      EXPECT_LE(it.step_norm, it.radius * (1 + 1e-12));
      if (k + 1 < hist.size()) {
        EXPECT_EQ(hist[k + 1].radius, it.next_radius);
      }
    }
    EXPECT_GT(rejected, 0) << tr.name();
    EXPECT_EQ(counter(rep, "rejected"), rejected);
    EXPECT_EQ(counter(rep, "accepted") + rejected, rep.iterations);
    EXPECT_EQ(counter(rep, "final_radius"), hist.back().next_radius);
  }
}

TEST(TrustRegion, DerivativesAreAssembledOnlyAtAcceptedPoints) {
  auto t = rosenbrock_chain();
  for (const std::string name : {"tr-dogleg", "tr-stcg"}) {
    auto solver = by_name(name, {{"delta0", 10.0}});
    auto problem = t.problem();
    VecX x = t.x0;
    const auto rep = solver->minimize(problem, x, tight(), nullptr);
    ASSERT_TRUE(rep.converged) << name;
    const double accepted = counter(rep, "accepted");
    // One Hessian at the start and after each accepted step (none at the final, converged point).
    EXPECT_EQ(counter(rep, "hessian_assemblies"), accepted) << name;
    EXPECT_EQ(counter(rep, "qp_calls"), rep.iterations) << name;
    EXPECT_GT(counter(rep, "qp_calls"), counter(rep, "hessian_assemblies")) << name;
    EXPECT_GE(counter(rep, "gradient_assemblies"), accepted + 1) << name;
    if (name == "tr-dogleg") {
      EXPECT_GE(counter(rep, "factorizations"), counter(rep, "hessian_assemblies"));
      EXPECT_GT(counter(rep, "cholmod_fallbacks"), 0);  // the indefinite start
      EXPECT_EQ(counter(rep, "cg_iterations"), 0);
    } else {
      EXPECT_GT(counter(rep, "cg_iterations"), 0);
      EXPECT_EQ(counter(rep, "factorizations"), 0);
    }
  }
}

TEST(TrustRegion, StagnationClauseStopsAsStagnatedOnceTheRadiusIsLarge) {
  // With Δ past stagnation_delta from the start and a huge tolerance, the first accepted step changes x by less
  // than stagnation_tol: criterion (7.1)'s second part stops the solve, as "stagnated", which meets (7.1).
  auto t = convex_chain();
  solvers::TrustRegionParams params;
  params.delta0 = 1e16;
  params.stagnation_tol = 1e3;
  params.qp = solvers::TrQp::SteihaugCg;  // not a Newton step: only Δ activates the clause
  solvers::TrustRegion tr(params);
  auto problem = t.problem();
  VecX x = t.x0;
  const auto rep = tr.minimize(problem, x, tight(), nullptr);
  EXPECT_EQ(rep.status, "stagnated");
  EXPECT_TRUE(rep.converged);
  EXPECT_EQ(rep.iterations, 1);
  // Below stagnation_delta, and without Newton steps, the clause is off: the gradient test stops the solve.
  params.delta0 = 1.0;
  solvers::TrustRegion tr2(params);
  x = t.x0;
  const auto rep2 = tr2.minimize(problem, x, tight(), nullptr);
  EXPECT_EQ(rep2.status, "converged");
  EXPECT_GT(rep2.iterations, 1);
}

TEST(TrustRegion, NewtonStepsActivateTheStagnationClauseAtTheLimitingAccuracy) {
  // A gradient target of 0 cannot be met in floating point. Near the minimizer the dogleg takes the full step of
  // a positive definite H while Δ stays small (the round-off rule keeps it): the trust region is Newton's method,
  // which is what (7.1)'s Δ > 1e15 stands for, so the clause stops the solve once the steps fall below 1e-12.
  auto t = convex_chain();
  solvers::TrustRegionParams params;
  params.delta0 = 1.0;
  params.delta_max = 10.0;  // far below stagnation_delta = 1e15
  solvers::TrustRegion tr(params);
  auto problem = t.problem();
  VecX x = t.x0;
  solvers::Stop stop;
  stop.rel_grad = 0.0;
  stop.abs_grad = 0.0;
  stop.max_iters = 200;
  const auto rep = tr.minimize(problem, x, stop, nullptr);
  EXPECT_EQ(rep.status, "stagnated");
  EXPECT_TRUE(rep.converged);
  EXPECT_LT(rep.iterations, 60);
  EXPECT_LE(counter(rep, "final_radius"), 10.0);
  EXPECT_LT(rep.grad_norm, 1e-10 * rep.initial_grad_norm);
}

TEST(TrustRegion, InterruptibleSolvesStopOnTheFlagAndCheckpointAcceptedIterates) {
  auto t = convex_chain();
  auto problem = t.problem();
  solvers::TrustRegion tr;
  solvers::Stop stop = tight();
  stop.checkpoint_seconds = 0.0;  // after every accepted step
  std::vector<std::pair<int, double>> calls;
  VecX last;
  stop.checkpoint = [&](const VecX& x, int iterations, double energy, double) {
    calls.emplace_back(iterations, energy);
    last = x;
  };
  VecX x = t.x0;
  const auto rep = tr.minimize(problem, x, stop, nullptr);
  ASSERT_TRUE(rep.converged) << rep.status;
  EXPECT_EQ(static_cast<double>(calls.size()), counter(rep, "accepted"));
  for (size_t i = 1; i < calls.size(); ++i) {
    EXPECT_GT(calls[i].first, calls[i - 1].first);
    EXPECT_LE(calls[i].second, calls[i - 1].second);
  }
  EXPECT_EQ(last, x);  // the last step was accepted: its iterate is the result

  mgcloth::set_interrupted(true);
  x = t.x0;
  stop.checkpoint = nullptr;
  const auto kept = tr.minimize(problem, x, stop, nullptr);  // not interruptible: unaffected
  EXPECT_TRUE(kept.converged);
  stop.interruptible = true;
  x = t.x0;
  const auto stopped = tr.minimize(problem, x, stop, nullptr);
  mgcloth::set_interrupted(false);
  EXPECT_EQ(stopped.status, "interrupted");
  EXPECT_FALSE(stopped.converged);
  EXPECT_EQ(stopped.iterations, 0);
  EXPECT_EQ(x, t.x0);
}

TEST(TrustRegion, LocalTrMinimizesTheLevelModelWithItsLinearTerm) {
  // h(x) = f(x) + <δg, x − x₀> (Kopaničáková 2019, eq. 4.3): its minimizer satisfies ∇f(x) = −δg, and ∇h(x₀)
  // is ∇f(x₀) + δg (first-order consistency, eq. 4.5).
  auto t = convex_chain();
  const VecX delta_g = VecX::LinSpaced(15, 0.3, -0.2);
  const solvers::LevelModel h(*t.objective, delta_g, t.x0);
  VecX gf, gh;
  t.objective->gradient(t.x0, gf);
  h.gradient(t.x0, gh);
  EXPECT_LE((gh - gf - delta_g).norm(), 1e-14 * gf.norm());
  EXPECT_DOUBLE_EQ(h.value(t.x0), t.objective->value(t.x0));
  solvers::LocalTrustRegion core;
  solvers::LocalTrControl control;
  control.max_iters = 200;
  control.abs_grad = 1e-10;
  VecX x = t.x0;
  double radius = 1.0;
  const auto res = core.run(h, x, radius, control);
  EXPECT_EQ(res.status, "converged");
  t.objective->gradient(x, gf);
  EXPECT_LE((gf + delta_g).norm(), 1e-9);
  EXPECT_LE((core.gradient() - gf - delta_g).norm(), 1e-12);
  EXPECT_NEAR(res.grad_norm, core.gradient().norm(), 1e-15);
  // A smoothing call: exactly the iterations asked for, and the radius comes back updated.
  x = t.x0;
  radius = 1e-3;
  core.reset();
  solvers::LocalTrControl smoothing;
  smoothing.max_iters = 2;
  const auto two = core.run(h, x, radius, smoothing);
  EXPECT_EQ(two.status, "max_iters");
  EXPECT_EQ(two.iterations, 2);
  EXPECT_EQ(core.history().size(), 2u);
  EXPECT_EQ(radius, core.history().back().next_radius);
  EXPECT_GT(radius, 1e-3);  // two very good steps of a tiny radius: it grew
}

TEST(TrustRegion, RadiusCapLimitsEverySubsequentStep) {
  auto t = rosenbrock_chain();
  solvers::LocalTrustRegion core;
  solvers::LocalTrControl control;
  control.max_iters = 30;
  control.radius_cap = [](const VecX&, double r) { return std::min(r, 0.05); };
  VecX x = t.x0;
  double radius = 0.05;
  core.run(solvers::LevelModel(*t.objective), x, radius, control);
  EXPECT_LE(radius, 0.05);
  for (const auto& it : core.history()) EXPECT_LE(it.step_norm, 0.05 * (1 + 1e-12));
  control.radius_cap = [](const VecX&, double) { return 0.0; };
  x = t.x0;
  radius = 1.0;
  const auto res = core.run(solvers::LevelModel(*t.objective), x, radius, control);
  EXPECT_EQ(res.status, "radius_exhausted");
  EXPECT_EQ(res.iterations, 1);
}

TEST(ShellSolvers, NewtonLineSearchConvergesFromAnIndefiniteStart) {
  auto t = rosenbrock_chain();
  auto solver = by_name("newton-ls");
  auto problem = t.problem();
  VecX x = t.x0;
  solvers::Trace trace;
  const auto rep = solver->minimize(problem, x, tight(), &trace);
  EXPECT_TRUE(rep.converged) << rep.status;
  EXPECT_LE((x - VecX::Ones(12)).norm(), 1e-8);
  EXPECT_GT(counter(rep, "cholmod_fallbacks"), 0);
  bool backtracked = false;
  for (size_t k = 1; k < trace.size(); ++k) {
    EXPECT_LE(trace[k].energy, trace[k - 1].energy) << k;
    backtracked = backtracked || trace[k].step < 1.0;
  }
  EXPECT_TRUE(backtracked);
  // Near the minimizer the full Newton step passes the Armijo test (quadratic convergence).
  ASSERT_GE(trace.size(), 4u);
  for (size_t k = trace.size() - 3; k < trace.size(); ++k) EXPECT_EQ(trace[k].step, 1.0) << k;
}

TEST(ShellSolvers, DampedNewtonConvergesLinearlyWithRatioOneMinusAlpha) {
  auto t = convex_chain();
  auto problem = t.problem();
  VecX reference = t.x0;
  ASSERT_TRUE(by_name("newton-ls")->minimize(problem, reference, tight(), nullptr).converged);
  auto damped = by_name("newton-damped");  // α = 0.3 by default
  VecX x = t.x0;
  solvers::Trace trace;
  const auto rep = damped->minimize(problem, x, tight(200), &trace);
  EXPECT_TRUE(rep.converged) << rep.status;
  // Replay the iterates: e_{k+1}/e_k → 1 − α = 0.7 (a Newton step is exact up to O(e²) here).
  std::vector<double> errors;
  x = t.x0;
  solvers::Stop one;
  one.max_iters = 1;
  one.rel_grad = 0.0;
  for (int k = 0; k < 40; ++k) {
    errors.push_back((x - reference).norm());
    damped->minimize(problem, x, one, nullptr);
  }
  for (int k = 5; k + 1 < 40; ++k) {
    if (errors[k] < 1e-10) break;
    EXPECT_NEAR(errors[k + 1] / errors[k], 0.7, 0.02) << k;
  }
  for (const auto& row : trace) EXPECT_TRUE(row.step == 0.0 || row.step == 0.3);
}

TEST(ShellSolvers, DampedNewtonWithAConfiguredAlphaAndDivergenceIsASolveError) {
  auto t = convex_chain();
  auto problem = t.problem();
  VecX x = t.x0;
  auto full = by_name("newton-damped", {{"alpha", 1.0}});
  const auto rep = full->minimize(problem, x, tight(50), nullptr);
  EXPECT_TRUE(rep.converged);
  EXPECT_LT(rep.iterations, 15);  // full Newton steps: quadratic convergence
  // A NaN in the start is reported, not iterated on.
  x = t.x0;
  x[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(full->minimize(problem, x, tight(50), nullptr), SolveError);
}

TEST(ShellSolvers, LinearizedTakesExactlyOneNewtonStep) {
  // On a quadratic one Newton step is the exact minimizer.
  auto q = quadratic_chain();
  auto problem = q.problem();
  auto lin = by_name("linearized");
  VecX x = q.x0;
  solvers::Trace trace;
  const auto rep = lin->minimize(problem, x, tight(100), &trace);
  EXPECT_EQ(rep.iterations, 1);
  EXPECT_EQ(trace.size(), 2u);
  EXPECT_TRUE(rep.converged) << rep.status;
  EXPECT_EQ(rep.status, "converged");
  VecX g;
  q.objective->gradient(x, g);
  EXPECT_LE(g.norm(), 1e-10 * rep.initial_grad_norm);
  // On a nonlinear problem: still one step (x₀ − H⁻¹g₀ where H is positive definite), reported as "linearized".
  auto t = convex_chain();
  auto problem2 = t.problem();
  ASSERT_GT(min_eigenvalue(*t.objective, t.x0), 0.0);
  x = t.x0;
  const auto rep2 = lin->minimize(problem2, x, tight(100), nullptr);
  EXPECT_EQ(rep2.iterations, 1);
  EXPECT_EQ(rep2.status, "linearized");
  EXPECT_FALSE(rep2.converged);
  linalg::BlockMatrix3 H;
  t.objective->hessian(t.x0, H, false);
  t.objective->gradient(t.x0, g);
  const VecX newton = t.x0 - Eigen::MatrixXd(H.to_sparse()).ldlt().solve(g);
  EXPECT_LE((x - newton).norm(), 1e-12 * newton.norm());
}

TEST(ShellSolvers, FactoryBuildsEveryNameAndRejectsBadParameters) {
  for (const std::string name : {"tr-dogleg", "tr-stcg", "newton-ls", "newton-damped", "linearized"}) {
    const auto names = solvers::solver_names();
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
    EXPECT_EQ(by_name(name)->name(), name);
    solvers::SolverConfig c;
    c.name = name;
    EXPECT_NO_THROW(solvers::resolved_params(c, "s.json", "solver.params")) << name;
    EXPECT_THROW(by_name(name, {{"bogus", 1}}), InputError) << name;
  }
  solvers::SolverConfig c;
  c.name = "tr-stcg";
  const Json j = solvers::resolved_params(c, "s.json", "solver.params");
  EXPECT_EQ(j.at("eta1"), 0.1);
  EXPECT_EQ(j.at("eta2"), 0.75);
  EXPECT_EQ(j.at("gamma1"), 0.5);
  EXPECT_EQ(j.at("gamma2"), 2.0);
  EXPECT_EQ(j.at("delta0"), 1.0);
  EXPECT_TRUE(j.contains("stcg_max_iters"));
  c.name = "tr-dogleg";
  EXPECT_FALSE(solvers::resolved_params(c, "s.json", "solver.params").contains("stcg_max_iters"));
  EXPECT_THROW(by_name("tr-dogleg", {{"stcg_max_iters", 10}}), InputError);  // meaningless for the dogleg
  EXPECT_THROW(by_name("tr-dogleg", {{"eta1", 0.8}, {"eta2", 0.5}}), InputError);
  EXPECT_THROW(by_name("tr-dogleg", {{"gamma1", 1.0}}), InputError);
  EXPECT_THROW(by_name("tr-dogleg", {{"gamma2", 1.0}}), InputError);
  EXPECT_THROW(by_name("tr-dogleg", {{"delta0", 10.0}, {"delta_max", 1.0}}), InputError);
  EXPECT_THROW(by_name("newton-ls", {{"alpha", 0.5}}), InputError);  // only the damped variant has alpha
  EXPECT_THROW(by_name("newton-damped", {{"alpha", 0.0}}), InputError);
  EXPECT_THROW(by_name("linearized", {{"armijo", 1e-4}}), InputError);
  try {
    by_name("tr-stcg", {{"eta_1", 0.2}});
    FAIL() << "unknown key accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("solver.params.eta_1"), std::string::npos) << e.what();
  }
  // Parameters arrive in the solver: a tiny initial radius with a tiny growth factor needs many more iterations.
  auto t = rosenbrock_chain();
  auto problem = t.problem();
  VecX a = t.x0, b = t.x0;
  const auto ra = by_name("tr-dogleg")->minimize(problem, a, tight(), nullptr);
  const auto rb = by_name("tr-dogleg", {{"delta0", 1e-4}, {"gamma2", 1.1}})->minimize(problem, b, tight(), nullptr);
  EXPECT_GT(rb.iterations, ra.iterations + 20);
}

TEST(Rmtr, TheBareNameRunsTheBestMeasuredConfigurationAndThePapersHasItsOwnName) {
  const auto resolved = [](const std::string& name) {
    solvers::SolverConfig c;
    c.name = name;
    return solvers::resolved_params(c, "test", "solver.params");
  };
  const Json best = resolved("rmtr"), paper = resolved("rmtr-paper");
  EXPECT_EQ(best["smoother"], "dogleg");
  EXPECT_EQ(best["initial"], "nested");
  EXPECT_EQ(best["coarse_start"], "best");
  EXPECT_EQ(best["hessian"], "hybrid");
  EXPECT_EQ(paper["smoother"], "stcg");
  EXPECT_EQ(paper["initial"], "fine");
  EXPECT_EQ(paper["coarse_start"], "projection");
  // Parameters still override either.
  solvers::SolverConfig c;
  c.name = "rmtr";
  c.params = Json{{"smoother", "schwarz"}};
  EXPECT_EQ(solvers::resolved_params(c, "test", "solver.params")["smoother"], "schwarz");
}
