// Every solver through the simulation: the same step's minimizer from every baseline, Projective Dynamics against
// its textbook local/global iteration, and an FMG drape that respects the obstacle.
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/projective.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <Eigen/SparseCholesky>
#include <gtest/gtest.h>

#include <filesystem>

using namespace mgcloth;
namespace fs = std::filesystem;

namespace {
/// `form`: the scene's energy form; empty: the one the solver was made for (projective for the pd-* presets).
sim::Scene shipped(const std::string& name, int vertices, const std::string& solver, int substeps = 1,
                   const Json& params = Json::object(), std::string form = "") {
  const std::string path = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/" + name + ".json";
  Json j = load_json(path);
  j["cloths"][0]["mesh"]["vertices"] = vertices;
  j["substeps"] = substeps;
  j["hierarchy"] = {{"min_coarse_vertices", 30}, {"max_coarse_vertices", 80}};
  j["solver"] = {{"name", solver}, {"rel_grad", 1e-3}, {"max_iters", 500}, {"params", params}};
  j["energy_form"] = !form.empty() ? form : solver.starts_with("pd-") ? "projective" : "elastic";
  return sim::parse_scene(j, path, fs::path(path).parent_path());
}
/// A step frozen after `steps` steps of Newton + CHOLMOD: its start state and its minimizer to 1e-10.
struct FrozenStep {
  VecX x_prev, v_prev, xstar;
  int frame = 0;
  long step = 0;
  std::vector<std::pair<std::string, double>> terms;  ///< the minimizer's energy per term
};
FrozenStep frozen_step(const std::string& scene, int vertices, int substeps, int steps) {
  sim::Simulator ref(shipped(scene, vertices, "newton-direct", substeps));
  for (int k = 0; k < steps; ++k) ref.step();
  FrozenStep f{ref.cloths()[0]->x(), ref.cloths()[0]->v(), VecX(), ref.frame(), ref.step_count(), {}};
  auto problem = ref.prepare_problem(0, f.xstar);
  solvers::Stop stop;
  stop.rel_grad = 1e-10;
  stop.max_iters = 300;
  const auto rep = ref.solver(0).minimize(problem, f.xstar, stop, nullptr);
  EXPECT_TRUE(rep.converged) << scene << ": " << rep.status << " after " << rep.iterations;
  f.terms = problem.objective->term_values(f.xstar);
  return f;
}
}  // namespace

TEST(SolverScenes, FasAndEveryElasticSolverReachTheSameMinimizer) {
  // Step 3 of the hanging cloth, frozen; every solver of the elastic form from the same start to a tight tolerance.
  // Δt = 1/300 s keeps the step's objective convex (inertia dominates), so that its minimizer is unique: at 1/30 s
  // the falling cloth buckles and solvers may rightly land in different local minima.
  const FrozenStep f = frozen_step("hanging", 400, 10, 2);
  ASSERT_FALSE(HasFailure());
  const VecX& xstar = f.xstar;
  solvers::Stop stop;
  stop.rel_grad = 1e-10;
  for (const std::string name : {"fmg", "fas", "newton-mg", "newton-amg", "gs-chebyshev"}) {
    sim::Simulator s(shipped("hanging", 400, name, 10));
    s.set_state(0, 2, {f.x_prev}, {f.v_prev});
    VecX x;
    auto p = s.prepare_problem(0, x);
    EXPECT_EQ(p.hierarchy.has_objectives(), std::string(name) == "fas") << name;
    solvers::Stop st = stop;
    st.max_iters = name == "gs-chebyshev" ? 20000 : 300;
    const auto rep = s.solver(0).minimize(p, x, st, nullptr);
    EXPECT_LT((x - xstar).norm(), 1e-6 * xstar.norm()) << name << ": " << rep.status << " after " << rep.iterations;
  }
}

