#include <mgcloth/core/error.hpp>
#include <mgcloth/sim/scene.hpp>

#include <gtest/gtest.h>

using namespace mgcloth;

namespace {
Json minimal() {
  return Json::parse(R"({
    "cloths": [ { "mesh": { "generator": "rectangle", "vertices": 100 } } ]
  })");
}
std::string error_of(const Json& j) {
  try {
    sim::parse_scene(j, "scene.json", ".");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(Scene, DefaultsAreFilledAndResolvedSceneRoundTrips) {
  const auto s = sim::parse_scene(minimal(), "scene.json", ".");
  EXPECT_EQ(s.cloths.size(), 1u);
  EXPECT_NEAR(s.cloths[0].material.youngs_modulus, 1e6, 0);
  EXPECT_EQ(s.solver.name, "fmg");
  const Json resolved = sim::to_json(s);
  EXPECT_TRUE(resolved["solver"]["params"].contains("matrix_update"));
  // The resolved scene is itself a valid scene that resolves to the same thing.
  const auto again = sim::parse_scene(resolved, "resolved.json", ".");
  EXPECT_EQ(sim::to_json(again), resolved);
}

// A scene that sets no stop rule gets the accuracy every shipped scene asks for, which fmg reaches in a few cycles
// per step (the library's 1e-6 within 100 iterations made fmg stop at its limit: bench/RESULTS.md, "Solver
// defaults"), and the consistent bending model, whose rigidity is the material's on any mesh.
TEST(Scene, ASceneWithoutAStopRuleGetsTheShippedScenesAccuracy) {
  const auto s = sim::parse_scene(minimal(), "scene.json", ".");
  EXPECT_EQ(s.solver.stop.rel_grad, 1e-3);
  EXPECT_EQ(s.solver.stop.max_iters, 200);
  EXPECT_EQ(s.cloths[0].material.bending, physics::BendingModel::Quadratic);
  const Json resolved = sim::to_json(s);
  EXPECT_EQ(resolved["solver"]["rel_grad"], 1e-3);
  EXPECT_EQ(resolved["cloths"][0]["material"]["bending"], "quadratic");
}

// The scene chooses the energy form; a solver that cannot minimize it is refused with what to do instead.
TEST(Scene, TheEnergyFormIsTheScenesAndASolverThatCannotMinimizeItIsRefused) {
  EXPECT_EQ(sim::parse_scene(minimal(), "scene.json", ".").energy_form, physics::EnergyForm::Elastic);
  Json j = minimal();
  j["solver"] = {{"name", "pd-fmg"}};
  const std::string e = error_of(j);
  EXPECT_NE(e.find("scene.json: solver \"pd-fmg\" cannot minimize the elastic energy form, only the projective one: "
                   "set \"energy_form\": \"projective\""), std::string::npos) << e;
  j["energy_form"] = "projective";
  const auto s = sim::parse_scene(j, "scene.json", ".");
  EXPECT_EQ(s.energy_form, physics::EnergyForm::Projective);
  EXPECT_EQ(sim::to_json(s)["energy_form"], "projective");
  j["solver"]["name"] = "newton-direct";  // Newton minimizes either form
  EXPECT_EQ(sim::parse_scene(j, "scene.json", ".").energy_form, physics::EnergyForm::Projective);
  j["energy_form"] = "projected";
  EXPECT_NE(error_of(j).find("energy_form"), std::string::npos) << error_of(j);
  j = Json::parse(R"({ "energy_form": "projective", "shells": [ { "control_mesh": { "generator": "rectangle",
                       "width": 1.0, "height": 1.0, "cells_u": 2, "cells_v": 2 } } ] })");
  EXPECT_NE(error_of(j).find("energy_form: shells have no projective form"), std::string::npos) << error_of(j);
}

TEST(Scene, UnknownKeysAreRejectedByPath) {
  Json j = minimal();
  j["cloths"][0]["material"] = {{"youngs_modulis", 1e6}};
  EXPECT_NE(error_of(j).find("scene.json: cloths[0].material.youngs_modulis: unknown key"), std::string::npos) << error_of(j);
  j = minimal();
  j["solvr"] = Json::object();
  EXPECT_NE(error_of(j).find("solvr: unknown key"), std::string::npos);
  j = minimal();
  j["solver"] = {{"params", {{"armijoo", 0.1}}}};
  EXPECT_NE(error_of(j).find("solver.params.armijoo: unknown key"), std::string::npos) << error_of(j);
}

