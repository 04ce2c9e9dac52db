// `mgcloth sweep` from the command line: in one process and on 1 and 2 MPI ranks on this machine (loopback), a run
// failing among good ones, and a sweep killed without warning (SIGKILL) then resumed on two ranks.
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/json.hpp>

#include "cli_run.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

class Sweep : public mgcloth::test::TempDirTest {
 protected:
  Sweep() : TempDirTest("mgcloth_sweep_cli_") {}
  void SetUp() override {
    TempDirTest::SetUp();
    // A cantilever strip of 300 vertices, 10 quasi-static frames: about 0.1 s per frame.
    mgcloth::write_file_atomic(dir / "strip.json", R"({
      "time_step": 0.25, "frames": 10,
      "cloths": [{ "name": "strip", "mesh": { "generator": "rectangle", "width": 0.1, "height": 0.02, "vertices": 300 },
        "material": { "preset": "cotton" },
        "pins": [{ "region": { "min": [0, 0], "max": [0.05, 0.02] }, "stiffness": 1e8 }] }],
      "solver": { "name": "newton-direct", "rel_grad": 1e-7, "max_iters": 100 } })");
  }
  /// A sweep of the strip over these densities, with the tip's probe.
  fs::path sweep_file(const std::string& densities) {
    const fs::path file = dir / "sweep.json";
    mgcloth::write_file_atomic(file, fmt::format(R"({{ "scene": "strip.json", "parameters": [
        {{ "path": "/cloths/0/material/density", "name": "density", "values": [{}] }}],
        "measures": [{{ "name": "tip", "type": "probe", "cloth": "strip", "uv": [0.1, 0.01] }}] }})", densities));
    return file;
  }
  /// The summary as rows of name → value.
  std::vector<std::map<std::string, std::string>> table(const fs::path& out) {
    std::istringstream in(mgcloth::read_file(out / "summary.csv"));
    std::string line;
    std::getline(in, line);
    std::vector<std::string> header;
    std::stringstream hs(line);
    for (std::string c; std::getline(hs, c, ',');) header.push_back(c);
    std::vector<std::map<std::string, std::string>> rows;
    while (std::getline(in, line)) {
      std::map<std::string, std::string> row;
      std::stringstream ls(line);
      std::string c;
      for (size_t k = 0; k < header.size() && std::getline(ls, c, ','); ++k) row[header[k]] = c;
      rows.push_back(row);
    }
    return rows;
  }
  static mgcloth::test::CliResult mpirun(int ranks, const std::string& args) {
#ifdef MGCLOTH_MPIEXEC
    // Root in a container: Open MPI refuses root unless told; --oversubscribe: more ranks than free slots.
    return mgcloth::test::run_cli(args, fmt::format("OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
                                                    "OMPI_MCA_btl=self,vader OMPI_MCA_pml=ob1 {} --oversubscribe -np {}",
                                                    MGCLOTH_MPIEXEC, ranks));
#else
    (void)ranks;
    (void)args;
    return {};
#endif
  }
};

#ifdef MGCLOTH_MPIEXEC
constexpr bool kMpi = true;
#else
constexpr bool kMpi = false;
#endif

}  // namespace

