// `mgcloth sweep SWEEP.json --out DIR`: the runs of a parameter sweep, one after another in this process, or under
// `mpirun -np N` handed out by rank 0 to every rank as each asks for work (runs differ in length).
#include "commands.hpp"

#include <mgcloth/core/error.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/sweep/sweep.hpp>

#include <fmt/format.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <mutex>
#include <thread>

#ifdef MGCLOTH_HAVE_MPI
#include <mpi.h>
#endif

namespace mgcloth::cli {

namespace fs = std::filesystem;

namespace {

struct SweepOptions {
  std::string file;
  std::string out;
  int threads = 0;
  bool resume = false;
  bool retry_failed = false;
  bool quiet = false;
} g_sweep;

/// The number of processes a launcher (mpirun, srun) started this one among, from its environment; 0 when no
/// launcher did.
int launched_world_size() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "PMI_SIZE"})
    if (const char* v = std::getenv(name)) return std::max(1, std::atoi(v));
  if (std::getenv("PMIX_RANK") || std::getenv("PMI_RANK")) return 1;
  return 0;
}

struct Tally {
  size_t ok = 0, failed = 0, pending = 0;
  explicit Tally(const std::vector<std::optional<sweep::RunResult>>& results) {
    for (const auto& r : results) {
      if (!r) ++pending;
      else if (r->status == "ok") ++ok;
      else ++failed;
    }
  }
};

void report(const sweep::RunResult& r, size_t done, size_t todo) {
  if (g_sweep.quiet) return;
  std::string line = fmt::format("mgcloth sweep: [{}/{}] run {} {} in {:.1f} s (rank {})", done, todo, r.run, r.status,
                                 r.wall_s, r.rank);
  if (r.status == "failed") line += ": " + r.message;
  std::fprintf(stderr, "%s\n", line.c_str());
}

int finish_message(const fs::path& out, const std::vector<std::optional<sweep::RunResult>>& results, double seconds) {
  const Tally t(results);
  if (!g_sweep.quiet)
    std::fprintf(stderr, "mgcloth sweep: %zu ok, %zu failed, %zu not run in %.1f s; table: %s\n", t.ok, t.failed,
                 t.pending, seconds, (out / "summary.csv").string().c_str());
  if (t.pending > 0) {
    std::fprintf(stderr, "mgcloth: sweep interrupted; continue it with --resume\n");
    return 130;
  }
  return 0;
}

int run_serial() {
  const sweep::Sweep s = sweep::load_sweep(g_sweep.file);
  install_interrupt_handler();
  Timer timer;
  sweep::RunOptions options;
  options.threads = g_sweep.threads;
  options.default_threads = omp_get_max_threads();  // nothing has changed it yet: all cores, or OMP_NUM_THREADS
  options.stop = [] { return interrupted(); };
  size_t done = 0, todo = s.size();
  if (g_sweep.resume && fs::exists(fs::path(g_sweep.out) / "sweep.json")) {
    std::vector<std::optional<sweep::RunResult>> finished;
    todo = sweep::pending_runs(s, g_sweep.out, finished, false).size();
    if (g_sweep.retry_failed)
      todo += static_cast<size_t>(std::count_if(finished.begin(), finished.end(),
                                                [](const auto& r) { return r && r->status == "failed"; }));
  }
  if (!g_sweep.quiet)
    std::fprintf(stderr, "mgcloth sweep: %zu runs of %s in one process -> %s\n", s.size(), s.scene_file.string().c_str(),
                 g_sweep.out.c_str());
  const auto results = sweep::run_serial(s, g_sweep.out, g_sweep.resume, g_sweep.retry_failed, options,
                                         [&](const sweep::RunResult& r) { report(r, ++done, todo); });
  return finish_message(g_sweep.out, results, timer.seconds());
}

#ifdef MGCLOTH_HAVE_MPI

/// kAsk: a worker's first request; kResult: a result and the next request; kLeave: a worker that stops (a signal);
/// kRun: a run's number for a worker; kStop: no more runs.
enum Tag : int { kAsk = 1, kResult = 2, kLeave = 3, kRun = 4, kStop = 5 };

void send_text(const std::string& text, int to, int tag) {
  MPI_Send(text.data(), static_cast<int>(text.size()), MPI_CHAR, to, tag, MPI_COMM_WORLD);
}