TEST(Scene, BadValuesNameTheField) {
  Json j = minimal();
  j["cloths"][0]["material"] = {{"youngs_modulus", -5.0}};
  EXPECT_NE(error_of(j).find("cloths[0].material.youngs_modulus: must be in"), std::string::npos) << error_of(j);
  j = minimal();
  j["time_step"] = "fast";
  EXPECT_NE(error_of(j).find("time_step: expected a number"), std::string::npos) << error_of(j);
  j = minimal();
  j["cloths"][0]["material"] = {{"poisson_ratio", 0.7}};
  EXPECT_NE(error_of(j).find("poisson_ratio"), std::string::npos);
  j = minimal();
  j["obstacles"] = Json::array({{{"shape", {{"type", "cone"}}}}});
  EXPECT_NE(error_of(j).find("obstacles[0].shape.type: unknown value \"cone\""), std::string::npos) << error_of(j);
  j = minimal();
  j["cloths"] = Json::array();
  EXPECT_NE(error_of(j).find("cloths"), std::string::npos);
  j = minimal();
  j["gravity"] = {0, 0};
  EXPECT_NE(error_of(j).find("gravity: expected 3 numbers"), std::string::npos);
  j = minimal();
  j["cloths"].push_back(j["cloths"][0]);
  j["cloths"][0]["name"] = "a";
  j["cloths"][1]["name"] = "a";
  EXPECT_NE(error_of(j).find("duplicate cloth name"), std::string::npos);
  j = minimal();
  j["solver"] = {{"velocity_tol", -0.01}};
  EXPECT_NE(error_of(j).find("solver.velocity_tol: must be"), std::string::npos) << error_of(j);
  j = minimal();
  j["solver"] = {{"velocity_rms_tol", -0.01}};
  EXPECT_NE(error_of(j).find("solver.velocity_rms_tol: must be"), std::string::npos) << error_of(j);
}

// A velocity tolerance is off unless set, resolves with the scene, and becomes each step's Stop::step_tol.
TEST(Scene, TheVelocityToleranceIsOffUnlessSetAndRoundTrips) {
  EXPECT_EQ(sim::parse_scene(minimal(), "scene.json", ".").solver.velocity_tol, 0.0);
  Json j = minimal();
  j["solver"] = {{"velocity_tol", 0.005}};
  const auto s = sim::parse_scene(j, "scene.json", ".");
  EXPECT_EQ(s.solver.velocity_tol, 0.005);
  EXPECT_EQ(sim::to_json(s)["solver"]["velocity_tol"], 0.005);
  EXPECT_EQ(s.solver.velocity_rms_tol, 0.0);
  j["solver"] = {{"velocity_rms_tol", 0.003}};
  const auto r = sim::parse_scene(j, "scene.json", ".");
  EXPECT_EQ(r.solver.velocity_rms_tol, 0.003);
  EXPECT_EQ(sim::to_json(r)["solver"]["velocity_rms_tol"], 0.003);
}

// A misspelled key used to lose to the missing field it was meant to be ("cloths: a scene needs at least one
// cloth", "cloths[0].mesh: missing required field").
TEST(Scene, UnknownKeysAreReportedBeforeMissingOnes) {
  Json j = Json::parse(R"({"clths": [ { "mesh": {} } ]})");
  EXPECT_EQ(error_of(j), "scene.json: clths: unknown key (did you mean \"cloths\"?)");
  j = Json::parse(R"({"frmes": 10})");
  EXPECT_EQ(error_of(j), "scene.json: frmes: unknown key (did you mean \"frames\"?)");
  j = Json::parse(R"({"bogus": 1})");
  EXPECT_EQ(error_of(j), "scene.json: bogus: unknown key");
  j = Json::parse(R"({"cloths": [ { "mseh": {} } ]})");
  EXPECT_EQ(error_of(j), "scene.json: cloths[0].mseh: unknown key (did you mean \"mesh\"?)");
  j = Json::parse(R"({"cloths": [ { "mesh": {} } ], "obstacles": [ { "shape": { "type": "sphere", "raduis": 1 } } ]})");
  EXPECT_EQ(error_of(j), "scene.json: obstacles[0].shape.raduis: unknown key (did you mean \"radius\"?)");
  j = Json::parse(R"({"cloths": [ { "mesh": {} } ], "obstacles": [ { "shape": { "type": "sphere" } } ]})");
  EXPECT_EQ(error_of(j), "scene.json: obstacles[0].shape.radius: missing required field");
  j = minimal();
  j["cloths"][0]["material"] = {{"youngs_modulis", 1e6}};
  EXPECT_EQ(error_of(j), "scene.json: cloths[0].material.youngs_modulis: unknown key (did you mean \"youngs_modulus\"?)");
}

