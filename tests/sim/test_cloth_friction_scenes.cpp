// Cloth–cloth friction end to end: a small sheet on a pinned sheet under tilted gravity against the block on an
// incline (static friction holds for μ > tan θ; otherwise it slides with a = g(sin θ − μ cos θ)), and the scene keys.
#include <mgcloth/collision/intersections.hpp>
#include <mgcloth/core/error.hpp>
#include <mgcloth/sim/simulator.hpp>

#include "resume_fixture.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

using namespace mgcloth;
namespace fs = std::filesystem;

namespace {

constexpr double kG = 9.81;
constexpr double kStep = 1.0 / 60.0;

/// A 0.4 × 0.12 m sheet pinned flat at z = 0 and a 5 × 5 cm sheet lying on it at height z (turned by 10° so that no
/// edges of the two meshes are parallel), under gravity g(sin θ, 0, −cos θ): the incline is the bottom sheet.
Json incline(double theta, double friction, double z = 1e-3) {
  const Json floor_mesh = {{"generator", "rectangle"}, {"width", 0.4}, {"height", 0.12}, {"vertices", 150}};
  const Json block_mesh = {{"generator", "rectangle"}, {"width", 0.05}, {"height", 0.05}, {"vertices", 36}};
  return {
      {"time_step", kStep},
      {"frames", 100},
      {"gravity", {kG * std::sin(theta), 0.0, -kG * std::cos(theta)}},
      {"cloths",
       {{{"name", "floor"},
         {"mesh", floor_mesh},
         {"pins", {{{"region", {{"min", {0.0, 0.0}}, {"max", {0.4, 0.12}}}}, {"stiffness", 1e6}}}}},
        {{"name", "block"},
         {"mesh", block_mesh},
         {"transform", {{"translation", {0.04, 0.03, z}}, {"rotation_deg", {0, 0, 10}}}}}}},
      {"cloth_contact", {{"friction", friction}}},
      {"solver", {{"name", "fmg"}, {"rel_grad", 1e-6}}},
  };
}

sim::Scene parse(const Json& j, const std::string& name = "scene.json") {
  return sim::parse_scene(j, name, fs::path(MGCLOTH_SOURCE_DIR) / "scenes");
}

double mean_x(const VecX& x) { return as_columns(x).row(0).mean(); }
double mean_vx(const sim::ClothBody& c) { return as_columns(c.v()).row(0).mean(); }

/// The block's history on the incline: mean x-position and x-velocity after every step, from rest at the contact's
/// equilibrium under the normal load (settled first under gravity g cos θ straight down, then released).
struct Slide {
  std::vector<double> x, v;
};

Slide slide(double theta, double friction, int steps) {
  Json settle = incline(0.0, friction);
  settle["gravity"] = {0.0, 0.0, -kG * std::cos(theta)};
  sim::Simulator rest(parse(settle));
  for (int k = 0; k < 6; ++k) rest.advance_frame();
  std::vector<VecX> x, v;
  for (const auto& b : rest.bodies()) {
    x.push_back(b->x());
    v.push_back(VecX::Zero(b->v().size()));
  }
  sim::Simulator s(parse(incline(theta, friction)));
  s.set_state(0, 0, x, v);
  Slide out;
  out.x.push_back(mean_x(s.cloths()[1]->x()));
  out.v.push_back(0.0);
  for (int k = 0; k < steps; ++k) {
    for (const auto& st : s.advance_frame()) EXPECT_EQ(st.intersections, 0);
    out.x.push_back(mean_x(s.cloths()[1]->x()));
    out.v.push_back(mean_vx(*s.cloths()[1]));
  }
  // The block still lies on the floor (it neither sank through nor lifted off).
  const auto z = as_columns(s.cloths()[1]->x()).row(2);
  EXPECT_GT(z.minCoeff(), 0.0);
  EXPECT_LT(z.maxCoeff(), 1e-3);
  return out;
}

/// The acceleration over the run: implicit Euler under a constant force gains h·a of velocity every step, so the
/// velocity's rise after the first step (which passes through the static part of the mollifier) is a·(T − h).
double acceleration(const Slide& s) {
  const size_t n = s.v.size() - 1;
  return (s.v[n] - s.v[1]) / (static_cast<double>(n - 1) * kStep);
}

}  // namespace

