// The step's objective rediscretized on the coarse levels of a cloth's hierarchy (Problem::level_objectives), in
// the elastic and the Projective Dynamics forms.
#include <mgcloth/physics/attachment.hpp>
#include <mgcloth/physics/inertia.hpp>
#include <mgcloth/bodies/cloth_body.hpp>
#include <mgcloth/sim/scene.hpp>

#include <gtest/gtest.h>

using namespace mgcloth;

namespace {

/// A 1 m sheet at z = 1, pinned at its top corners (moving up), over a moving sphere it does not touch yet.
sim::Scene sheet_scene() {
  const Json j = Json::parse(R"({ "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 1500, "unstructured": true },
      "transform": { "translation": [-0.5, -0.5, 1.0] },
      "pins": [ { "points": [[0, 1], [1, 1]], "motion": { "type": "constant_velocity", "velocity": [0, 0, 0.1] } } ] } ],
    "obstacles": [ { "shape": { "type": "sphere", "radius": 0.25 }, "position": [0, 0, 0.5],
      "motion": { "type": "constant_velocity", "linear_velocity": [0, 0, 0.3] } } ],
    "hierarchy": { "min_coarse_vertices": 50, "max_coarse_vertices": 150 } })");
  return sim::parse_scene(j, "sheet.json", ".");
}

/// The scene's environment for its cloth, in the given energy form, with or without its obstacles.
bodies::ClothEnvironment environment(const sim::Scene& s, bool projective, bool obstacles = true) {
  bodies::ClothEnvironment env = sim::cloth_environment(s);
  env.energy_form = projective ? physics::EnergyForm::Projective : physics::EnergyForm::Elastic;
  if (!obstacles) env.obstacles.clear();
  return env;
}

std::vector<std::string> term_names(const physics::Objective& obj) {
  std::vector<std::string> names;
  for (const auto& t : obj.terms()) names.push_back(t->name());
  return names;
}

template <class T>
const T* find_term(const physics::Objective& obj) {
  for (const auto& t : obj.terms())
    if (const auto* p = dynamic_cast<const T*>(t.get())) return p;
  return nullptr;
}

VecX inject(const VecX& fine, const std::vector<Index>& to_finest) {
  VecX out(3 * to_finest.size());
  for (size_t i = 0; i < to_finest.size(); ++i) out.segment<3>(3 * i) = fine.segment<3>(3 * to_finest[i]);
  return out;
}

bool is_elastic(const std::string& name) { return name.starts_with("membrane") || name.starts_with("bending"); }

}  // namespace

TEST(LevelObjectives, SameTermsTotalMassAndNoElasticEnergyAtRest) {
  const sim::Scene scene = sheet_scene();
  for (bool projective : {false, true}) {
    SCOPED_TRACE(projective ? "projective" : "elastic");
    bodies::ClothBody body(scene.cloths[0], environment(scene, projective));
    const auto levels = body.level_objectives();
    const auto& h = body.hierarchy();
    ASSERT_GE(h.num_levels(), 3);
    ASSERT_EQ(levels.size(), static_cast<size_t>(h.num_levels() - 1));
    EXPECT_EQ(body.level_objectives(), levels);  // built once
    const auto names = term_names(body.objective());
    EXPECT_NE(std::find(names.begin(), names.end(), projective ? "contact_pd" : "contact"), names.end());
    EXPECT_NE(std::find(names.begin(), names.end(), "attachment"), names.end());
    const double fine_mass = body.mass().sum();
    const hierarchy::Hierarchy solver_levels = body.solver_hierarchy(true);
    ASSERT_EQ(solver_levels.num_levels(), levels.size() + 1);
    for (size_t l = 0; l < levels.size(); ++l) {
      const auto& level = h.level(static_cast<Index>(l + 1));
      EXPECT_EQ(solver_levels.levels[l + 1].objective, levels[l]);
      // The levels' vertex sets are nested: the projection of iterates is injection.
      VecX projected;
      solver_levels.levels[l].project(l == 0 ? body.x() : inject(body.x(), h.level(static_cast<Index>(l)).to_finest), projected);
      EXPECT_EQ(projected, inject(body.x(), level.to_finest)) << "level " << l + 1;
      EXPECT_EQ(levels[l]->num_vertices(), level.mesh.num_vertices());
      EXPECT_EQ(term_names(*levels[l]), names) << "level " << l + 1;
      const auto* inertia = find_term<physics::InertiaTerm>(*levels[l]);
      ASSERT_NE(inertia, nullptr);
      EXPECT_NEAR(inertia->mass().sum(), fine_mass, 1e-12 * fine_mass);
      // The flat, unstretched initial sheet injected onto the level is stress-free there too.
      const VecX x = inject(body.x(), level.to_finest);
      for (const auto& [name, value] : levels[l]->term_values(x))
        if (is_elastic(name)) {
          EXPECT_LT(std::abs(value), 1e-18) << name << " on level " << l + 1;
        }
    }
  }
}

