// The time-step robustness study (Kopaničáková 2019, §7.4.1, Fig. 10): the dt ladder, the pass criterion (7.1),
// and the search that halves dt until a solver converges at every step of the window.
#include <mgcloth/core/error.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/studies/timestep_bench.hpp>

#include <gtest/gtest.h>

#include <algorithm>

using namespace mgcloth;

namespace {

sim::Scene shell_scene(const std::string& name) {
  return sim::load_scene(std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_" + name + ".json");
}

studies::TimestepBenchOptions small_study(const std::string& solvers) {
  studies::TimestepBenchOptions opt;
  opt.level = 1;
  opt.solvers = studies::parse_solver_list(solvers);
  opt.threads = 1;
  return opt;
}

}  // namespace

TEST(TimestepBench, LadderHalvesFromMaxDownToMin) {
  studies::TimestepBenchOptions opt;
  EXPECT_EQ(studies::timestep_ladder(opt), (std::vector<double>{1, 0.5, 0.25, 0.125, 0.0625, 0.03125, 0.015625}));
  opt.min_dt = 0.2;  // not a power of two: the smallest halving above it is the last
  EXPECT_EQ(studies::timestep_ladder(opt), (std::vector<double>{1, 0.5, 0.25}));
  opt.min_dt = 0.0;
  EXPECT_THROW(studies::timestep_ladder(opt), InputError);
  opt.min_dt = 2.0;
  EXPECT_THROW(studies::timestep_ladder(opt), InputError);
}

TEST(TimestepBench, StallPassesOnlyAtTheLimitingAccuracy) {
  solvers::SolveReport r;
  r.status = "stalled";
  r.initial_grad_norm = 1.0;
  r.grad_norm = 1e-6;
  EXPECT_TRUE(studies::meets_criterion(r, 1e-5));
  r.grad_norm = 1e-2;
  EXPECT_FALSE(studies::meets_criterion(r, 1e-5));
  EXPECT_TRUE(studies::meets_criterion(r, 1e-5, 5e-2));
  r.status = "max_iters";
  r.grad_norm = 1e-9;
  EXPECT_FALSE(studies::meets_criterion(r, 1e-5));
  r.converged = true;
  r.status = "converged";
  EXPECT_TRUE(studies::meets_criterion(r, 1e-5));
}

// The Trampoline is nearly linear: the trust region converges at dt = 1, so nothing smaller is tried.
TEST(TimestepBench, TrustRegionPassesTheTrampolineAtOneSecond) {
  studies::TimestepBenchOptions opt = small_study("tr-dogleg");
  opt.window = 2.0;
  int progress_calls = 0;
  const auto rows = studies::run_timestep_bench({shell_scene("trampoline")}, opt,
                                            [&](const std::vector<studies::TimestepBenchRow>&) { ++progress_calls; });
  ASSERT_EQ(rows.size(), 1u);
  const auto& r = rows[0];
  EXPECT_TRUE(r.passed) << r.status;
  EXPECT_EQ(r.time_step, 1.0);
  EXPECT_EQ(r.steps, 2);
  EXPECT_EQ(r.steps_run, 2);
  EXPECT_EQ(r.failed_step, 0);
  EXPECT_EQ(r.status, "converged");
  EXPECT_EQ(r.dofs, 147);
  EXPECT_GT(r.iterations, 0);
  EXPECT_EQ(progress_calls, 1);
  const auto summary = studies::timestep_bench_summary(rows);
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary[0].largest_dt, 1.0);
}

// Three damped Newton iterations never reach ‖g‖ < 1e-7: every dt of the ladder is tried and fails at step 1.
TEST(TimestepBench, AFailingSolverTriesEverySmallerStep) {
  studies::TimestepBenchOptions opt = small_study("newton-damped");
  opt.max_iters = 3;
  opt.min_dt = 0.25;
  opt.window = 0.5;
  const auto rows = studies::run_timestep_bench({shell_scene("drooping")}, opt);
  ASSERT_EQ(rows.size(), 3u);
  const double dts[] = {1.0, 0.5, 0.25};
  const int steps[] = {1, 1, 2};
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].time_step, dts[i]);
    EXPECT_EQ(rows[i].steps, steps[i]);
    EXPECT_FALSE(rows[i].passed);
    EXPECT_EQ(rows[i].failed_step, 1);
    EXPECT_EQ(rows[i].steps_run, 1);
    EXPECT_EQ(rows[i].status, "max_iters");
    EXPECT_EQ(rows[i].iterations, 3);
  }
  EXPECT_EQ(studies::timestep_bench_summary(rows)[0].largest_dt, 0.0);
}