// "Invalid argument []" came from the filesystem library when the run created its folder.
TEST(Scene, EmptyOutputDirIsRejected) {
  Json j = minimal();
  j["output"] = {{"dir", ""}};
  EXPECT_EQ(error_of(j), "scene.json: output.dir: must not be empty (leave it out for the default \"out\")");
}

// Names go unquoted into stats.csv and into folder names: a comma, quote, newline or NUL broke the CSV's columns.
TEST(Scene, NamesThatWouldBreakCsvOrPathsAreRejected) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"a,b", "contains ','"},
      {"say \"hi\"", "contains '\"'"},
      {"two\nlines", "contains the control character 0x0a"},
      {std::string("nul\0byte", 8), "contains the control character 0x00"},
      {"tab\there", "contains the control character 0x09"},
      {"../up", "contains '/'"},
      {"..", "is a folder name"},
      {"", "is empty"},
      {std::string(65, 'x'), "is 65 bytes long"},
  };
  for (const auto& [name, why] : bad) {
    Json j = minimal();
    j["cloths"][0]["name"] = name;
    const std::string e = error_of(j);
    EXPECT_EQ(e.rfind("scene.json: cloths[0].name: " + Json(name).dump() + " " + why + ": a name goes unquoted", 0), 0u)
        << e;
    j = minimal();
    j["obstacles"] = Json::array({{{"name", name}, {"shape", {{"type", "plane"}}}}});
    EXPECT_NE(error_of(j).find("obstacles[0].name: "), std::string::npos) << error_of(j);
  }
  Json j = minimal();
  j["cloths"][0]["name"] = "Ärmel links (panel-3)";
  EXPECT_EQ(error_of(j), "");
}

TEST(Scene, MalformedJsonGivesLineAndColumn) {
  try {
    parse_json("{\n  \"frames\": 3,\n  \"cloths\": [ ,]\n}", "bad.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.json:3:"), std::string::npos) << e.what();
  }
  // NaN is not JSON: it is a syntax error, never a silently accepted value.
  EXPECT_THROW(parse_json("{\"time_step\": NaN}", "nan.json"), InputError);
}

TEST(Scene, MissingFileIsAnInputError) {
  EXPECT_THROW(sim::load_scene("/nonexistent/scene.json"), InputError);
}

TEST(Scene, ShippedScenesParse) {
  for (const char* name : {"drape_sphere", "hanging", "tablecloth", "rotating_sphere"}) {
    EXPECT_NO_THROW(sim::load_scene(std::string(MGCLOTH_SOURCE_DIR) + "/scenes/" + name + ".json")) << name;
  }
}

TEST(Scene, KeyframeTimesMustIncrease) {
  Json j = minimal();
  j["obstacles"] = Json::parse(R"([{ "shape": { "type": "sphere", "radius": 0.1 },
    "motion": { "type": "keyframes", "keys": [ { "time": 1.0 }, { "time": 0.5 } ] } }])");
  EXPECT_NE(error_of(j).find("obstacles[0].motion.keys[1].time: key times must increase"), std::string::npos) << error_of(j);
  j = minimal();
  j["cloths"][0]["pins"] = Json::parse(R"([{ "vertices": [0], "motion": { "type": "keyframes", "keys": [] } }])");
  EXPECT_NE(error_of(j).find("needs at least one key"), std::string::npos) << error_of(j);
}
