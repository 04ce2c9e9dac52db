// The benchmark library behind `mgcloth bench`: solver spec strings, the relative energy error, the state cache,
// and one tiny convergence run.
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/studies/convergence.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <unistd.h>

using namespace mgcloth;
namespace fs = std::filesystem;

TEST(SolverSpec, NameAlone) {
  const auto s = studies::parse_solver_spec("newton");
  EXPECT_EQ(s.label, "newton");
  EXPECT_EQ(s.config.name, "newton");
  EXPECT_TRUE(s.config.params.is_object());
  EXPECT_TRUE(s.config.params.empty());
}

TEST(SolverSpec, ParametersAreJsonScalarsOrUnquotedStrings) {
  const std::string spec = "fmg@hessian_update=step@residual_levels=2@tol=1e-3@psd=false@name=\"x\"@raw=\"y";
  const auto s = studies::parse_solver_spec(spec);
  EXPECT_EQ(s.label, spec);
  EXPECT_EQ(s.config.name, "fmg");
  EXPECT_EQ(s.config.params.at("hessian_update"), "step");
  EXPECT_TRUE(s.config.params.at("residual_levels").is_number_integer());
  EXPECT_EQ(s.config.params.at("residual_levels"), 2);
  EXPECT_DOUBLE_EQ(s.config.params.at("tol").get<double>(), 1e-3);
  EXPECT_EQ(s.config.params.at("psd"), false);
  EXPECT_EQ(s.config.params.at("name"), "x");
  EXPECT_EQ(s.config.params.at("raw"), "\"y");  // not valid JSON: taken as it is
  EXPECT_EQ(studies::parse_solver_spec("newton@linear_solver=\"cholmod\"").config.params.at("linear_solver"), "cholmod");
  EXPECT_EQ(studies::parse_solver_spec("newton@linear_solver=pcg-jacobi").config.params.at("linear_solver"), "pcg-jacobi");
}

TEST(SolverSpec, ListsSplitOnCommasAndKeepEachSpecAsItsLabel) {
  const auto list = studies::parse_solver_list("newton, newton@linear_solver=pcg-mg ,fmg");
  ASSERT_EQ(list.size(), 3u);
  EXPECT_EQ(list[0].label, "newton");
  EXPECT_EQ(list[1].label, "newton@linear_solver=pcg-mg");
  EXPECT_EQ(list[1].config.params.at("linear_solver"), "pcg-mg");
  EXPECT_EQ(list[2].config.name, "fmg");
}