// RMTR needs two levels and a level-1 shell has one: that solver's row says so, once (a smaller step cannot help),
// and the study goes on to the next solver instead of ending.
TEST(TimestepBench, ASolverThatCannotRunIsRecordedAndTheStudyGoesOn) {
  studies::TimestepBenchOptions opt = small_study("rmtr,tr-dogleg");
  opt.window = 1.0;
  const auto rows = studies::run_timestep_bench({shell_scene("trampoline")}, opt);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].solver, "rmtr");
  EXPECT_EQ(rows[0].status, "error");
  EXPECT_FALSE(rows[0].passed);
  EXPECT_NE(rows[0].message.find("two levels"), std::string::npos) << rows[0].message;
  EXPECT_EQ(rows[1].solver, "tr-dogleg");
  EXPECT_TRUE(rows[1].passed) << rows[1].status;
  const auto summary = studies::timestep_bench_summary(rows);
  ASSERT_EQ(summary.size(), 2u);
  EXPECT_EQ(summary[0].largest_dt, 0.0);
  EXPECT_EQ(summary[1].largest_dt, 1.0);
}

// Sixty line-search Newton iterations are too few for the Drooping's first step at dt = 1 (the cloth falls far), and
// enough once dt is small: the search halves dt until a try passes, and stops there.
TEST(TimestepBench, SearchStopsAtTheFirstPassingStep) {
  studies::TimestepBenchOptions opt = small_study("newton-ls");
  opt.max_iters = 60;
  opt.window = 0.25;
  const auto rows = studies::run_timestep_bench({shell_scene("drooping")}, opt);
  ASSERT_GE(rows.size(), 2u);
  EXPECT_FALSE(rows.front().passed);
  EXPECT_TRUE(rows.back().passed) << rows.back().status;
  for (size_t i = 0; i + 1 < rows.size(); ++i) EXPECT_FALSE(rows[i].passed) << rows[i].time_step;
  EXPECT_EQ(studies::timestep_bench_summary(rows)[0].largest_dt, rows.back().time_step);
  const std::string csv = studies::timestep_bench_csv(rows);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), static_cast<long>(rows.size()) + 1);
}

// An interrupted study resumes from its rows: the ones it has are taken as they are, a try that the try cap would
// have cut is run again, and the cap fails a try between steps.
TEST(TimestepBench, ResumesFromEarlierRowsAndCapsTries) {
  studies::TimestepBenchOptions opt = small_study("tr-dogleg");
  opt.window = 1.0;
  const sim::Scene trampoline = shell_scene("trampoline");
  std::vector<studies::TimestepBenchRow> previous = studies::run_timestep_bench({trampoline}, opt);
  ASSERT_EQ(previous.size(), 1u);
  previous[0].iterations = -7;  // marks the row: a rerun would count its iterations again
  const auto round_trip = studies::timestep_bench_rows(studies::timestep_bench_json(previous, opt));
  EXPECT_EQ(studies::run_timestep_bench({trampoline}, opt, {}, round_trip)[0].iterations, -7);

  opt.max_try_seconds = 1e-9;  // the earlier try ran longer than this: run again
  auto rows = studies::run_timestep_bench({trampoline}, opt, {}, previous);
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_GT(rows[0].iterations, 0);
  EXPECT_TRUE(rows[0].passed);  // one step: the first step always runs

  opt.window = 2.0;
  opt.min_dt = 1.0;
  rows = studies::run_timestep_bench({trampoline}, opt);
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_FALSE(rows[0].passed);
  EXPECT_EQ(rows[0].status, "try_time_limit");
  EXPECT_EQ(rows[0].failed_step, 2);
  EXPECT_EQ(rows[0].steps_run, 1);
}

TEST(TimestepBench, RejectsSceneWithoutShellsAndBadOptions) {
  studies::TimestepBenchOptions opt = small_study("tr-dogleg");
  sim::Scene no_shells = shell_scene("trampoline");
  no_shells.shells.clear();
  EXPECT_THROW(studies::run_timestep_bench({no_shells}, opt), InputError);
  opt.window = -1.0;
  EXPECT_THROW(studies::run_timestep_bench({shell_scene("trampoline")}, opt), InputError);
}