TEST(SolverScenes, TheFmgCudaPipelineReachesTheCpuMinimizerWithPinsAndContact) {
  // The GPU pipeline run by its host backend (the same kernels, on the CPU) through the simulator: one frozen step
  // of the hanging cloth (pins) and of the sphere drape in contact, against Newton + CHOLMOD and the CPU FMG.
  for (const std::string scene : {"hanging", "drape_sphere"}) {
    const int substeps = scene == "hanging" ? 10 : 4;
    const FrozenStep f = frozen_step(scene, 500, substeps, scene == "hanging" ? 2 : 16);
    ASSERT_FALSE(HasFailure());
    if (scene == "drape_sphere") {
      ASSERT_GT(f.terms.back().second, 0.0) << "the drape's step must be in contact";
    }
    for (const std::string name : {"fmg", "fmg-cuda"}) {
      const Json params = name == "fmg-cuda" ? Json{{"backend", "host"}} : Json::object();
      sim::Simulator s(shipped(scene, 500, name, substeps, params));
      s.set_state(f.frame, f.step, {f.x_prev}, {f.v_prev});
      VecX x;
      auto p = s.prepare_problem(0, x);
      solvers::Stop stop;
      stop.rel_grad = 1e-10;
      stop.max_iters = 500;
      const auto rep = s.solver(0).minimize(p, x, stop, nullptr);
      EXPECT_TRUE(rep.converged) << scene << " " << name << ": " << rep.status << " after " << rep.iterations;
      EXPECT_LT((x - f.xstar).norm(), 1e-5 * f.xstar.norm()) << scene << " " << name;
    }
  }
}

TEST(SolverScenes, ProjectiveDynamicsDirectIsTheTextbookLocalGlobalIteration) {
  // One pd-direct iteration must equal x1 = L⁻¹ (M y / h² + M g + Σ_t w A_t P(F_t) b_a + Σ_pins k target), the
  // local step (per-triangle projection P onto rotations) followed by the global solve with the constant matrix L.
  sim::Simulator s(shipped("hanging", 200, "pd-direct"));
  for (int k = 0; k < 3; ++k) s.step();  // a deformed state, so that the projections are not the identity
  const auto& body = *s.cloths()[0];
  VecX y;
  auto problem = s.prepare_problem(0, y);
  const physics::Objective& obj = *problem.objective;
  const double h = s.scene().step_size();
  const Index n = body.mesh().num_vertices();

  VecX rhs = VecX::Zero(3 * n);
  for (Index i = 0; i < n; ++i)
    rhs.segment<3>(3 * i) += body.mass()[i] * (y.segment<3>(3 * i) / (h * h) + s.scene().gravity);
  const physics::PDStrainMembrane* strain = nullptr;
  for (const auto& t : obj.terms())
    if (auto* p = dynamic_cast<const physics::PDStrainMembrane*>(t.get())) strain = p;
  ASSERT_NE(strain, nullptr);
  const physics::Material& mat = s.scene().cloths[0].material;
  for (Index t = 0; t < body.mesh().num_triangles(); ++t) {
    const auto& tri = body.mesh().tris[t];
    const physics::TriangleRest rest = physics::triangle_rest(body.mesh(), t);
    physics::Mat32 Ds;
    Ds.col(0) = y.segment<3>(3 * tri[1]) - y.segment<3>(3 * tri[0]);
    Ds.col(1) = y.segment<3>(3 * tri[2]) - y.segment<3>(3 * tri[0]);
    const physics::Mat32 P = physics::project_strain(Ds * rest.dm_inv, mat.pd_strain_min, mat.pd_strain_max);
    const Vec2 b1 = rest.dm_inv.row(0).transpose(), b2 = rest.dm_inv.row(1).transpose(), b0 = -b1 - b2;
    const double wa = strain->weight() * rest.area;
    rhs.segment<3>(3 * tri[0]) += wa * P * b0;
    rhs.segment<3>(3 * tri[1]) += wa * P * b1;
    rhs.segment<3>(3 * tri[2]) += wa * P * b2;
  }
  const auto targets = body.pin_targets(s.time() + h);
  for (size_t p = 0; p < targets.size(); ++p)
    rhs.segment<3>(3 * body.pinned_vertices()[p]) += s.scene().cloths[0].pins[0].stiffness * targets[p];
  linalg::BlockMatrix3 L;
  obj.hessian(y, L, false);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Eigen::SparseMatrix<double>(L.to_sparse()));
  ASSERT_EQ(ldlt.info(), Eigen::Success);
  const VecX textbook = ldlt.solve(rhs);

  VecX x = y;
  solvers::Stop one;
  one.rel_grad = 0.0;
  one.max_iters = 1;
  s.solver(0).minimize(problem, x, one, nullptr);
  EXPECT_LT((x - textbook).norm(), 1e-9 * textbook.norm()) << "max difference " << (x - textbook).cwiseAbs().maxCoeff();
  EXPECT_GT((x - y).norm(), 1e-6) << "the iteration moved nothing: the comparison would be vacuous";
}

