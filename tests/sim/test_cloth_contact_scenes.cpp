// Cloth–cloth contact end to end: the shipped contact scenes at low resolution, every step checked for
// intersections by the exact checker, with every solver that keeps trial points admissible.
#include <mgcloth/collision/intersections.hpp>
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/sim/simulator.hpp>

#include "resume_fixture.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

using namespace mgcloth;
namespace fs = std::filesystem;

namespace {

Json shipped_json(const std::string& name, int vertices_per_cloth, int frames) {
  const std::string path = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/" + name + ".json";
  Json j = load_json(path);
  for (auto& c : j["cloths"]) c["mesh"]["vertices"] = vertices_per_cloth;
  j["frames"] = frames;
  return j;
}

sim::Scene parse(const Json& j, const std::string& name = "test") {
  return sim::parse_scene(j, name, fs::path(MGCLOTH_SOURCE_DIR) / "scenes");
}

/// Runs the scene and checks every step: no intersection (the checker in the simulator and a second, direct call),
/// a positive distance between every pair within reach.
void run_checked(sim::Simulator& s, int frames) {
  for (int f = 0; f < frames; ++f) {
    for (const auto& st : s.advance_frame()) {
      ASSERT_EQ(st.intersections, 0) << "frame " << f + 1 << " step " << st.step;
      ASSERT_GE(st.contact_pairs, 0);
      ASSERT_GT(st.min_distance, 0.0) << "frame " << f + 1;
      // Detection runs in every step (at least the cache at its start) and is part of the step's time.
      ASSERT_GT(st.contact_detection_ms, 0.0);
      ASSERT_LE(st.contact_detection_ms, st.wall_ms);
      ASSERT_GE(st.check_ms, 0.0);
      ASSERT_LE(st.check_ms, st.wall_ms);
    }
    const auto& group = s.group(0);
    ASSERT_TRUE(group.cloth_contact());
    const VecX& x = group.x();
    ASSERT_EQ(collision::find_intersections(x, group.cloth_contact()->triangles(), 100, nullptr, SIZE_MAX,
                                            &group.cloth_contact()->joined_points())
                  .size(), 0u) << "frame " << f + 1;
  }
}

double max_z(const sim::ClothBody& c) { return as_columns(c.x()).row(2).maxCoeff(); }

}  // namespace

TEST(ClothContactScenes, StackedSheetsOnASphereStayInOrderAndNeverIntersect) {
  // Three of the five sheets keep the test short; they fall 1.5 cm apart onto each other and the sphere.
  Json j = shipped_json("layers_sphere", 200, 20);
  j["cloths"] = Json::array({j["cloths"][0], j["cloths"][1], j["cloths"][2]});
  sim::Simulator s(parse(j));
  run_checked(s, 20);
  // The sheets lie on the sphere in the order they fell, each on the one below.
  // (The highest point of each: the corners of the upper, rotated sheets hang lower than the lower sheets' own.)
  const auto cloths = s.cloths();
  for (size_t k = 1; k < cloths.size(); ++k) EXPECT_GT(max_z(*cloths[k]), max_z(*cloths[k - 1])) << k;
  // The top of the stack rests on the sphere at about the layers' thicknesses: no sheet went through another.
  const double top = as_columns(cloths.back()->x()).row(2).maxCoeff();
  EXPECT_GT(top, 0.25 + 2 * 0.002 * 0.5);
  EXPECT_LT(top, 0.25 + 0.05);
}

TEST(ClothContactScenes, AStripFallingOnTheFloorFoldsWithoutPassingThroughItself) {
  sim::Simulator s(parse(shipped_json("fold_floor", 500, 30)));
  run_checked(s, 30);
  // It has come down and piled up: much of it lies in layers near the floor, touching itself.
  const auto z = as_columns(s.cloths()[0]->x()).row(2);
  EXPECT_LT(z.maxCoeff(), 1.0);
}

