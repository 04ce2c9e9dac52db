#pragma once
// Parameter sweeps (docs/sweeps.md): one base scene, parameters varied by JSON pointer, each run simulated in
// process into a folder of its own, and one summary table. What hands the runs out (one process, or MPI ranks in
// `mgcloth sweep`) is the caller's; everything here is per run and safe to call from one thread per run.
#include <mgcloth/core/json.hpp>
#include <mgcloth/sweep/measures.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace mgcloth::sweep {

/// One varied parameter: where it goes in the scene and its values.
struct Parameter {
  std::string path;    ///< JSON pointer into the scene, as written ("/cloths/0/material/bending_stiffness")
  std::string column;  ///< its column in summary.csv ("name", default: the path's tokens joined by '.')
  std::string group;   ///< parameters of one group are zipped (equal counts); groups are crossed
  std::vector<Json> values;
};

struct Sweep {
  std::string file;                 ///< the sweep file (for messages)
  std::filesystem::path scene_file;  ///< the base scene, absolute
  Json scene;                       ///< the base scene's JSON
  std::vector<Parameter> parameters;
  /// Per run, the index into each parameter's values (parameters order). Groups are crossed in the order they
  /// first appear, the last one varying fastest.
  std::vector<std::vector<size_t>> runs;
  std::vector<Measure> measures;
  std::string frames = "last";  ///< what each run keeps: all | last | none
  int threads = 0;              ///< threads per run (0: the cores divided among the processes of a machine)
  std::uint64_t seed = 1;

  size_t size() const { return runs.size(); }
  /// The scene of run `run`: the base scene with the run's values written in, output.dir left to the caller.
  Json run_scene(size_t run) const;
  /// The summary's column names for the parameters and for the measures.
  std::vector<std::string> parameter_columns() const;
  std::vector<std::string> measure_columns() const;
  /// The sweep as run: every run's values and the measures. Two sweeps with equal descriptions run the same runs, so
  /// a resumed sweep must have the description it started with.
  Json description() const;
};

/// Parses and expands a sweep file. Unknown keys, wrong types, empty or mismatched lists, a bad pointer or a value
/// that the scene rejects at its first value are InputError naming the file and field; relative scene paths are
/// the sweep file's folder's.
Sweep load_sweep(const std::filesystem::path& path);
Sweep parse_sweep(const Json& json, const std::string& file, const std::filesystem::path& base_dir);

/// What became of one run; result.json in its folder.
struct RunResult {
  size_t run = 0;
  std::string status;   ///< ok | failed
  std::string message;  ///< failed: why (the scene's or the solver's message)
  double wall_s = 0.0;  ///< this attempt's wall time (a resumed run counts from where it resumed)
  int frames = 0;
  long steps = 0;
  long iterations = 0;      ///< solver iterations over every step
  long unconverged = 0;     ///< steps that ended at max_iters without meeting the tolerance
  int resumed_from = -1;    ///< the frame a partial run was resumed from (−1: started fresh)
  int rank = 0;             ///< the process (MPI rank) that ran it
  std::vector<double> measures;  ///< measure_columns() order; NaN: undefined or not reached
};
Json to_json(const RunResult& r);
RunResult result_from_json(const Json& j, const Sweep& sweep);

/// runs/NNNNN (five digits, more for larger sweeps).
std::filesystem::path run_folder(const std::filesystem::path& out, size_t run);

/// Writes out/sweep.json (the description) for a new sweep, or checks it for a resumed one. A new sweep refuses a
/// folder that holds another sweep's results (nothing is overwritten); a resumed one refuses a changed sweep.
void prepare_output(const Sweep& sweep, const std::filesystem::path& out, bool resume);

/// The finished result of a run in `out` (its result.json), if any; a damaged file counts as not finished.
std::optional<RunResult> read_result(const Sweep& sweep, const std::filesystem::path& out, size_t run);

struct RunOptions {
  int threads = 0;  ///< the run's threads (0: the sweep's, then the scene's)
  /// Where neither the options, the sweep nor the run's scene names a thread count: all cores, as the process had them
  /// before any run set its own (the thread count is process-wide: a run on 1 thread must not leave the next scene's
  /// "threads": 0 on 1). 0 leaves OpenMP's current setting.
  int default_threads = 0;
  int rank = 0;
  /// Called between frames; true ends the run early (it stays partial and resumes from its checkpoint).
  std::function<bool()> stop;
};

/// Simulates run `run` into run_folder(out, run), resuming it from its checkpoint when it has one and no result;
/// writes result.json atomically as the last thing. A failure (a bad value, a diverging solve) is a RunResult with
/// status "failed", not an exception. Returns nullopt when `stop` ended it before its last frame.
std::optional<RunResult> execute_run(const Sweep& sweep, const std::filesystem::path& out, size_t run,
                                     const RunOptions& options);

/// summary.csv, written atomically: one row per run in run order (runs without a result: status "pending"), with
/// the run's number, status, parameter values, wall time, last frame, steps, iterations, measures, rank, message and
/// folder.
void write_summary(const Sweep& sweep, const std::filesystem::path& out, const std::vector<std::optional<RunResult>>& results);

/// Keeps summary.csv current as results arrive without letting its rewrites dominate: a table of 10^5 runs is ~15 MB,
/// and rewriting it after every result would cost more than the results. A rewrite is due once ten times the last
/// one's duration has passed since it (a small table: after every result; a large one: at most a tenth of the time);
/// flush() writes what is pending. result.json stays the record: a summary that lags loses nothing.
class SummaryWriter {
 public:
  SummaryWriter(const Sweep& sweep, std::filesystem::path out) : m_sweep(sweep), m_out(std::move(out)) {}
  /// The results changed: rewrite now if due, else mark it pending.
  void update(const std::vector<std::optional<RunResult>>& results);
  /// Whether a pending rewrite is due (for a caller polling while it waits).
  bool due() const;
  void flush(const std::vector<std::optional<RunResult>>& results);

 private:
  void write(const std::vector<std::optional<RunResult>>& results);
  const Sweep& m_sweep;
  std::filesystem::path m_out;
  std::chrono::steady_clock::time_point m_last{};
  double m_cost = 0.0;  ///< the last rewrite's duration, s
  bool m_pending = false;
};

/// The summary's text (what write_summary writes).
std::string summary_csv(const Sweep& sweep, const std::vector<std::optional<RunResult>>& results);

/// Runs every unfinished run one after another in this process (`mgcloth sweep` without MPI, and the Python
/// module's run_sweep). `on_result` is called after each run. Returns every run's result; nullopt for those a stop
/// left unfinished.
std::vector<std::optional<RunResult>> run_serial(const Sweep& sweep, const std::filesystem::path& out, bool resume,
                                                 bool retry_failed, const RunOptions& options,
                                                 const std::function<void(const RunResult&)>& on_result = {});

/// The runs a (resumed) sweep still has to do: those without a result, and with `retry_failed` the failed ones.
std::vector<size_t> pending_runs(const Sweep& sweep, const std::filesystem::path& out,
                                 std::vector<std::optional<RunResult>>& results, bool retry_failed);

}  // namespace mgcloth::sweep