TEST(LevelObjectives, CoarseGradientAtTheInjectedPredictionIsGravity) {
  // A free sheet (no pins, no obstacles) at rest, then moving rigidly: at the injected prediction y the inertia and
  // the elastic terms vanish on every level, leaving −m g; a rigid shift δ adds m δ/h².
  Json j = Json::parse(R"({ "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 1200, "unstructured": true },
      "material": { "bending": "quadratic" } } ],
    "hierarchy": { "min_coarse_vertices": 50, "max_coarse_vertices": 150 } })");
  const sim::Scene scene = sim::parse_scene(j, "free.json", ".");
  const double h = 0.01;
  for (bool projective : {false, true}) {
    SCOPED_TRACE(projective ? "projective" : "elastic");
    bodies::ClothBody body(scene.cloths[0], environment(scene, projective, false));
    VecX y = body.prepare_step(0.0, h);  // before the levels exist: they must pick up this step when built
    const auto levels = body.level_objectives();
    const auto& hier = body.hierarchy();
    for (int step = 0; step < 2; ++step) {
      if (step == 1) {
        body.v() = Vec3(0.3, -0.1, 0.2).replicate(body.mesh().num_vertices(), 1);
        y = body.prepare_step(h, h);
      }
      for (size_t l = 0; l < levels.size(); ++l) {
        const auto& level = hier.level(static_cast<Index>(l + 1));
        const VecX mass = find_term<physics::InertiaTerm>(*levels[l])->mass();
        const VecX yc = inject(y, level.to_finest);
        const Vec3 delta(1e-3, 2e-3, -1e-3);
        for (const Vec3& shift : {Vec3(Vec3::Zero()), delta}) {
          VecX x = yc;
          for (Index i = 0; i < mass.size(); ++i) x.segment<3>(3 * i) += shift;
          VecX g;
          levels[l]->gradient(x, g);
          VecX expected(g.size());
          for (Index i = 0; i < mass.size(); ++i) expected.segment<3>(3 * i) = mass[i] * (shift / (h * h) - scene.gravity);
          EXPECT_LE((g - expected).norm(), 1e-9 * expected.norm()) << "level " << l + 1 << ", step " << step;
        }
      }
    }
  }
}

TEST(LevelObjectives, CoarseLevelsFollowPinsObstaclesAndActiveSets) {
  const sim::Scene scene = sheet_scene();
  bodies::ClothBody body(scene.cloths[0], environment(scene, true));
  const auto levels = body.level_objectives();
  const auto& hier = body.hierarchy();
  const double h = 1.0 / 30.0;
  // The sphere rises towards the sheet at 0.3 m/s: out of reach of the active set (φ < 2d) for the first 20 steps,
  // through the sheet's middle at the 30th.
  for (int step = 0; step < 30; ++step) {
    body.v() = VecX::Zero(body.v().size());
    body.prepare_step(step * h, h);
    const auto targets = body.pin_targets((step + 1) * h);
    const auto* fine_contact = dynamic_cast<const physics::PDObstacleContact*>(body.contact());
    ASSERT_NE(fine_contact, nullptr);
    for (size_t l = 0; l < levels.size(); ++l) {
      const auto* pins = find_term<physics::AttachmentTerm>(*levels[l]);
      ASSERT_NE(pins, nullptr);
      ASSERT_EQ(pins->targets().size(), targets.size());
      for (size_t p = 0; p < targets.size(); ++p) EXPECT_EQ(pins->targets()[p], targets[p]);
      // Pinned vertices are kept: each coarse pin sits on the same finest vertex as the fine pin.
      const auto& to_finest = hier.level(static_cast<Index>(l + 1)).to_finest;
      for (size_t p = 0; p < targets.size(); ++p)
        EXPECT_EQ(to_finest[pins->elements()[p][0]], body.pinned_vertices()[p]);
      const auto* contact = find_term<physics::PDObstacleContact>(*levels[l]);
      ASSERT_NE(contact, nullptr);
      EXPECT_EQ(contact->poses()[0].translation, fine_contact->poses()[0].translation);
      if (step < 20) {
        EXPECT_EQ(contact->num_active(), 0) << "step " << step << ", level " << l + 1;
      } else if (step == 29) {
        EXPECT_GT(contact->num_active(), 0) << "level " << l + 1;
      }
    }
    if (step < 20) {
      EXPECT_EQ(fine_contact->num_active(), 0);
    } else if (step == 29) {
      EXPECT_GT(fine_contact->num_active(), 0);
    }
  }
}

TEST(LevelObjectives, GarmentLevelsKeepTheirSeams) {
  const Json j = {{"cloths", {{{"mesh", {{"generator", "tube"}, {"circumference", 1.2}, {"height", 0.3}, {"vertices", 1200}}}}}},
                  {"hierarchy", {{"max_coarse_vertices", 150}, {"min_coarse_vertices", 50}}}};
  const sim::Scene scene = sim::parse_scene(j, "skirt.json", ".");
  for (bool projective : {false, true}) {
    bodies::ClothBody body(scene.cloths[0], environment(scene, projective, false));
    const auto levels = body.level_objectives();
    ASSERT_GE(levels.size(), 2u);
    const auto names = term_names(body.objective());
    ASSERT_NE(std::find(names.begin(), names.end(), "seam"), names.end());
    for (size_t l = 0; l < levels.size(); ++l) {
      EXPECT_EQ(term_names(*levels[l]), names) << "level " << l + 1;
      // The sewn initial tube: its seams are closed on every level.
      const VecX x = inject(body.x(), body.hierarchy().level(static_cast<Index>(l + 1)).to_finest);
      for (const auto& [name, value] : levels[l]->term_values(x)) {
        if (name == "seam") {
          EXPECT_LT(std::abs(value), 1e-20) << "level " << l + 1;
        }
      }
    }
  }
}