TEST(SolverScenes, ProjectiveDynamicsSolversAgree) {
  // The three PD global steps minimize the same PD energy: all reach its minimizer of one step. (PD converges
  // linearly and slowly on a pinned cloth — the weakness Wang 2018 §4.4 starts from — hence the modest tolerance.)
  // The scene chooses the form, not the solver: Newton and the FMG given a scene of the projective form minimize
  // that same energy and land on the same minimizer.
  sim::Simulator ref(shipped("hanging", 100, "pd-direct"));
  ref.step();
  const VecX x_prev = ref.cloths()[0]->x(), v_prev = ref.cloths()[0]->v();
  std::vector<VecX> results;
  for (const std::string name : {"pd-direct", "pd-fmg", "pd-gs-chebyshev", "newton-direct", "fmg"}) {
    sim::Simulator s(shipped("hanging", 100, name, 1, Json::object(), "projective"));
    ASSERT_EQ(s.scene().energy_form, physics::EnergyForm::Projective);
    s.set_state(0, 1, {x_prev}, {v_prev});
    VecX x;
    auto p = s.prepare_problem(0, x);
    solvers::Stop st;
    st.rel_grad = 1e-4;
    st.max_iters = 20000;
    const auto rep = s.solver(0).minimize(p, x, st, nullptr);
    EXPECT_TRUE(rep.converged) << name << ": " << rep.status << " after " << rep.iterations << ", relative gradient "
                               << rep.grad_norm / rep.initial_grad_norm;
    std::printf("%-16s %6d iterations, %.1f ms\n", name.c_str(), rep.iterations, rep.wall_ms);
    results.push_back(x);
  }
  for (size_t k = 1; k < results.size(); ++k)
    EXPECT_LT((results[k] - results[0]).norm(), 1e-3 * results[0].norm()) << "solver " << k;
}

TEST(SolverScenes, FmgDrapeStaysWithinTheContactThickness) {
  sim::Simulator s(shipped("drape_sphere", 600, "fmg"));
  const double r = s.scene().obstacles[0].radius, thickness = s.scene().contact.thickness;
  for (int f = 0; f < 16; ++f) {
    for (const auto& st : s.advance_frame()) EXPECT_TRUE(st.report.converged) << "frame " << f + 1 << ": " << st.report.status;
    const auto& x = s.cloths()[0]->x();
    double closest = kInf;
    for (Index i = 0; i < x.size() / 3; ++i) closest = std::min(closest, x.segment<3>(3 * i).norm() - r);
    ASSERT_GE(closest, -1e-9) << "frame " << f + 1;  // projected onto the surface at worst
    if (f >= 8) {
      EXPECT_LT(closest, thickness) << "frame " << f + 1 << ": the cloth should rest in the contact layer";
    }
  }
}