// μ > tan θ: static friction holds. The lagged friction's static part is a stiff spring of reach ε_v h per step
// (ε_v the static friction velocity, 1e-3 m/s by default): under a tangential load ρ μN with ρ < 1 a contact creeps
// by the y of f1(y/ε_v h) = ρ each step, so at ε_v (1 − √(1 − ρ)) < ε_v. The drift over 0.5 s is thus below
// ε_v · 0.5 s = 0.5 mm (measured 0.24 mm), where the frictionless block slides 0.6 m.
TEST(ClothFrictionScenes, StaticFrictionHoldsABlockOnAnInclineFlatterThanAtanMu) {
  const double theta = 20.0 * std::numbers::pi / 180.0;  // tan θ = 0.36
  const double mu = 0.5, eps_v = 1e-3;
  const int steps = 30;  // 0.5 s
  const Slide s = slide(theta, mu, steps);
  const double drift = s.x.back() - s.x.front();
  EXPECT_GE(drift, 0.0);
  EXPECT_LT(drift, eps_v * steps * kStep);
  const double creep = eps_v * (1.0 - std::sqrt(1.0 - std::tan(theta) / mu));
  EXPECT_NEAR(s.v.back(), creep, 0.05 * creep);
}

// μ < tan θ: the block slides with a = g(sin θ − μ cos θ). The mollifier weakens friction only while a contact moves
// less than ε_v h in a step (the first step here, left out of the fit), and the normal force is the settled one; what
// remains is the solver's tolerance (rel_grad 1e-6) and the pairs entering and leaving the layer as the block crosses
// the floor's triangles. Measured within 1e-4 of the classical value; 1% leaves room for other solver paths while
// friction itself changes the acceleration by half.
TEST(ClothFrictionScenes, ABlockSlidesDownASteeperInclineWithTheKineticAcceleration) {
  const double theta = 30.0 * std::numbers::pi / 180.0;  // tan θ = 0.58
  const double mu = 0.3;
  const Slide s = slide(theta, mu, 18);  // 0.3 s, 0.11 m down the floor
  const double expected = kG * (std::sin(theta) - mu * std::cos(theta));
  EXPECT_NEAR(acceleration(s), expected, 0.01 * expected);
}

TEST(ClothFrictionScenes, AFrictionlessBlockSlidesWithGSinTheta) {
  const double theta = 30.0 * std::numbers::pi / 180.0;
  const Slide s = slide(theta, 0.0, 18);
  const double expected = kG * std::sin(theta);
  EXPECT_NEAR(acceleration(s), expected, 0.01 * expected);
}

TEST(ClothFrictionScenes, CoefficientsPerPairOfClothsReachTheTerm) {
  Json j = incline(0.3, 0.4);
  j["cloth_contact"]["friction_pairs"] = {{{"cloths", {"block", "floor"}}, {"friction", 0.8}},
                                          {{"cloths", {"block", "block"}}, {"friction", 0.1}}};
  const sim::Scene scene = parse(j);
  // The resolved scene carries them and parses to the same.
  const sim::Scene again = parse(sim::to_json(scene));
  ASSERT_EQ(again.cloth_contact.friction.pairs.size(), 2u);
  EXPECT_EQ(again.cloth_contact.friction.pairs[0].friction, 0.8);
  EXPECT_EQ(again.cloth_contact.friction.friction, 0.4);
  sim::Simulator s(scene);
  const physics::ClothFriction* f = s.group(0).cloth_friction();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->friction(0, 1), 0.8);
  EXPECT_EQ(f->friction(1, 0), 0.8);
  EXPECT_EQ(f->friction(1, 1), 0.1);
  EXPECT_EQ(f->friction(0, 0), 0.4);
  // No friction anywhere: no term.
  sim::Simulator none(parse(incline(0.3, 0.0)));
  EXPECT_FALSE(none.group(0).cloth_friction());
}