TEST(SolverSpec, MalformedSpecsAreInputErrorsNamingTheSpec) {
  for (const char* bad : {"", "@a=1", "newton@", "newton@=1", "newton@a", "newton@a=", "newton@a=1@a=2", "newton@a=[1]",
                          "newton@a={}"}) {
    try {
      (void)studies::parse_solver_spec(bad);
      ADD_FAILURE() << "accepted \"" << bad << "\"";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("\"") + bad + "\""), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(studies::parse_solver_list(""), InputError);
  EXPECT_THROW(studies::parse_solver_list("newton,,fmg"), InputError);
  EXPECT_THROW(studies::parse_solver_list("newton,"), InputError);
}

TEST(SolverSpec, CheckUsesTheFactorysMessages) {
  EXPECT_FALSE(studies::check_solver_spec(studies::parse_solver_spec("newton@linear_solver=cholmod")));
  const auto message = [](const std::string& spec) {
    try {
      (void)studies::check_solver_spec(studies::parse_solver_spec(spec));
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  EXPECT_NE(message("newtn").find("unknown solver \"newtn\""), std::string::npos) << message("newtn");
  EXPECT_NE(message("newton@linear_slver=cholmod").find("linear_slver: unknown key"), std::string::npos)
      << message("newton@linear_slver=cholmod");
  EXPECT_NE(message("newton@linear_solver=nope").find("nope"), std::string::npos);
}

TEST(RelativeEnergyError, IsOneAtTheStartAndZeroAtTheMinimum) {
  for (const auto& [e0, emin] : {std::pair{1.440284171670333, 1.4323657962256815}, std::pair{-3.0e5, -3.1e5},
                                std::pair{1e-300, -1e-300}, std::pair{0.1 + 0.2, 0.3 - 1e-17}})
    EXPECT_EQ(studies::relative_energy_error(e0, e0, emin), 1.0) << e0 << " " << emin;
  EXPECT_EQ(studies::relative_energy_error(2.0, 3.0, 2.0), 0.0);
  EXPECT_DOUBLE_EQ(studies::relative_energy_error(2.5, 3.0, 2.0), 0.5);
  EXPECT_LT(studies::relative_energy_error(1.9, 3.0, 2.0), 0.0);  // below E*: negative, kept as is
  EXPECT_TRUE(std::isnan(studies::relative_energy_error(1.0, 2.0, 2.0)));  // E_0 = E*: nothing to measure
  EXPECT_TRUE(std::isnan(studies::relative_energy_error(1.0, 1.0, 2.0)));
}

TEST(RelativeEnergyError, TimeToALevelIsTheFirstRowReachingIt) {
  const std::vector<studies::ConvergenceRow> rows{{"a", 0, 0.0, 3.0, 1.0, 1.0},   {"a", 1, 0.5, 2.1, 1.0, 0.05},
                                              {"b", 0, 0.0, 3.0, 1.0, 1.0},   {"b", 1, 0.2, 2.0, 1.0, 1e-5},
                                              {"a", 2, 0.9, 2.0, 1.0, 1e-3}, {"a", 3, 1.2, 2.0, 1.0, 2e-3}};
  EXPECT_EQ(studies::time_to_error(rows, "a", 1e-2).value_or(-1.0), 0.9);
  EXPECT_EQ(studies::time_to_error(rows, "a", 1e-3).value_or(-1.0), 0.9);
  EXPECT_FALSE(studies::time_to_error(rows, "a", 1e-4));
  EXPECT_EQ(studies::time_to_error(rows, "b", 1e-4).value_or(-1.0), 0.2);
  EXPECT_FALSE(studies::time_to_error(rows, "c", 1.0));
}

namespace {
sim::Scene tiny_scene(int vertices) {
  const Json j = parse_json(R"({ "cloths": [ { "name": "sheet", "mesh": { "vertices": 100 },
      "transform": { "translation": [-0.5, -0.5, 1.0] }, "pins": [ { "points": [[0, 1], [1, 1]] } ] } ],
      "solver": { "rel_grad": 1e-4 } })", "tiny.json");
  return studies::with_vertex_count(sim::parse_scene(j, "tiny.json", "."), vertices);
}
fs::path temp_file(const std::string& name) {
  return fs::temp_directory_path() / (name + std::to_string(::getpid()));  // builds may run the suite concurrently
}
}  // namespace

TEST(VertexCount, SetsEveryGeneratedMeshAndRejectsFileMeshes) {
  EXPECT_EQ(tiny_scene(150).cloths[0].mesh.rectangle.target_vertices, 150);
  sim::Scene s = tiny_scene(150);
  s.cloths.push_back(s.cloths[0]);
  s.cloths[1].mesh.generator = "tube";
  s = studies::with_vertex_count(s, 300);
  EXPECT_EQ(s.cloths[0].mesh.rectangle.target_vertices, 300);
  EXPECT_EQ(s.cloths[1].mesh.tube.target_vertices, 300);
  EXPECT_THROW(studies::with_vertex_count(s, 3), InputError);
  s.cloths[1].mesh.file = "/some/mesh.obj";
  EXPECT_THROW(studies::with_vertex_count(s, 300), InputError);
}