std::string receive_text(int from, int tag, MPI_Status* status) {
  MPI_Status probe;
  MPI_Probe(from, tag, MPI_COMM_WORLD, &probe);
  int count = 0;
  MPI_Get_count(&probe, MPI_CHAR, &count);
  std::string text(static_cast<size_t>(count), '\0');
  MPI_Recv(text.data(), count, MPI_CHAR, probe.MPI_SOURCE, probe.MPI_TAG, MPI_COMM_WORLD, status);
  return text;
}

/// Threads per run so that the ranks on one machine share its cores: the cores over the ranks there.
int threads_per_run(const sweep::Sweep& s) {
  if (g_sweep.threads > 0) return g_sweep.threads;
  if (s.threads > 0) return s.threads;
  MPI_Comm local;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &local);
  int local_size = 1;
  MPI_Comm_size(local, &local_size);
  MPI_Comm_free(&local);
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  return std::max(1, cores / local_size);
}

/// Rank 0: hands out runs to every rank that asks (itself included, through a thread of its own, so that this
/// thread alone calls MPI) and keeps the summary current as results arrive.
int coordinate(const sweep::Sweep& s, int size, int threads) {
  Timer timer;
  std::vector<std::optional<sweep::RunResult>> results;
  const std::vector<size_t> pending = sweep::pending_runs(s, g_sweep.out, results, g_sweep.retry_failed);
  sweep::SummaryWriter summary(s, g_sweep.out);
  summary.flush(results);
  if (!g_sweep.quiet)
    std::fprintf(stderr, "mgcloth sweep: %zu runs of %s (%zu to do) on %d ranks x %d threads -> %s\n", s.size(),
                 s.scene_file.string().c_str(), pending.size(), size, threads, g_sweep.out.c_str());
  std::mutex lock;
  std::deque<size_t> queue(pending.begin(), pending.end());
  std::vector<sweep::RunResult> arrived;  // the local thread's results, for this thread to record
  size_t done = 0;
  const auto next = [&]() -> std::optional<size_t> {
    std::lock_guard<std::mutex> guard(lock);
    if (queue.empty() || interrupted()) return std::nullopt;
    const size_t run = queue.front();
    queue.pop_front();
    return run;
  };
  bool local_done = false;
  std::string local_error;  // what stopped the local runs other than a run's own failure (a full disk)
  std::thread local([&] {
    sweep::RunOptions options;
    options.threads = threads;
    options.rank = 0;
    options.stop = [] { return interrupted(); };
    try {
      while (const auto run = next()) {
        auto r = sweep::execute_run(s, g_sweep.out, *run, options);
        if (!r) break;
        std::lock_guard<std::mutex> guard(lock);
        arrived.push_back(std::move(*r));
      }
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> guard(lock);
      local_error = e.what();
    }
    std::lock_guard<std::mutex> guard(lock);
    local_done = true;
  });
  const auto record = [&](sweep::RunResult r) {
    const size_t run = r.run;
    results[run] = std::move(r);
    report(*results[run], ++done, pending.size());
    summary.update(results);
  };
  int workers = size - 1;
  for (;;) {
    std::vector<sweep::RunResult> mine;
    bool all_local_done = false;
    std::string error;
    {
      std::lock_guard<std::mutex> guard(lock);
      mine.swap(arrived);
      all_local_done = local_done;
      error = local_error;
    }
    for (auto& r : mine) record(std::move(r));
    if (!error.empty()) {
      summary.flush(results);
      local.join();
      std::fprintf(stderr, "mgcloth: error: rank 0: %s\n", error.c_str());
      MPI_Abort(MPI_COMM_WORLD, 1);
    }
    if (all_local_done && workers == 0) break;
    int flag = 0;
    MPI_Status status;
    MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
    if (!flag) {
      if (summary.due()) summary.flush(results);
      // A blocking receive would spin a core that the local runs need.
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      continue;
    }
    const int from = status.MPI_SOURCE;
    const std::string text = receive_text(from, status.MPI_TAG, &status);
    if (status.MPI_TAG == kLeave) {
      --workers;
      continue;
    }
    if (status.MPI_TAG == kResult) {
      try {
        record(sweep::result_from_json(parse_json(text, fmt::format("rank {}'s result", from)), s));
      } catch (const std::exception& e) {
        std::fprintf(stderr, "mgcloth: error: rank %d sent a result that does not read: %s\n", from, e.what());
      }
    }
    if (const auto run = next()) {
      const unsigned long long index = *run;
      MPI_Send(&index, 1, MPI_UNSIGNED_LONG_LONG, from, kRun, MPI_COMM_WORLD);
    } else {
      MPI_Send(nullptr, 0, MPI_UNSIGNED_LONG_LONG, from, kStop, MPI_COMM_WORLD);
      --workers;
    }
  }
  local.join();
  summary.flush(results);
  return finish_message(g_sweep.out, results, timer.seconds());
}

