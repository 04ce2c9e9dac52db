// A run resumed from its checkpoint repeats the uninterrupted run bit for bit (README: "produces the same frames as
// an uninterrupted run"), for every solver that carries state from one step into the next (issue 25: fmg's frames
// differed by 1.6 mm after extending a finished 10-frame run to 20).
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/sim/checkpoint.hpp>

#include "cli_run.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

struct ResumeCase {
  const char* solver;
  const char* params;  ///< the solver's "params" object
  const char* label;   ///< the test's name
};

class Resume : public mgcloth::test::TempDirTest, public ::testing::WithParamInterface<ResumeCase> {
 protected:
  Resume() : TempDirTest("mgcloth_resume_") {}
  mgcloth::test::CliResult run(const fs::path& out, const std::string& extra) {
    return mgcloth::test::run_cli("run " + (dir / "scene.json").string() + " -q --threads 1 --out " + out.string() +
                                  " " + extra);
  }
  /// A hanging sheet (large motion, so that each step's solve takes several cycles), solved by c's solver.
  void write_scene(const ResumeCase& c, int frames) {
    std::ofstream(dir / "scene.json") << R"({ "frames": )" << frames << R"(, "cloths": [ { "name": "sheet", "mesh": {
        "generator": "rectangle", "vertices": 500, "unstructured": true },
        "pins": [ { "points": [[0, 1], [1, 1]] } ] } ],
      "energy_form": ")" << (std::string(c.solver).starts_with("pd-") ? "projective" : "elastic") << R"(",
      "solver": { "name": ")" << c.solver << R"(", "rel_grad": 1e-3, "params": )" << c.params << " } }";
  }
};

TEST_P(Resume, AFinishedRunExtendedByResumeIsTheUninterruptedRun) {
  const ResumeCase& c = GetParam();
  write_scene(c, 20);
  const fs::path whole = dir / "whole", parts = dir / "parts";
  auto r = run(whole, "");
  ASSERT_EQ(r.code, 0) << r.out;
  r = run(parts, "--frames 10");
  ASSERT_EQ(r.code, 0) << r.out;
  r = run(parts, "--resume");
  ASSERT_EQ(r.code, 0) << r.out;
  for (int f = 11; f <= 20; ++f) {
    const std::string name = fmt::format("frame_{:05d}.obj", f);
    EXPECT_TRUE(mgcloth::read_file(parts / name) == mgcloth::read_file(whole / name)) << name << " differs";
  }
  // Positions, velocities and what the solver carries into the next step.
  EXPECT_TRUE(mgcloth::read_file(parts / "checkpoint.bin") == mgcloth::read_file(whole / "checkpoint.bin"));
}

TEST_P(Resume, ASolverStateOfAnotherKindIsRefused) {
  const ResumeCase& c = GetParam();
  write_scene(c, 4);
  const fs::path out = dir / "out", file = out / "checkpoint.bin";
  auto r = run(out, "--frames 2");
  ASSERT_EQ(r.code, 0) << r.out;
  // A well-formed checkpoint (its checksum recomputed) whose solver state another kind of solver wrote.
  mgcloth::sim::Checkpoint k = mgcloth::sim::decode_checkpoint(mgcloth::read_file(file), file);
  k.bodies[0].solver_state = std::string("other") + '\0' + std::string(16, '\1');
  std::ofstream(file, std::ios::binary) << mgcloth::sim::encode_checkpoint(k);
  r = run(out, "--resume");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("checkpoint.bin: cloth \"sheet\": "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("solver state"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out / "frame_00003.obj"));
}

// A run started by an older mgcloth, whose stats.csv lacked columns added since, resumes into one table: the old
// rows are rewritten under the new header by column name, the columns they lacked left empty.
class ResumeOlderStats : public mgcloth::test::TempDirTest {
 protected:
  ResumeOlderStats() : TempDirTest("mgcloth_resume_old_") {}
};

TEST_F(ResumeOlderStats, RowsOfAnOlderHeaderAreMappedByColumnName) {
  std::ofstream(dir / "scene.json") << R"({ "frames": 3, "cloths": [ { "name": "sheet", "mesh": {
      "generator": "rectangle", "vertices": 200 }, "pins": [ { "points": [[0, 1], [1, 1]] } ] } ],
      "solver": { "name": "fmg", "rel_grad": 1e-3 } })";
  const fs::path out = dir / "out";
  auto r = mgcloth::test::run_cli("run " + (dir / "scene.json").string() + " -q --threads 1 --frames 2 --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.out;
  const auto lines = [](const fs::path& f) {
    std::vector<std::string> v;
    std::ifstream in(f);
    for (std::string l; std::getline(in, l);) v.push_back(l);
    return v;
  };
  const auto cells = [](const std::string& s) {
    std::vector<std::string> v;
    std::stringstream in(s);
    for (std::string c; std::getline(in, c, ',');) v.push_back(c);
    if (!s.empty() && s.back() == ',') v.push_back("");
    return v;
  };
  const auto before = lines(out / "stats.csv");
  ASSERT_EQ(before.size(), 3u);
  const auto header = cells(before[0]);
  // The older file: without the last column, and with the first two swapped.
  {
    std::ofstream o(out / "stats.csv");
    for (const auto& l : before) {
      auto c = cells(l);
      c.pop_back();
      std::swap(c[0], c[2]);
      o << fmt::format("{}\n", fmt::join(c, ","));
    }
  }
  r = mgcloth::test::run_cli("run " + (dir / "scene.json").string() + " -q --threads 1 --resume --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.out;
  const auto after = lines(out / "stats.csv");
  ASSERT_EQ(after.size(), 4u);
  EXPECT_EQ(after[0], before[0]);
  for (size_t i = 1; i < after.size(); ++i) EXPECT_EQ(cells(after[i]).size(), header.size()) << after[i];
  for (size_t i = 1; i < 3; ++i) {
    auto expected = cells(before[i]);
    expected.back() = "";
    EXPECT_EQ(cells(after[i]), expected);
  }
}

// Each solver kind that carries state across steps (each of these differed before its state was checkpointed), and
// newton-direct, which carries none.
INSTANTIATE_TEST_SUITE_P(
    Solvers, Resume,
    ::testing::Values(ResumeCase{"fmg", "{}", "fmg"}, ResumeCase{"pd-fmg", "{}", "pd_fmg"},
                      ResumeCase{"fmg-cuda", R"({ "backend": "host" })", "fmg_cuda_host"},
                      ResumeCase{"newton-mg", R"({ "chebyshev": true })", "newton_mg_chebyshev"},
                      ResumeCase{"linearized", "{}", "linearized"}, ResumeCase{"rmtr-paper", R"({ "smoother": "dogleg" })", "rmtr_paper_dogleg"},
                      ResumeCase{"newton-direct", "{}", "newton_direct"}),
    [](const auto& info) { return std::string(info.param.label); });

}  // namespace