TEST(StateCache, RoundTripsAndIgnoresOtherKeysAndBrokenFiles) {
  const fs::path file = temp_file("mgcloth_state_cache_test");
  studies::SimState st;
  st.frame = 3;
  st.step = 6;
  st.x = {VecX::LinSpaced(9, 0.0, 1.0), VecX::Constant(3, 0.25)};
  st.v = {VecX::Constant(9, -1.5), VecX::LinSpaced(3, 1.0, 2.0)};
  const Json key = {{"scene", "a"}, {"steps", 6}};
  EXPECT_FALSE(studies::load_state_cache(file, key));  // missing
  studies::save_state_cache(file, key, st);
  const auto back = studies::load_state_cache(file, key);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->frame, 3);
  EXPECT_EQ(back->step, 6);
  ASSERT_EQ(back->x.size(), 2u);
  for (size_t c = 0; c < 2; ++c) {
    EXPECT_EQ(back->x[c], st.x[c]);
    EXPECT_EQ(back->v[c], st.v[c]);
  }
  EXPECT_FALSE(studies::load_state_cache(file, Json{{"scene", "a"}, {"steps", 5}}));
  const std::string bytes = read_file(file);
  write_file_atomic(file, bytes.substr(0, bytes.size() - 8));  // truncated
  EXPECT_FALSE(studies::load_state_cache(file, key));
  write_file_atomic(file, "not a cache\n");
  EXPECT_FALSE(studies::load_state_cache(file, key));
  fs::remove(file);
}

TEST(Convergence, TinyStepConvergesFromTheSameStartAndCachesItsState) {
  const fs::path cache = temp_file("mgcloth_convergence_cache");
  fs::remove(cache);
  studies::ConvergenceOptions opt;
  opt.step = 2;
  opt.solvers = studies::parse_solver_list("newton,newton@linear_solver=pcg-jacobi");
  opt.budget_seconds = 5.0;
  opt.max_iters = 40;
  opt.threads = 1;
  opt.state_cache = cache.string();
  const sim::Scene scene = tiny_scene(120);
  const auto a = studies::run_convergence(scene, opt);
  EXPECT_EQ(a.start_state, "simulated");
  EXPECT_EQ(a.cloth, "sheet");
  ASSERT_EQ(a.references.size(), 1u);
  EXPECT_EQ(a.references[0].form, "elastic");
  EXPECT_TRUE(a.references[0].reached) << a.references[0].rel_grad;
  EXPECT_GT(a.references[0].initial_energy, a.references[0].energy);
  ASSERT_EQ(a.summaries.size(), 2u);
  for (const auto& s : a.summaries) {
    EXPECT_LT(std::abs(s.final_error), 1e-6) << s.solver;
    EXPECT_TRUE(s.time_to[2]) << s.solver;
  }
  // Both start at the same x0: the same E_0, error exactly 1.
  for (const auto& label : {"newton", "newton@linear_solver=pcg-jacobi"}) {
    const auto it = std::find_if(a.rows.begin(), a.rows.end(), [&](const auto& r) { return r.solver == label; });
    ASSERT_NE(it, a.rows.end());
    EXPECT_EQ(it->iteration, 0);
    EXPECT_EQ(it->rel_energy_error, 1.0);
    EXPECT_EQ(it->energy, a.references[0].initial_energy);
  }
  EXPECT_EQ(studies::convergence_csv(a).rfind("solver,iteration,wall_s,energy,grad_norm,rel_energy_error\n", 0), 0u);
  const Json j = studies::to_json(a, opt);
  EXPECT_EQ(j.at("references")[0].at("energy").get<double>(), a.references[0].energy);
  EXPECT_TRUE(j.at("solvers")[0].at("time_to").contains("1e-04"));

  // Again from the cache: the same step, so the same start point and E*.
  opt.solvers = studies::parse_solver_list("newton");
  const auto b = studies::run_convergence(scene, opt);
  EXPECT_EQ(b.start_state, "cache");
  EXPECT_EQ(b.references[0].initial_energy, a.references[0].initial_energy);
  EXPECT_EQ(b.references[0].energy, a.references[0].energy);
  // E* came from the reference cache (the solve is not repeated: its recorded time is the first run's).
  EXPECT_TRUE(fs::exists(cache.string() + ".references"));
  EXPECT_EQ(b.references[0].seconds, a.references[0].seconds);
  EXPECT_EQ(b.references[0].iterations, a.references[0].iterations);
  // A stricter reference is another key: solved again, and both stay cached.
  opt.reference_rel_grad = 1e-11;
  const auto b2 = studies::run_convergence(scene, opt);
  EXPECT_NE(b2.references[0].seconds, a.references[0].seconds);
  opt.reference_rel_grad = 1e-10;
  EXPECT_EQ(studies::run_convergence(scene, opt).references[0].seconds, a.references[0].seconds);
  // Another vertex count does not match the cached state.
  const auto c = studies::run_convergence(tiny_scene(100), opt);
  EXPECT_EQ(c.start_state, "simulated");
  fs::remove(cache);
  fs::remove(cache.string() + ".references");
}