/// Ranks 1..N-1: ask rank 0 for a run, run it, send its result with the next request.
int work(const sweep::Sweep& s, int rank, int threads) {
  sweep::RunOptions options;
  options.threads = threads;
  options.rank = rank;
  options.stop = [] { return interrupted(); };
  std::string result;  // the last run's, sent with the next request
  for (;;) {
    send_text(result, 0, result.empty() ? kAsk : kResult);
    unsigned long long run = 0;
    MPI_Status status;
    MPI_Recv(&run, 1, MPI_UNSIGNED_LONG_LONG, 0, MPI_ANY_TAG, MPI_COMM_WORLD, &status);
    if (status.MPI_TAG == kStop) return 0;
    // A signal: the run stops after its frame in progress and stays partial, as does a run not yet started; both
    // continue with --resume.
    const auto r = interrupted() ? std::nullopt : sweep::execute_run(s, g_sweep.out, static_cast<size_t>(run), options);
    if (!r) {
      send_text(std::string(), 0, kLeave);
      return 130;
    }
    result = sweep::to_json(*r).dump();
  }
}

int run_mpi() {
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  install_interrupt_handler();
  // Rank 0 reads and checks the sweep and prepares the folder; the others start only once that worked.
  int ok = 1;
  std::string error;
  if (rank == 0) {
    try {
      const sweep::Sweep s = sweep::load_sweep(g_sweep.file);
      sweep::prepare_output(s, g_sweep.out, g_sweep.resume);
    } catch (const std::exception& e) {
      error = e.what();
      ok = 0;
    }
  }
  MPI_Bcast(&ok, 1, MPI_INT, 0, MPI_COMM_WORLD);
  if (!ok) {
    if (rank == 0) std::fprintf(stderr, "mgcloth: error: %s\n", error.c_str());
    MPI_Finalize();
    return 1;
  }
  int code = 0;
  try {
    const sweep::Sweep s = sweep::load_sweep(g_sweep.file);
    const int threads = threads_per_run(s);
    code = rank == 0 ? coordinate(s, size, threads) : work(s, rank, threads);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mgcloth: error: rank %d: %s\n", rank, e.what());
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  MPI_Finalize();
  return code;
}

#endif

}  // namespace

void add_sweep_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "sweep", "Run a parameter sweep of a scene (docs/sweeps.md); under mpirun -np N the runs are shared by the ranks");
  cmd->add_option("sweep", g_sweep.file, "Sweep file (JSON)")->required();
  cmd->add_option("--out,-o", g_sweep.out, "Output folder: runs/NNNNN/ per run and summary.csv")->required();
  cmd->add_option("--threads,-j", g_sweep.threads,
                  "Threads per run, 0-1024; 0: the sweep's \"threads\", else the cores over the ranks on a machine")
      ->check(CLI::Range(0, 1024));
  cmd->add_flag("--resume", g_sweep.resume,
                "Continue a sweep in --out: finished runs are kept, partial ones continue from their checkpoints");
  cmd->add_flag("--retry-failed", g_sweep.retry_failed, "With --resume, also run the failed runs again");
  cmd->add_flag("--quiet,-q", g_sweep.quiet, "No progress output");
}

int run_sweep_command() {
  if (g_sweep.retry_failed && !g_sweep.resume) throw InputError("--retry-failed: only with --resume");
  const int world = launched_world_size();
#ifdef MGCLOTH_HAVE_MPI
  if (world > 0) return run_mpi();
#else
  if (world > 1)
    throw InputError(fmt::format("started as one of {} processes (mpirun), but this mgcloth was built without MPI: each "
                                 "would run the whole sweep. Install libopenmpi-dev and rebuild, or run it without "
                                 "mpirun",
                                 world));
#endif
  return run_serial();
}

}  // namespace mgcloth::cli