TEST_F(Sweep, RunsInOneProcessAndRefusesBadInput) {
  const fs::path out = dir / "out";
  auto r = mgcloth::test::run_cli(fmt::format("sweep {} --out {} -q -j 1", sweep_file("300, 150").string(), out.string()));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto rows = table(out);
  ASSERT_EQ(rows.size(), 2u);
  for (const auto& row : rows) {
    EXPECT_EQ(row.at("status"), "ok");
    EXPECT_EQ(row.at("last_frame"), "10");
    EXPECT_LT(std::stod(row.at("tip_z")), 0.0);
  }
  EXPECT_TRUE(fs::exists(out / "runs" / "00001" / "frame_00010.obj"));
  EXPECT_TRUE(fs::exists(out / "runs" / "00001" / "stats.csv"));
  EXPECT_TRUE(fs::exists(out / "runs" / "00001" / "scene.resolved.json"));
  // The same folder again without --resume: refused, nothing touched.
  r = mgcloth::test::run_cli(fmt::format("sweep {} --out {} -q", sweep_file("300, 150").string(), out.string()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--resume"), std::string::npos) << r.out;
  r = mgcloth::test::run_cli(fmt::format("sweep {} --out {} -q", (dir / "none.json").string(), out.string()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("none.json: no such sweep file"), std::string::npos) << r.out;
  r = mgcloth::test::run_cli(fmt::format("sweep {} --out {} --retry-failed", sweep_file("1").string(), out.string()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--retry-failed: only with --resume"), std::string::npos) << r.out;
  if (!kMpi) {
    // Started by a launcher as one of several processes, a build without MPI would run the whole sweep in each.
    r = mgcloth::test::run_cli(fmt::format("sweep {} --out {} -q", sweep_file("1").string(), (dir / "o2").string()),
                               "OMPI_COMM_WORLD_SIZE=2");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.out.find("without MPI"), std::string::npos) << r.out;
  }
}

TEST_F(Sweep, OnOneAndTwoRanksAFailingRunIsRecordedAndTheOthersFinish) {
  if (!kMpi) GTEST_SKIP() << "built without MPI (libopenmpi-dev)";
  for (int ranks : {1, 2}) {
    const fs::path out = dir / fmt::format("out{}", ranks);
    const auto r = mpirun(ranks, fmt::format("sweep {} --out {} -q", sweep_file("300, -5, 150, 600").string(), out.string()));
    ASSERT_EQ(r.code, 0) << r.out;
    const auto rows = table(out);
    ASSERT_EQ(rows.size(), 4u);
    std::set<std::string> ranks_seen;
    for (size_t k = 0; k < rows.size(); ++k) {
      EXPECT_EQ(rows[k].at("status"), k == 1 ? "failed" : "ok") << k;
      ranks_seen.insert(rows[k].at("rank"));
    }
    EXPECT_NE(rows[1].at("message").find("density"), std::string::npos) << rows[1].at("message");
    EXPECT_EQ(ranks_seen.size(), static_cast<size_t>(ranks));  // runs are handed to every rank
    // The same runs give the same tip on any number of ranks.
    if (ranks == 2) {
      const auto one = table(dir / "out1");
      for (size_t k : {0u, 2u, 3u}) EXPECT_EQ(rows[k].at("tip_z"), one[k].at("tip_z")) << k;
    }
  }
}

// Killed without warning in the middle of its third run: the finished runs stay finished (their result.json is not
// written again), the partial one continues from its checkpoint, and the rest run, here on two ranks.
TEST_F(Sweep, AKilledSweepResumesWithoutRedoingFinishedRuns) {
  const fs::path file = sweep_file("300, 200, 150, 400, 500, 600");
  const fs::path out = dir / "out";
  const fs::path third = out / "runs" / "00002";
  const std::string script = fmt::format(
      "{} sweep {} --out {} -q -j 1 > /dev/null 2>&1 & pid=$!; i=0; "
      "while [ \"$(cat '{}/stats.csv' 2>/dev/null | wc -l)\" -lt 4 ] && [ $i -lt 1200 ] && kill -0 $pid 2>/dev/null; "
      "do sleep 0.05; i=$((i+1)); done; kill -KILL $pid; wait $pid",
      MGCLOTH_CLI, file.string(), out.string(), third.string());
  const int status = std::system(script.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 128 + 9);
  const std::string first = mgcloth::read_file(out / "runs" / "00000" / "result.json");
  const std::string second = mgcloth::read_file(out / "runs" / "00001" / "result.json");
  ASSERT_FALSE(fs::exists(third / "result.json"));
  ASSERT_TRUE(fs::exists(third / "checkpoint.bin"));
  auto rows = table(out);
  EXPECT_EQ(rows[0].at("status"), "ok");
  EXPECT_EQ(rows[2].at("status"), "pending");

  const std::string resume = fmt::format("sweep {} --out {} --resume -q -j 1", file.string(), out.string());
  const auto r = kMpi ? mpirun(2, resume) : mgcloth::test::run_cli(resume);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(mgcloth::read_file(out / "runs" / "00000" / "result.json"), first);
  EXPECT_EQ(mgcloth::read_file(out / "runs" / "00001" / "result.json"), second);
  rows = table(out);
  ASSERT_EQ(rows.size(), 6u);
  for (const auto& row : rows) EXPECT_EQ(row.at("status"), "ok");
  EXPECT_GE(std::stoi(rows[2].at("resumed_from")), 3);  // at least three frames were in its stats.csv
  EXPECT_EQ(rows[2].at("last_frame"), "10");
  EXPECT_EQ(rows[3].at("resumed_from"), "-1");
  // Once more: nothing left to do.
  const auto again = mgcloth::test::run_cli(resume);
  ASSERT_EQ(again.code, 0) << again.out;
  EXPECT_EQ(mgcloth::read_file(out / "runs" / "00000" / "result.json"), first);
}