TEST(Convergence, BadOptionsFailBeforeSimulating) {
  studies::ConvergenceOptions opt;
  opt.solvers = studies::parse_solver_list("newton");
  opt.step = 0;
  EXPECT_THROW(studies::run_convergence(tiny_scene(100), opt), InputError);
  opt.step = 1;
  opt.solvers = studies::parse_solver_list("newton,nope");
  EXPECT_THROW(studies::run_convergence(tiny_scene(100), opt), InputError);
  opt.solvers.clear();
  EXPECT_THROW(studies::run_convergence(tiny_scene(100), opt), InputError);
}

namespace {

// Only the energy forms that some solver minimizes get an E*: a Projective Dynamics comparison does not pay for
// the elastic reference, and every relative error is measured against its own form's E*.
TEST(Convergence, ReferencesOnlyForTheFormsBenchmarked) {
  studies::ConvergenceOptions opt;
  opt.step = 2;
  opt.solvers = studies::parse_solver_list("pd-direct,pd-gs-chebyshev");
  opt.budget_seconds = 2.0;
  opt.max_iters = 200;
  opt.threads = 1;
  opt.pd_reference_max_iters = 2000;
  const auto r = studies::run_convergence(tiny_scene(120), opt);
  ASSERT_EQ(r.references.size(), 1u);
  EXPECT_EQ(r.references[0].form, "projective");
  ASSERT_EQ(r.summaries.size(), 2u);
  for (const auto& s : r.summaries) {
    EXPECT_EQ(s.form, "projective");
    EXPECT_TRUE(std::isfinite(s.final_error)) << s.solver;
    EXPECT_GT(s.final_error, -1e-6) << s.solver;  // E* is the lowest minimum seen (polished if a solver went below)
  }
}

}  // namespace

// `bench convergence --body NAME` freezes the step of any body of the scene, solved on its own.
TEST(Convergence, TheBenchmarkedBodyIsChosenByName) {
  Json j = parse_json(R"({ "cloths": [
      { "name": "sheet", "mesh": { "vertices": 100 }, "transform": { "translation": [-0.5, -0.5, 1.0] },
        "pins": [ { "points": [[0, 1], [1, 1]] } ] },
      { "name": "flag", "mesh": { "vertices": 60 }, "transform": { "translation": [1.0, -0.5, 1.0] },
        "pins": [ { "points": [[0, 1]] } ] } ],
      "solver": { "rel_grad": 1e-4 } })", "two.json");
  const sim::Scene scene = sim::parse_scene(j, "two.json", ".");
  studies::ConvergenceOptions opt;
  opt.solvers = studies::parse_solver_list("newton");
  opt.budget_seconds = 5.0;
  opt.max_iters = 40;
  opt.threads = 1;
  opt.body = "flag";
  const auto r = studies::run_convergence(scene, opt);
  EXPECT_EQ(r.cloth, "flag");
  const sim::Simulator s(scene);
  EXPECT_EQ(r.vertices, s.bodies()[1]->num_points());
  ASSERT_EQ(r.summaries.size(), 1u);
  EXPECT_LT(std::abs(r.summaries[0].final_error), 1e-6);
  opt.body = "skirt";
  try {
    studies::run_convergence(scene, opt);
    ADD_FAILURE() << "an unknown body must be refused";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no body named \"skirt\" (its bodies: sheet, flag)"), std::string::npos) << e.what();
  }
}