// Every solver family that supports contact keeps it intersection-free (two sheets, one falling on the other).
TEST(ClothContactScenes, EverySolverThatSupportsContactKeepsItIntersectionFree) {
  for (const char* solver : {"fmg", "newton-direct", "newton-mg", "newton-ls"}) {
    Json j = shipped_json("layers_sphere", 150, 10);
    j["cloths"] = Json::array({j["cloths"][0], j["cloths"][1]});
    j["solver"]["name"] = solver;
    sim::Simulator s(parse(j));
    SCOPED_TRACE(solver);
    run_checked(s, 10);
    EXPECT_GT(max_z(*s.cloths()[1]), max_z(*s.cloths()[0]));
  }
}

TEST(ClothContactScenes, SolversThatCannotLimitTheirStepsAreRefused) {
  for (const char* solver : {"fas", "tr-dogleg", "rmtr", "pd-fmg", "pd-direct"}) {
    Json j = shipped_json("layers_sphere", 200, 2);
    j["solver"]["name"] = solver;
    if (std::string(solver).rfind("pd-", 0) == 0) j["energy_form"] = "projective";
    try {
      parse(j, "scene.json");
      ADD_FAILURE() << solver << " accepted";
    } catch (const InputError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(solver), std::string::npos) << m;
      EXPECT_NE(m.find("intersection-free"), std::string::npos) << m;
      EXPECT_NE(m.find("fmg"), std::string::npos) << m;
    }
  }
}

TEST(ClothContactScenes, ClothsThatStartIntersectingAreRefusedByTriangle) {
  Json j = shipped_json("layers_sphere", 200, 2);
  j["cloths"] = Json::array({j["cloths"][0], j["cloths"][1]});
  // The second sheet tilted through the first.
  j["cloths"][1]["transform"]["rotation_deg"] = Json::array({10.0, 0.0, 0.0});
  j["cloths"][1]["transform"]["translation"] = Json::array({-0.4, -0.4, 0.25});
  try {
    sim::Simulator s(parse(j, "scene.json"));
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("intersect at the start"), std::string::npos) << m;
    EXPECT_NE(m.find("cloth \"sheet1\" triangle"), std::string::npos) << m;
    EXPECT_NE(m.find("cloth \"sheet2\" triangle"), std::string::npos) << m;
  }
}

TEST(ClothContactScenes, BadContactParametersNameTheirPath) {
  for (const auto& [key, value] : std::vector<std::pair<std::string, Json>>{
           {"thickness", -1.0}, {"stiffness", 0.0}, {"ccd_separation", 1.5}, {"barrier_fraction", 2.0}, {"nonsense", 1}}) {
    Json j = shipped_json("layers_sphere", 200, 2);
    j["cloth_contact"][key] = value;
    try {
      parse(j, "scene.json");
      ADD_FAILURE() << key << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
}

// A run resumed from a step's state (as from checkpoint.bin: positions, velocities, the solver's carried state)
// repeats the uninterrupted run bit for bit with contact too: every step starts from contact stencils that depend on
// its start point alone.
TEST(ClothContactScenes, AResumedRunRepeatsTheUninterruptedOneBitForBit) {
  Json j = shipped_json("layers_sphere", 150, 8);
  j["cloths"] = Json::array({j["cloths"][0], j["cloths"][1]});
  const sim::Scene scene = parse(j);
  sim::Simulator straight(scene), first(scene);
  for (int f = 0; f < 8; ++f) straight.advance_frame();
  for (int f = 0; f < 5; ++f) first.advance_frame();
  auto resumed_ptr = sim::fixtures::resumed_from(scene, first);
  sim::Simulator& resumed = *resumed_ptr;
  for (int f = 5; f < 8; ++f) resumed.advance_frame();
  for (size_t b = 0; b < straight.bodies().size(); ++b) {
    EXPECT_EQ(resumed.bodies()[b]->x(), straight.bodies()[b]->x()) << b;
    EXPECT_EQ(resumed.bodies()[b]->v(), straight.bodies()[b]->v()) << b;
  }
}
