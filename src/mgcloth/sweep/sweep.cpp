#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/sim/recorder.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/sim/solver_fit.hpp>
#include <mgcloth/sweep/sweep.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>

namespace fs = std::filesystem;

namespace mgcloth::sweep {

namespace {

constexpr size_t kMaxRuns = 1'000'000;
constexpr int kDescriptionFormat = 1;
const char* const kDescriptionFile = "sweep.json";
const char* const kResultFile = "result.json";
const char* const kSummaryFile = "summary.csv";
const std::vector<std::string> kFixedColumns{"run", "status", "wall_s", "last_frame", "steps", "iterations",
                                             "unconverged_steps", "rank", "resumed_from", "message", "folder"};

/// A uniform double in [0, 1) from the engine's bits: std::uniform_real_distribution's algorithm is the standard
/// library's choice, and a sweep must draw the same samples on every machine of a cluster.
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// The scene's own name for a pointer's place ("cloths[0].material.bending_stiffness"), as its errors write it.
std::string scene_path(const Json& scene, const Json::json_pointer& pointer) {
  std::string out;
  const Json* at = &scene;
  std::vector<std::string> tokens;
  for (Json::json_pointer p = pointer; !p.empty(); p = p.parent_pointer()) tokens.push_back(p.back());
  std::reverse(tokens.begin(), tokens.end());
  for (const std::string& t : tokens) {
    if (at && at->is_array()) {
      out += "[" + t + "]";
    } else {
      out += (out.empty() ? "" : ".") + t;
    }
    if (at && at->is_array()) {
      size_t k = 0;
      const bool numeric = !t.empty() && std::all_of(t.begin(), t.end(), [](unsigned char ch) { return std::isdigit(ch) != 0; });
      if (numeric) k = std::stoul(t);
      at = numeric && k < at->size() ? &(*at)[k] : nullptr;
    } else if (at && at->is_object() && at->contains(t)) {
      at = &(*at)[t];
    } else {
      at = nullptr;
    }
  }
  return out;
}

bool valid_column(const std::string& c) {
  if (c.empty() || c.size() > 64) return false;
  return std::none_of(c.begin(), c.end(), [](char ch) {
    return static_cast<unsigned char>(ch) < 0x20 || ch == ',' || ch == '"' || ch == '\\' || ch == 0x7f;
  });
}

std::vector<Json> range_values(JsonReader& r) {
  const double start = r.required_number("start");
  const double stop = r.required_number("stop");
  const bool log = r.choice("scale", "linear", {"linear", "log"}) == "log";
  const bool integer = r.boolean("integer", false);
  if (r.has("count") == r.has("step")) r.fail("count", "give exactly one of \"count\" and \"step\"");
  std::vector<double> v;
  if (log && !(start > 0.0 && stop > 0.0)) r.fail("scale", "\"log\" needs start > 0 and stop > 0");
  if (r.has("count")) {
    const int n = r.integer("count", 1, 1, static_cast<int>(kMaxRuns));
    for (int i = 0; i < n; ++i) {
      const double t = n == 1 ? 0.0 : static_cast<double>(i) / (n - 1);
      v.push_back(log ? std::exp(std::log(start) + t * (std::log(stop) - std::log(start))) : start + t * (stop - start));
    }
    v.front() = start;  // exactly the endpoints the user wrote (exp(log(x)) is not always x)
    if (n > 1) v.back() = stop;
  } else {
    const double step = r.number("step", 1.0);
    if (log) {
      if (!(step > 1.0)) r.fail("step", "with \"log\" scale the step is a factor: must be > 1");
    } else if (!(step > 0.0)) {
      r.fail("step", "must be > 0");
    }
    const double lo = std::min(start, stop), hi = std::max(start, stop);
    const double slack = 1e-9 * std::max(std::abs(start), std::abs(stop));
    for (long i = 0;; ++i) {
      const double x = log ? start * std::pow(stop >= start ? step : 1.0 / step, static_cast<double>(i))
                           : start + (stop >= start ? 1.0 : -1.0) * step * static_cast<double>(i);
      if (x < lo - slack || x > hi + slack) break;
      v.push_back(x);
      if (v.size() > kMaxRuns) r.fail("step", fmt::format("gives more than {} values", kMaxRuns));
    }
  }
  std::vector<Json> out;
  for (double x : v) out.push_back(integer ? Json(std::llround(x)) : Json(x));
  r.finish();
  return out;
}

std::vector<Json> random_values(JsonReader& r, std::uint64_t seed, size_t index) {
  const double lo = r.required_number("min");
  const double hi = r.required_number("max");
  if (!(hi >= lo)) r.fail("max", fmt::format("must be >= min ({})", lo));
  const bool log = r.choice("scale", "linear", {"linear", "log"}) == "log";
  if (log && !(lo > 0.0)) r.fail("scale", "\"log\" needs min > 0");
  const bool integer = r.boolean("integer", false);
  const int n = r.integer("count", 1, 1, static_cast<int>(kMaxRuns));
  if (!r.has("count")) r.fail("count", "missing required field");
  r.finish();
  // One stream per parameter, so that adding a parameter does not move another's samples.
  std::mt19937_64 rng(seed + 0x9E3779B97F4A7C15ull * (index + 1));
  std::vector<Json> out;
  for (int i = 0; i < n; ++i) {
    const double t = uniform01(rng);
    if (integer) {
      const long long a = std::llround(std::ceil(lo)), b = std::llround(std::floor(hi));
      if (b < a) r.fail("min", "no integer lies in [min, max]");
      out.push_back(a + static_cast<long long>(std::floor(t * static_cast<double>(b - a + 1))));
    } else {
      out.push_back(log ? std::exp(std::log(lo) + t * (std::log(hi) - std::log(lo))) : lo + t * (hi - lo));
    }
  }
  return out;
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string csv_value(const Json& v) {
  if (v.is_string()) return csv_field(v.get<std::string>());
  if (v.is_number_float()) return fmt::format("{}", v.get<double>());
  return csv_field(v.dump());
}

std::string number_text(double x) { return std::isfinite(x) ? fmt::format("{}", x) : std::string("nan"); }

Json finite_or_null(double x) { return std::isfinite(x) ? Json(x) : Json(nullptr); }

}  // namespace

Json Sweep::run_scene(size_t run) const {
  Json j = scene;
  for (size_t p = 0; p < parameters.size(); ++p)
    j[Json::json_pointer(parameters[p].path)] = parameters[p].values[runs[run][p]];
  return j;
}

std::vector<std::string> Sweep::parameter_columns() const {
  std::vector<std::string> out;
  for (const Parameter& p : parameters) out.push_back(p.column);
  return out;
}

std::vector<std::string> Sweep::measure_columns() const {
  std::vector<std::string> out;
  for (const Measure& m : measures)
    for (const std::string& c : m.columns()) out.push_back(c);
  return out;
}

Json Sweep::description() const {
  Json j{{"format", kDescriptionFormat}, {"scene", scene_file.string()}, {"base_scene", scene}, {"frames", frames}};
  j["parameters"] = Json::array();
  for (const Parameter& p : parameters)
    j["parameters"].push_back({{"path", p.path}, {"column", p.column}, {"group", p.group}, {"values", p.values}});
  j["runs"] = runs;
  j["measures"] = Json::array();
  for (const Measure& m : measures) j["measures"].push_back(to_json(m));
  return j;
}

Sweep parse_sweep(const Json& json, const std::string& file, const fs::path& base_dir) {
  JsonReader r(json, file);
  Sweep s;
  s.file = file;
  const fs::path scene = r.required_string("scene");
  s.scene_file = fs::absolute(scene.is_absolute() ? scene : base_dir / scene).lexically_normal();
  if (!fs::is_regular_file(s.scene_file)) r.fail("scene", fmt::format("no such scene file: {}", s.scene_file.string()));
  s.scene = load_json(s.scene_file.string());
  if (!s.scene.is_object()) r.fail("scene", fmt::format("{} is not a JSON object", s.scene_file.string()));
  s.seed = static_cast<std::uint64_t>(r.number("seed", 1.0, 0.0, 9007199254740992.0));
  if (r.has("seed") && std::floor(json["seed"].get<double>()) != json["seed"].get<double>())
    r.fail("seed", "must be a whole number");
  s.frames = r.choice("frames", s.frames, {"all", "last", "none"});
  s.threads = r.integer("threads", 0, 0, 1024);
  const bool zip_all = r.choice("combine", "cross", {"cross", "zip"}) == "zip";
  auto params = r.objects("parameters");
  if (params.empty()) r.fail("parameters", "a sweep varies at least one parameter (a list of {\"path\", ...})");
  for (size_t k = 0; k < params.size(); ++k) {
    JsonReader& pr = params[k];
    Parameter p;
    p.path = pr.required_string("path");
    Json::json_pointer pointer;
    try {
      pointer = Json::json_pointer(p.path);
    } catch (const Json::exception& e) {
      pr.fail("path", fmt::format("not a JSON pointer (\"/cloths/0/material/density\"): {}", e.what()));
    }
    if (pointer.empty()) pr.fail("path", "must name a field of the scene, not the whole scene");
    // The parent must exist: writing through a missing one would invent objects, or pad an array with nulls.
    const Json::json_pointer parent = pointer.parent_pointer();
    if (!s.scene.contains(parent))
      pr.fail("path", fmt::format("{} has no {}", s.scene_file.string(), parent.to_string()));
    const Json& container = s.scene.at(parent);
    if (container.is_array()) {
      if (!s.scene.contains(pointer))
        pr.fail("path", fmt::format("{}: {} has {} entries", s.scene_file.string(), parent.to_string(), container.size()));
    } else if (!container.is_object()) {
      pr.fail("path", fmt::format("{}: {} is a {}, not an object", s.scene_file.string(), parent.to_string(),
                                  container.type_name()));
    }
    std::string column;
    for (Json::json_pointer q = pointer; !q.empty(); q = q.parent_pointer()) column = q.back() + (column.empty() ? "" : "." + column);
    if (pr.has("name")) {
      p.column = pr.name("name", "");
    } else if (!valid_column(column)) {
      pr.fail("path", "its tokens make no column name (give the parameter a \"name\")");
    } else {
      p.column = column;
    }
    p.group = zip_all ? std::string("*") : pr.string("group", "");
    if (zip_all && pr.has("group")) pr.fail("group", "not with \"combine\": \"zip\" (every parameter is zipped)");
    const int sources = pr.has("values") + pr.has("range") + pr.has("random");
    if (sources == 0) pr.finish();  // a misspelt "values" is the likelier mistake: named as such
    if (sources != 1) pr.fail("values", "give exactly one of \"values\", \"range\" and \"random\"");
    if (pr.has("values")) {
      const Json& v = pr.raw("values");
      if (!v.is_array() || v.empty()) pr.fail("values", "expected a non-empty array");
      p.values.assign(v.begin(), v.end());
    } else if (pr.has("range")) {
      JsonReader rr = pr.object("range");
      p.values = range_values(rr);
    } else {
      JsonReader rr = pr.object("random");
      p.values = random_values(rr, s.seed, k);
    }
    pr.finish();
    // Each parameter's first value in the base scene, parsed: a typo in the path or a value of the wrong kind is the
    // sweep's error, found now, not a failed run per value.
    Json trial = s.scene;
    trial[pointer] = p.values.front();
    const std::string place = scene_path(s.scene, pointer);
    try {
      (void)sim::parse_scene(trial, s.scene_file.string(), s.scene_file.parent_path());
    } catch (const InputError& e) {
      const std::string what = e.what();
      if (what.find(place) != std::string::npos)
        pr.fail("path", fmt::format("with its first value {}: {}", p.values.front().dump(), what));
    }
    s.parameters.push_back(std::move(p));
  }
  for (auto& mr : r.objects("measures")) s.measures.push_back(parse_measure(mr));
  r.finish();

  std::set<std::string> columns(kFixedColumns.begin(), kFixedColumns.end());
  const auto claim = [&](const std::string& c, const std::string& where) {
    if (!columns.insert(c).second)
      throw InputError(fmt::format("{}: {}: column \"{}\" is used twice (columns {} are the summary's own)", file, where,
                                   c, fmt::join(kFixedColumns, ", ")));
  };
  for (size_t k = 0; k < s.parameters.size(); ++k) claim(s.parameters[k].column, fmt::format("parameters[{}]", k));
  for (size_t k = 0; k < s.measures.size(); ++k)
    for (const std::string& c : s.measures[k].columns()) claim(c, fmt::format("measures[{}]", k));
  std::set<std::string> paths;
  for (size_t k = 0; k < s.parameters.size(); ++k)
    if (!paths.insert(s.parameters[k].path).second)
      throw InputError(fmt::format("{}: parameters[{}].path: {} is varied twice", file, k, s.parameters[k].path));

  // Groups: zipped inside, crossed between, in the order they first appear.
  std::vector<std::vector<size_t>> groups;
  std::map<std::string, size_t> group_of;
  for (size_t k = 0; k < s.parameters.size(); ++k) {
    const std::string& g = s.parameters[k].group;
    if (g.empty() || !group_of.count(g)) {
      if (!g.empty()) group_of[g] = groups.size();
      groups.push_back({k});
    } else {
      const size_t first = groups[group_of[g]].front();
      if (s.parameters[k].values.size() != s.parameters[first].values.size())
        throw InputError(fmt::format("{}: parameters[{}]: {} values, but parameters[{}] of the same zipped group has {}",
                                     file, k, s.parameters[k].values.size(), first, s.parameters[first].values.size()));
      groups[group_of[g]].push_back(k);
    }
  }
  size_t total = 1;
  for (const auto& g : groups) {
    total *= s.parameters[g.front()].values.size();
    if (total > kMaxRuns) throw InputError(fmt::format("{}: the sweep has more than {} runs", file, kMaxRuns));
  }
  s.runs.assign(total, std::vector<size_t>(s.parameters.size(), 0));
  for (size_t run = 0; run < total; ++run) {
    size_t rest = run;
    for (size_t gi = groups.size(); gi-- > 0;) {
      const size_t n = s.parameters[groups[gi].front()].values.size();
      for (size_t k : groups[gi]) s.runs[run][k] = rest % n;
      rest /= n;
    }
  }
  return s;
}

Sweep load_sweep(const fs::path& path) {
  if (!fs::is_regular_file(path)) throw InputError(fmt::format("{}: no such sweep file", path.string()));
  const Json j = load_json(path.string());
  return parse_sweep(j, path.string(), path.has_parent_path() ? path.parent_path() : fs::path("."));
}

Json to_json(const RunResult& r) {
  Json j{{"run", r.run},       {"status", r.status},       {"message", r.message},
         {"wall_s", r.wall_s}, {"frames", r.frames},       {"steps", r.steps},
         {"iterations", r.iterations}, {"unconverged_steps", r.unconverged}, {"resumed_from", r.resumed_from},
         {"rank", r.rank}};
  j["measures"] = Json::array();
  for (double m : r.measures) j["measures"].push_back(finite_or_null(m));
  return j;
}

RunResult result_from_json(const Json& j, const Sweep& sweep) {
  RunResult r;
  r.run = j.at("run").get<size_t>();
  r.status = j.at("status").get<std::string>();
  if (r.status != "ok" && r.status != "failed") throw Error("unknown status " + r.status);
  r.message = j.at("message").get<std::string>();
  r.wall_s = j.at("wall_s").get<double>();
  r.frames = j.at("frames").get<int>();
  r.steps = j.at("steps").get<long>();
  r.iterations = j.at("iterations").get<long>();
  r.unconverged = j.at("unconverged_steps").get<long>();
  r.resumed_from = j.at("resumed_from").get<int>();
  r.rank = j.at("rank").get<int>();
  for (const Json& m : j.at("measures"))
    r.measures.push_back(m.is_null() ? std::numeric_limits<double>::quiet_NaN() : m.get<double>());
  if (r.status == "ok" && r.measures.size() != sweep.measure_columns().size())
    throw Error("result has another sweep's measures");
  return r;
}

fs::path run_folder(const fs::path& out, size_t run) { return out / "runs" / fmt::format("{:05d}", run); }

void prepare_output(const Sweep& sweep, const fs::path& out, bool resume) {
  const fs::path file = out / kDescriptionFile;
  const Json mine = sweep.description();
  if (resume) {
    if (!fs::exists(file))
      throw InputError(fmt::format("{}: no sweep to resume here (no {}); start it without --resume", out.string(),
                                   kDescriptionFile));
    Json theirs;
    try {
      theirs = parse_json(read_file(file), file.string());
    } catch (const Error& e) {
      throw InputError(fmt::format("{}: cannot resume: {}", out.string(), e.what()));
    }
    if (theirs != mine)
      throw InputError(fmt::format("{}: was started by a different sweep (its scene, runs or measures differ from {}'s); "
                                   "resume it with the sweep file that started it, or choose another --out",
                                   out.string(), sweep.file));
    return;
  }
  if (fs::exists(file) || fs::exists(out / "runs"))
    throw InputError(fmt::format("{}: already holds a sweep; continue it with --resume, or choose another --out",
                                 out.string()));
  fs::create_directories(out / "runs");
  write_file_atomic(file, mine.dump(1) + "\n");
}

std::optional<RunResult> read_result(const Sweep& sweep, const fs::path& out, size_t run) {
  const fs::path file = run_folder(out, run) / kResultFile;
  if (!fs::exists(file)) return std::nullopt;
  try {
    RunResult r = result_from_json(parse_json(read_file(file), file.string()), sweep);
    if (r.run != run) return std::nullopt;
    return r;
  } catch (const std::exception&) {
    return std::nullopt;  // a damaged result is no result: the run is done again
  }
}

std::optional<RunResult> execute_run(const Sweep& sweep, const fs::path& out, size_t run, const RunOptions& options) {
  const fs::path dir = run_folder(out, run);
  Timer timer;
  RunResult res;
  res.run = run;
  res.rank = options.rank;
  try {
    fs::create_directories(dir);
    sim::Scene scene = sim::parse_scene(sweep.run_scene(run), sweep.scene_file.string(), sweep.scene_file.parent_path());
    scene.output.dir = dir.string();
    if (options.threads > 0) scene.threads = options.threads;
    else if (sweep.threads > 0) scene.threads = sweep.threads;
    else if (scene.threads == 0) scene.threads = options.default_threads;
    if (sweep.frames != "all") scene.output.every = std::max(1, scene.frames);
    const int total = scene.frames;
    sim::Simulator sim(std::move(scene));
    sim::check_solver_fits(sim);
    sim::Recorder rec(dir, sim);
    bool resumed = false;
    if (fs::exists(dir / "checkpoint.bin")) {
      try {
        rec.resume(sim);
        resumed = true;
        res.resumed_from = sim.frame();
      } catch (const InputError&) {
        // A checkpoint written by a killed process before it was complete, or by another scene: start over.
      }
    }
    if (!resumed) rec.start(sim);
    while (sim.frame() < total) {
      if (options.stop && options.stop()) {
        rec.finish(sim);
        return std::nullopt;
      }
      const auto stats = sim.advance_frame();
      rec.record_frame(sim, stats);
      for (const auto& s : stats) {
        ++res.steps;
        res.iterations += s.report.iterations;
        if (!s.report.converged) ++res.unconverged;
      }
    }
    rec.finish(sim);
    for (const Measure& m : sweep.measures)
      for (double v : evaluate(m, sim)) res.measures.push_back(v);
    res.frames = sim.frame();
    res.status = "ok";
    if (sweep.frames != "all") {
      // output.every = frames: only frame 0 and the last were written.
      for (int f : {0, res.frames})
        if (f < res.frames || sweep.frames == "none") {
          fs::remove(sim::Recorder::frame_path(dir, f));
          fs::remove(sim::Recorder::obstacle_frame_path(dir, f));
        }
      fs::remove(dir / "checkpoint.bin");  // a finished run is not resumed
    }
  } catch (const std::bad_alloc&) {
    res.status = "failed";
    res.message = "out of memory";
  } catch (const std::exception& e) {
    res.status = "failed";
    res.message = e.what();
  }
  if (res.status == "failed") res.measures.clear();
  res.wall_s = timer.seconds();
  fs::create_directories(dir);
  write_file_atomic(dir / kResultFile, to_json(res).dump(1) + "\n");
  return res;
}

std::string summary_csv(const Sweep& sweep, const std::vector<std::optional<RunResult>>& results) {
  const auto params = sweep.parameter_columns();
  const auto measures = sweep.measure_columns();
  std::vector<std::string> header{"run", "status"};
  for (const auto& c : params) header.push_back(c);
  for (const char* c : {"wall_s", "last_frame", "steps", "iterations", "unconverged_steps"}) header.push_back(c);
  for (const auto& c : measures) header.push_back(c);
  for (const char* c : {"rank", "resumed_from", "message", "folder"}) header.push_back(c);
  std::string text = fmt::format("{}\n", fmt::join(header, ","));
  for (size_t run = 0; run < sweep.size(); ++run) {
    std::vector<std::string> row{std::to_string(run)};
    const RunResult* r = run < results.size() && results[run] ? &*results[run] : nullptr;
    row.push_back(r ? r->status : "pending");
    for (size_t p = 0; p < sweep.parameters.size(); ++p)
      row.push_back(csv_value(sweep.parameters[p].values[sweep.runs[run][p]]));
    if (r) {
      row.push_back(fmt::format("{:.3f}", r->wall_s));
      row.push_back(std::to_string(r->frames));
      row.push_back(std::to_string(r->steps));
      row.push_back(std::to_string(r->iterations));
      row.push_back(std::to_string(r->unconverged));
      for (size_t m = 0; m < measures.size(); ++m)
        row.push_back(m < r->measures.size() ? number_text(r->measures[m]) : std::string());
      row.push_back(std::to_string(r->rank));
      row.push_back(std::to_string(r->resumed_from));
      row.push_back(csv_field(r->message));
    } else {
      row.insert(row.end(), 5 + measures.size() + 3, std::string());
    }
    row.push_back(fmt::format("runs/{:05d}", run));
    text += fmt::format("{}\n", fmt::join(row, ","));
  }
  return text;
}

void write_summary(const Sweep& sweep, const fs::path& out, const std::vector<std::optional<RunResult>>& results) {
  write_file_atomic(out / kSummaryFile, summary_csv(sweep, results));
}

void SummaryWriter::write(const std::vector<std::optional<RunResult>>& results) {
  const auto start = std::chrono::steady_clock::now();
  write_summary(m_sweep, m_out, results);
  m_last = std::chrono::steady_clock::now();
  m_cost = std::chrono::duration<double>(m_last - start).count();
  m_pending = false;
}

bool SummaryWriter::due() const {
  return m_pending && std::chrono::duration<double>(std::chrono::steady_clock::now() - m_last).count() >= 10.0 * m_cost;
}

void SummaryWriter::update(const std::vector<std::optional<RunResult>>& results) {
  m_pending = true;
  if (due()) write(results);
}

void SummaryWriter::flush(const std::vector<std::optional<RunResult>>& results) {
  if (m_pending || m_last == std::chrono::steady_clock::time_point{}) write(results);
}

std::vector<size_t> pending_runs(const Sweep& sweep, const fs::path& out, std::vector<std::optional<RunResult>>& results,
                                 bool retry_failed) {
  results.assign(sweep.size(), std::nullopt);
  std::vector<size_t> pending;
  for (size_t run = 0; run < sweep.size(); ++run) {
    results[run] = read_result(sweep, out, run);
    if (results[run] && retry_failed && results[run]->status == "failed") {
      fs::remove(run_folder(out, run) / kResultFile);
      results[run].reset();
    }
    if (!results[run]) pending.push_back(run);
  }
  return pending;
}

std::vector<std::optional<RunResult>> run_serial(const Sweep& sweep, const fs::path& out, bool resume, bool retry_failed,
                                                 const RunOptions& options,
                                                 const std::function<void(const RunResult&)>& on_result) {
  prepare_output(sweep, out, resume);
  std::vector<std::optional<RunResult>> results;
  const std::vector<size_t> pending = pending_runs(sweep, out, results, retry_failed);
  SummaryWriter summary(sweep, out);
  summary.flush(results);
  for (size_t run : pending) {
    if (options.stop && options.stop()) break;
    std::optional<RunResult> r = execute_run(sweep, out, run, options);
    if (!r) break;  // stopped inside the run: it stays partial
    results[run] = std::move(r);
    summary.update(results);
    if (on_result) on_result(*results[run]);
  }
  summary.flush(results);
  return results;
}

}  // namespace mgcloth::sweep