// A shell is a body like a cloth: its step can be the frozen one, also after simulated steps, and the state at the
// start of the step (cached or not) holds every body, the shell's included.
TEST(Convergence, AShellsStepCanBeTheFrozenOne) {
  Json j = parse_json(R"({ "gravity": [0, 0, -9.81], "time_step": 0.5,
      "cloths": [ { "name": "sheet", "mesh": { "vertices": 60 }, "pins": [ { "points": [[0, 1], [1, 1]] } ] } ],
      "shells": [ { "name": "plate", "control_mesh": { "generator": "rectangle", "cells_u": 2, "cells_v": 2 },
                    "level": 2, "boundary": [ { "type": "fixed", "sides": "all" } ] } ],
      "solver": { "name": "tr-dogleg", "rel_grad": 1e-6, "max_iters": 200 } })", "both.json");
  const sim::Scene scene = sim::parse_scene(j, "both.json", ".");
  studies::ConvergenceOptions opt;
  opt.solvers = studies::parse_solver_list("tr-dogleg");
  opt.step = 2;
  opt.budget_seconds = 5.0;
  opt.max_iters = 100;
  opt.threads = 1;
  opt.body = "plate";
  const fs::path cache = fs::temp_directory_path() / ("mgcloth_shell_state_" + std::to_string(::getpid()) + ".bin");
  opt.state_cache = cache.string();
  const sim::Simulator s(scene);
  for (const char* start : {"simulated", "cache"}) {
    const auto r = studies::run_convergence(scene, opt);
    EXPECT_EQ(r.start_state, start);
    EXPECT_EQ(r.cloth, "plate");
    EXPECT_EQ(r.vertices, s.bodies()[1]->num_points());
    ASSERT_EQ(r.summaries.size(), 1u);
    EXPECT_LT(std::abs(r.summaries[0].final_error), 1e-6) << r.summaries[0].status;
  }
  fs::remove(cache);
  fs::remove(cache.string() + ".references");
}

namespace {
/// The first `sheets` sheets of the shipped layered drape, `vertices` each (with_vertex_count: per cloth).
sim::Scene layers(size_t sheets, Index vertices) {
  const std::string file = std::string(MGCLOTH_SOURCE_DIR) + "/scenes/layers_sphere.json";
  Json j = load_json(file);
  j["cloths"] = Json(std::vector<Json>(j["cloths"].begin(), j["cloths"].begin() + static_cast<long>(sheets)));
  return studies::with_vertex_count(sim::parse_scene(j, file, fs::path(file).parent_path()), vertices);
}
}  // namespace