TEST(ClothFrictionScenes, BadFrictionKeysNameTheirPath) {
  const Json pair = {{"cloths", {"floor", "block"}}, {"friction", 0.5}};
  const auto with_pair = [&](const std::string& key, const Json& value) {
    Json p = pair;
    if (value.is_null()) p.erase(key);
    else p[key] = value;
    return Json::array({p});
  };
  const std::vector<std::tuple<std::string, Json, std::string>> cases{
      {"friction", -0.5, "cloth_contact.friction"},
      {"friction", std::nan(""), "cloth_contact.friction"},
      {"friction", "high", "cloth_contact.friction"},
      {"static_friction_velocity", 0.0, "cloth_contact.static_friction_velocity"},
      {"friction_pairs", Json::object(), "cloth_contact.friction_pairs"},
      {"friction_pairs", with_pair("cloths", Json::array({"floor", "nobody"})),
       "cloth_contact.friction_pairs[0].cloths[1]: no cloth is named \"nobody\""},
      {"friction_pairs", with_pair("cloths", Json::array({"floor"})), "cloth_contact.friction_pairs[0].cloths"},
      {"friction_pairs", with_pair("cloths", "floor"), "cloth_contact.friction_pairs[0].cloths"},
      {"friction_pairs", with_pair("friction", -1.0), "cloth_contact.friction_pairs[0].friction"},
      {"friction_pairs", with_pair("friction", std::nan("")), "cloth_contact.friction_pairs[0].friction"},
      {"friction_pairs", with_pair("friction", Json()), "cloth_contact.friction_pairs[0].friction: missing"},
      {"friction_pairs", with_pair("mu", 0.5), "cloth_contact.friction_pairs[0].mu"},
      {"friction_pairs", Json::array({pair, {{"cloths", {"block", "floor"}}, {"friction", 0.2}}}),
       "cloth_contact.friction_pairs[1].cloths: the pair \"block\", \"floor\" is given twice"},
  };
  for (const auto& [key, value, message] : cases) {
    Json j = incline(0.3, 0.4);
    j["cloth_contact"][key] = value;
    try {
      parse(j);
      ADD_FAILURE() << key << " = " << value.dump() << " accepted";
    } catch (const InputError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find("scene.json: " + message), std::string::npos) << m;
    }
  }
}

// Friction is frozen from each step's start state alone, so a run resumed mid-slide (as from checkpoint.bin)
// repeats the uninterrupted one bit for bit.
TEST(ClothFrictionScenes, AResumedSlideRepeatsTheUninterruptedOneBitForBit) {
  const sim::Scene scene = parse(incline(0.5, 0.3, 0.99e-3));
  sim::Simulator straight(scene), first(scene);
  for (int f = 0; f < 10; ++f) straight.advance_frame();
  for (int f = 0; f < 5; ++f) first.advance_frame();
  auto resumed_ptr = sim::fixtures::resumed_from(scene, first);
  sim::Simulator& resumed = *resumed_ptr;
  for (int f = 5; f < 10; ++f) resumed.advance_frame();
  ASSERT_TRUE(resumed.group(0).cloth_friction());
  EXPECT_GT(resumed.group(0).cloth_friction()->num_pairs(), 0);
  EXPECT_GT(mean_vx(*resumed.cloths()[1]), 0.1);  // sliding
  for (size_t b = 0; b < straight.bodies().size(); ++b) {
    EXPECT_EQ(resumed.bodies()[b]->x(), straight.bodies()[b]->x()) << b;
    EXPECT_EQ(resumed.bodies()[b]->v(), straight.bodies()[b]->v()) << b;
  }
}
