// The Projective Dynamics form of a cloth end to end. A PD solver is Newton's method with the PD matrix as the
// Hessian, so solvers::Newton (exact_hessian_below = 0) runs these scenes as line-searched local/global PD.
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/physics/projective.hpp>
#include <mgcloth/bodies/cloth_body.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/solvers/newton.hpp>

#include <gtest/gtest.h>

#include <filesystem>

using namespace mgcloth;
namespace fs = std::filesystem;

namespace {

/// A cloth of a scene in the PD form, stepped as Simulator::step does, by Newton on the PD matrix.
struct PdCloth {
  explicit PdCloth(const sim::Scene& s) : scene(s) {
    bodies::ClothEnvironment env = sim::cloth_environment(scene);
    env.energy_form = physics::EnergyForm::Projective;
    body = std::make_unique<bodies::ClothBody>(scene.cloths[0], env);
    solvers::NewtonParams p;
    p.exact_hessian_below = 0.0;
    p.project_psd = false;  // the PD matrix is PSD; projection would only cost eigen-decompositions
    newton = std::make_unique<solvers::Newton>(p);
  }

  solvers::SolveReport step() {
    const double h = scene.step_size();
    VecX x = body->prepare_step(t, h);
    solvers::Problem problem;
    problem.objective = &body->objective();
    if (const auto* c = body->contact())
      problem.project = [c](VecX& y) { return physics::project_out_of_obstacles(y, c->obstacle_data()); };
    const auto report = newton->minimize(problem, x, scene.solver.stop, nullptr);
    const VecX solved = x;
    body->finish_step(x, h);
    projected = ((x - solved).array() != 0.0).count();
    t += h;
    return report;
  }

  sim::Scene scene;
  std::unique_ptr<bodies::ClothBody> body;
  std::unique_ptr<solvers::Newton> newton;
  double t = 0.0;
  Eigen::Index projected = 0;  ///< coordinates the last step's contact projection moved
};

}  // namespace

TEST(ProjectiveForm, ClothBodyBuildsThePdTerms) {
  const Json j = Json::parse(R"({ "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 100 },
      "pins": [ { "points": [[0, 1]] } ] } ], "obstacles": [ { "shape": { "type": "plane" } } ] })");
  const sim::Scene scene = sim::parse_scene(j, "pd.json", ".");
  PdCloth pd(scene);
  std::vector<std::string> names;
  for (const auto& t : pd.body->objective().terms()) names.push_back(t->name());
  // Hinge bending (the preset's) becomes quadratic bending: the PD form has no state-dependent matrix.
  const std::vector<std::string> expected{"inertia", "gravity", "membrane_pd_strain", "bending_quadratic", "attachment",
                                          "contact_pd"};
  EXPECT_EQ(names, expected);
  EXPECT_TRUE(pd.body->projective());
  ASSERT_NE(pd.body->contact(), nullptr);
  EXPECT_NE(dynamic_cast<const physics::PDObstacleContact*>(pd.body->contact()), nullptr);
}

TEST(ProjectiveForm, StrainLimitsAreOptionalMaterialKeys) {
  Json j = Json::parse(R"({ "cloths": [ { "mesh": { "vertices": 100 },
      "material": { "pd_strain_min": 0.9, "pd_strain_max": 1.1 } } ] })");
  const sim::Scene s = sim::parse_scene(j, "pd.json", ".");
  EXPECT_EQ(s.cloths[0].material.pd_strain_min, 0.9);
  EXPECT_EQ(s.cloths[0].material.pd_strain_max, 1.1);
  EXPECT_EQ(sim::to_json(s)["cloths"][0]["material"]["pd_strain_max"], 1.1);
  j["cloths"][0]["material"]["pd_strain_min"] = 1.2;
  EXPECT_THROW(sim::parse_scene(j, "pd.json", "."), InputError);
  const sim::Scene defaults = sim::parse_scene(Json::parse(R"({ "cloths": [ { "mesh": {} } ] })"), "pd.json", ".");
  EXPECT_EQ(defaults.cloths[0].material.pd_strain_min, 1.0);
  EXPECT_EQ(defaults.cloths[0].material.pd_strain_max, 1.0);
}