// Cloth contact couples the sheets, so the frozen problem is their joint step, contact term included, the same for
// every solver; each run keeps the contact guarantee (checked by the exact intersection checker at its end).
TEST(Convergence, AContactSceneFreezesTheJointStepOfItsSheets) {
  const sim::Scene scene = layers(2, 150);
  studies::ConvergenceOptions opt;
  opt.step = 5;  // the upper sheet lies on the lower one, which lies on the sphere
  opt.solvers = studies::parse_solver_list("fmg,newton-direct,newton-amg");
  opt.budget_seconds = 5.0;
  // Each reaches 1e-3 within 200 iterations (under 1 s). With contact the energy is not convex: FMG with its
  // refined line searches ends here in another minimum than Newton's and polishes into E* more slowly.
  opt.max_iters = 200;
  opt.threads = 1;
  opt.body = "sheet2";  // any sheet: both are in the group
  const auto r = studies::run_convergence(scene, opt);
  EXPECT_TRUE(r.cloth_contact);
  EXPECT_EQ(r.cloth, "sheet2");
  EXPECT_EQ(r.bodies, (std::vector<std::string>{"sheet1", "sheet2"}));
  const sim::Simulator s(scene);
  ASSERT_EQ(s.bodies().size(), 2u);
  EXPECT_EQ(s.bodies()[0]->num_points(), s.bodies()[1]->num_points());  // --vertices: each sheet's own count
  EXPECT_EQ(r.vertices, s.bodies()[0]->num_points() + s.bodies()[1]->num_points());
  EXPECT_GT(r.start.pairs, 0) << "the sheets must touch at x0, or the test measures nothing about contact";
  EXPECT_EQ(r.start.intersections, 0);
  EXPECT_GT(r.start.min_distance, 0.0);
  ASSERT_EQ(r.references.size(), 1u);
  EXPECT_TRUE(r.references[0].reached) << r.references[0].rel_grad;
  ASSERT_EQ(r.summaries.size(), 3u);
  for (const auto& sm : r.summaries) {
    SCOPED_TRACE(sm.solver);
    EXPECT_TRUE(sm.time_to[1]) << sm.status << ", final error " << sm.final_error;  // 1e-3
    EXPECT_EQ(sm.contact.intersections, 0);
    EXPECT_GT(sm.contact.pairs, 0);
    EXPECT_GT(sm.contact.min_distance, 0.0);
  }
  // FMG's collision detection along its steps is timed apart from its other phases.
  const auto& fmg_counters = r.summaries[0].counters;
  const auto limit = std::find_if(fmg_counters.begin(), fmg_counters.end(),
                                  [](const auto& c) { return c.first == "step_limit_ms"; });
  ASSERT_NE(limit, fmg_counters.end());
  EXPECT_GT(limit->second, 0.0);
  for (const auto& label : {"fmg", "newton-direct", "newton-amg"}) {  // the same x0: the same E_0
    const auto it = std::find_if(r.rows.begin(), r.rows.end(), [&](const auto& row) { return row.solver == label; });
    ASSERT_NE(it, r.rows.end());
    EXPECT_EQ(it->energy, r.references[0].initial_energy) << label;
  }
  const Json j = studies::to_json(r, opt);
  EXPECT_EQ(j.at("vertices").get<Index>(), r.vertices);
  EXPECT_EQ(j.at("contact_at_x0").at("intersections").get<Index>(), 0);
  EXPECT_EQ(j.at("solvers")[0].at("contact_at_end").at("intersections").get<Index>(), 0);
}

// Solvers that do not keep their trial points within the contact's step limits are refused by name, with the list
// of those that do, before anything is simulated (no state is cached).
TEST(Convergence, AContactSceneRefusesSolversThatCannotKeepContact) {
  const fs::path cache = temp_file("mgcloth_contact_refusal_cache");
  fs::remove(cache);
  studies::ConvergenceOptions opt;
  opt.step = 5;
  opt.solvers = studies::parse_solver_list("fmg,rmtr,fas");
  opt.state_cache = cache.string();
  try {
    studies::run_convergence(layers(2, 150), opt);
    ADD_FAILURE() << "rmtr and fas must be refused on a contact scene";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("solvers \"rmtr\", \"fas\" do not keep their trial points intersection-free"), std::string::npos) << m;
    EXPECT_NE(m.find("those that do: fmg"), std::string::npos) << m;
    EXPECT_NE(m.find("newton-direct"), std::string::npos) << m;
    EXPECT_NE(m.find("layers_sphere.json"), std::string::npos) << m;
  }
  EXPECT_FALSE(fs::exists(cache));
}