TEST(ProjectiveForm, HangingSheetSettlesToTheStaticStretch) {
  // A 0.5 m square hanging in the xz-plane from its whole top edge. The PD strain membrane has Poisson's ratio 0,
  // so the static state is a 1D bar: tension ρtg·s at height s above the bottom, strain ρtg·s/w, and the bottom
  // edge drops by Δ = ρtg L²/(2w). The stretching modes are stiff (ωh ≈ 5), so implicit Euler settles in a few steps.
  const Json j = Json::parse(R"({ "cloths": [ { "mesh": { "generator": "rectangle", "width": 0.5, "height": 0.5,
      "vertices": 200 }, "transform": { "rotation_deg": [90, 0, 0] },
      "pins": [ { "region": { "min": [0, 0.5], "max": [0.5, 0.5] }, "stiffness": 1e6 } ] } ],
    "solver": { "rel_grad": 1e-6, "abs_grad": 1e-8, "max_iters": 100 } })");
  PdCloth pd(sim::parse_scene(j, "hang.json", "."));
  const auto& body = *pd.body;
  for (int s = 0; s < 20; ++s) {
    const auto report = pd.step();
    ASSERT_TRUE(report.converged) << "step " << s << ": " << report.status << " after " << report.iterations;
  }
  EXPECT_LT(body.v().cwiseAbs().maxCoeff(), 1e-6);
  const physics::Material& mat = pd.scene.cloths[0].material;
  const double w = 2.0 * mat.mu() * mat.thickness, L = 0.5;
  const double drop = mat.areal_density() * 9.81 * L * L / (2.0 * w);
  double worst = 0.0;
  int bottom = 0;
  for (Index i = 0; i < body.mesh().num_vertices(); ++i)
    if (body.mesh().u(1, i) < 1e-12) {
      worst = std::max(worst, std::abs(body.x()[3 * i + 2] + drop) / drop);
      ++bottom;
    }
  EXPECT_GE(bottom, 5);
  EXPECT_LT(worst, 0.01) << "bottom edge drop " << drop << " m";
  // At rest the step's solution is the static equilibrium: no force left but the (vanishing) inertial one.
  VecX g;
  pd.body->objective().gradient(body.x(), g);
  EXPECT_LT(g.norm(), 1e-7);
}

TEST(ProjectiveForm, SheetDroppedOnASphereRestsOnIt) {
  // The shipped drape at low resolution. PD converges slowly where the sheet wraps (rotations are stiff in the PD
  // matrix), so the solves stop at a loose tolerance; the contact term must still hold the sheet up by itself: the
  // post-solve projection finds no vertex inside the sphere.
  const std::string path = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/drape_sphere.json";
  Json j = load_json(path);
  j["cloths"][0]["mesh"]["vertices"] = 200;
  j["solver"] = {{"rel_grad", 1e-2}, {"max_iters", 200}};
  PdCloth pd(sim::parse_scene(j, path, fs::path(path).parent_path()));
  const double r = pd.scene.obstacles[0].radius, thickness = pd.scene.contact.thickness;
  const auto* contact = dynamic_cast<const physics::PDObstacleContact*>(pd.body->contact());
  ASSERT_NE(contact, nullptr);
  for (int s = 0; s < 12; ++s) {
    pd.step();
    EXPECT_EQ(pd.projected, 0) << "step " << s + 1;
    const auto& x = pd.body->x();
    ASSERT_TRUE(x.allFinite());
    for (Index i = 0; i < x.size() / 3; ++i)
      ASSERT_GE(x.segment<3>(3 * i).norm() - r, -thickness) << "step " << s + 1 << " vertex " << i;
  }
  EXPECT_GT(contact->num_active(), 0);
  const auto cols = as_columns(pd.body->x());
  EXPECT_NEAR(cols.row(2).maxCoeff(), r, 0.01);  // resting on the sphere's top
  EXPECT_LT(cols.row(2).minCoeff(), 0.0);        // the sides fall past it
}
