#include <mgcloth/collision/intersections.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/sim/checkpoint.hpp>
#include <mgcloth/sim/recorder.hpp>
#include <mgcloth/studies/convergence.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

namespace mgcloth::studies {

namespace fs = std::filesystem;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// The timed runs stop on the budget or the iteration cap, not on the gradient: a relative gradient this small is
/// below what double precision resolves in the energy.
constexpr double kTimedRelGrad = 1e-14;

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> parts;
  std::string part;
  std::istringstream in(s);
  while (std::getline(in, part, sep)) parts.push_back(part);
  if (s.empty() || s.back() == sep) parts.emplace_back();
  return parts;
}

/// A JSON scalar, or the text itself as an unquoted string.
Json parse_scalar(const std::string& spec, const std::string& key, const std::string& text) {
  Json v = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (v.is_discarded()) return text;
  if (v.is_array() || v.is_object())
    throw_input_error("solver \"{}\": {}: expected a number, true/false or a string, got {}", spec, key, text);
  return v;
}

bool has_solver(const std::string& name) {
  const auto names = solvers::solver_names();
  return std::find(names.begin(), names.end(), name) != names.end();
}

/// The solver that simulates the steps before the benchmarked one and gives the elastic form's E*.
SolverSpec elastic_reference() {
  if (has_solver("newton-direct")) return parse_solver_spec("newton-direct");
  return parse_solver_spec("newton@linear_solver=cholmod");
}

/// The studied body's index among the scene's bodies (its cloths, then its shells).
size_t study_body(const sim::Scene& scene, const std::string& name) {
  std::vector<std::string> names;
  for (const auto& c : scene.cloths) names.push_back(c.name);
  for (const auto& s : scene.shells) names.push_back(s.name);
  if (names.empty()) throw_input_error("{}: the scene has no bodies", scene.file);
  if (name.empty()) return 0;
  for (size_t b = 0; b < names.size(); ++b)
    if (names[b] == name) return b;
  throw_input_error("body: {} has no body named \"{}\" (its bodies: {})", scene.file, name, fmt::join(names, ", "));
}

std::string form_name(bool projective) { return projective ? "projective" : "elastic"; }

/// The scene with `spec` as its solver (its stop criteria kept), in the energy form the solver was made for (the
/// study compares each solver on its own form), and the options' thread count.
sim::Scene with_solver(sim::Scene scene, const SolverSpec& spec, int threads) {
  // Without cloth contact a joint objective is the sum of its bodies' own: one body's step is its block, solved on
  // its own. Contact couples the cloths, and only their group's step is the problem a simulation solves.
  if (!frozen_group_is_scenes(scene)) scene.solve_jointly = false;
  scene.solver.name = spec.config.name;
  scene.solver.params = spec.config.params;
  scene.energy_form = check_solver_spec(spec) ? physics::EnergyForm::Projective : physics::EnergyForm::Elastic;
  if (threads > 0) scene.threads = threads;
  return scene;
}

/// A simulator of `scene` with `spec` as its solver, in `state`.
std::unique_ptr<sim::Simulator> simulator_at(const sim::Scene& scene, const SolverSpec& spec, int threads, const SimState& state) {
  auto sim = std::make_unique<sim::Simulator>(with_solver(scene, spec, threads));
  sim->set_state(state.frame, state.step, state.x, state.v);
  return sim;
}

/// The group of the studied body in `sim` (the body's own without cloth contact; see with_solver).
size_t study_group(const sim::Simulator& sim, const sim::Scene& scene, const std::string& body) {
  return sim.group_of(study_body(scene, body));
}

/// Cloth contact at x, measured as Simulator::step measures it for stats.csv (the exact checker always runs here:
/// the guarantee is what the study checks).
ContactCheck contact_check(const physics::ClothContact* contact, const VecX& x) {
  ContactCheck c;
  if (!contact) return c;
  const physics::ContactStats cs = contact->stats(x);
  c.pairs = cs.pairs;
  c.min_distance = cs.min_distance;
  size_t count = 0;
  const VecX all = contact->with_kinematic(x);
  collision::find_intersections(all, contact->triangles(), 0, &count, contact->cloth_triangles(),
                                &contact->joined_points());
  c.intersections = static_cast<Index>(count);
  return c;
}

double rel_grad_of(const solvers::SolveReport& r) {
  return r.initial_grad_norm > 0.0 ? r.grad_norm / r.initial_grad_norm : 0.0;
}

/// The reference cache: E* solves are the longest part of a benchmark (minutes at 120K vertices), and a series of
/// runs on one frozen step (Fig. 4, 6, 7) needs the same E*. It lives next to the state cache, as one JSON object
/// per line: {"key": …, "reference": …}; the key is everything the reference depends on.
fs::path reference_cache_file(const std::string& state_cache) { return state_cache + ".references"; }

Json reference_to_json(const ReferenceEnergy& r) {
  return {{"form", r.form},   {"solver", r.solver},       {"energy", r.energy},   {"initial_energy", r.initial_energy},
          {"iterations", r.iterations}, {"rel_grad", r.rel_grad}, {"status", r.status}, {"reached", r.reached},
          {"seconds", r.seconds}};
}

Json reference_report(const ReferenceEnergy& r) {
  Json j = reference_to_json(r);
  j["polished_from"] = r.polished_from.empty() ? Json(nullptr) : Json(r.polished_from);
  j["unpolished_energy"] = r.polished_from.empty() ? Json(nullptr) : Json(r.unpolished_energy);
  return j;
}

std::optional<ReferenceEnergy> load_reference(const std::string& state_cache, const Json& key) {
  if (state_cache.empty()) return std::nullopt;
  std::ifstream in(reference_cache_file(state_cache));
  std::string line;
  while (std::getline(in, line)) {
    const Json j = Json::parse(line, nullptr, false);
    if (j.is_discarded() || !j.is_object() || !j.contains("key") || j["key"] != key || !j.contains("reference")) continue;
    try {
      const Json& r = j["reference"];
      ReferenceEnergy ref;
      ref.form = r.at("form").get<std::string>();
      ref.solver = r.at("solver").get<std::string>();
      ref.energy = r.at("energy").get<double>();
      ref.initial_energy = r.at("initial_energy").get<double>();
      ref.iterations = r.at("iterations").get<int>();
      ref.rel_grad = r.at("rel_grad").get<double>();
      ref.status = r.at("status").get<std::string>();
      ref.reached = r.at("reached").get<bool>();
      ref.seconds = r.at("seconds").get<double>();
      return ref;
    } catch (const Json::exception&) {
      continue;
    }
  }
  return std::nullopt;
}

void save_reference(const std::string& state_cache, const Json& key, const ReferenceEnergy& ref) {
  if (state_cache.empty()) return;
  const fs::path file = reference_cache_file(state_cache);
  std::string kept;
  {
    std::ifstream in(file);
    std::string line;
    while (std::getline(in, line)) {
      const Json j = Json::parse(line, nullptr, false);
      if (!j.is_discarded() && j.is_object() && j.contains("key") && j["key"] != key) kept += line + "\n";
    }
  }
  write_file_atomic(file, kept + Json{{"key", key}, {"reference", reference_to_json(ref)}}.dump() + "\n");
}

ReferenceEnergy solve_reference(const sim::Scene& scene, const SolverSpec& spec, bool projective, int max_iters,
                                const ConvergenceOptions& opt, const SimState& state, const VecX& x0, const VecX& from);

/// E* of one form: the reference solver from x0 to opt.reference_rel_grad.
ReferenceEnergy reference_energy(const sim::Scene& scene, const SolverSpec& spec, bool projective, int max_iters,
                                 const ConvergenceOptions& opt, const SimState& state, const VecX& x0,
                                 const Json& state_key) {
  Json key = {{"state", state_key},         {"form", form_name(projective)},
              {"solver", spec.label},       {"rel_grad", opt.reference_rel_grad},
              {"max_iters", max_iters},     {"max_seconds", opt.reference_max_seconds},
              {"threads", opt.threads}};
  if (!opt.body.empty()) key["body"] = opt.body;  // (caches of the first body written before --body stay valid)
  if (auto cached = load_reference(opt.state_cache, key)) {
    logger().info("E* ({} form) = {:.15e} read from {}", cached->form, cached->energy,
                  reference_cache_file(opt.state_cache).string());
    return *cached;
  }
  ReferenceEnergy ref = solve_reference(scene, spec, projective, max_iters, opt, state, x0, x0);
  save_reference(opt.state_cache, key, ref);
  return ref;
}

/// The reference solver of one form from `from` (x0, or a solver's final iterate that went below E*) to
/// opt.reference_rel_grad, the gradient norm relative to the one at x0 in both cases.
ReferenceEnergy solve_reference(const sim::Scene& scene, const SolverSpec& spec, bool projective, int max_iters,
                                const ConvergenceOptions& opt, const SimState& state, const VecX& x0, const VecX& from) {
  auto sim = simulator_at(scene, spec, opt.threads, state);
  VecX start;
  const size_t group = study_group(*sim, scene, opt.body);
  solvers::Problem problem = sim->prepare_problem(group, start);
  VecX x = from;
  ReferenceEnergy ref;
  ref.form = form_name(projective);
  ref.solver = spec.label;
  ref.initial_energy = problem.objective->value(x0);
  VecX g0;
  problem.objective->gradient(x0, g0);
  const double g0_norm = g0.norm();
  solvers::Stop stop;
  stop.rel_grad = 0.0;
  stop.abs_grad = opt.reference_rel_grad * g0_norm;
  stop.max_iters = max_iters;
  stop.max_seconds = opt.reference_max_seconds;
  Timer timer;
  const solvers::SolveReport r = sim->solver(group).minimize(problem, x, stop, nullptr);
  ref.seconds = timer.seconds();
  ref.energy = problem.objective->value(x);
  ref.iterations = r.iterations;
  ref.rel_grad = g0_norm > 0.0 ? r.grad_norm / g0_norm : 0.0;
  ref.status = r.status;
  ref.reached = ref.rel_grad <= opt.reference_rel_grad;
  if (!ref.reached)
    logger().warn("E* of the {} form: {} stopped ({}) at relative gradient {:.2e} after {} iterations, not {:.0e}; "
                  "using its final energy",
                  ref.form, spec.label, r.status, ref.rel_grad, r.iterations, opt.reference_rel_grad);
  logger().info("E* ({} form) = {:.15e} by {} in {} iterations ({:.2f} s, relative gradient {:.1e}, {})", ref.form,
                ref.energy, spec.label, ref.iterations, ref.seconds, ref.rel_grad, r.status);
  return ref;
}

void check_options(const ConvergenceOptions& opt) {
  if (opt.step < 1) throw_input_error("step: must be at least 1 (got {})", opt.step);
  if (opt.solvers.empty()) throw_input_error("solvers: the list is empty");
  if (!(opt.budget_seconds > 0.0)) throw_input_error("budget: must be a positive number of seconds (got {})", opt.budget_seconds);
  if (opt.max_iters < 1) throw_input_error("max iterations: must be at least 1 (got {})", opt.max_iters);
  if (opt.threads < 0) throw_input_error("threads: must be non-negative (got {})", opt.threads);
  for (size_t i = 0; i < opt.solvers.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (opt.solvers[i].label == opt.solvers[j].label) throw_input_error("solvers: \"{}\" is listed twice", opt.solvers[i].label);
}

}  // namespace

SolverSpec parse_solver_spec(const std::string& text) {
  SolverSpec s;
  s.label = trim(text);
  const std::vector<std::string> parts = split(s.label, '@');
  s.config.name = parts[0];
  if (s.config.name.empty()) throw_input_error("solver \"{}\": empty solver name", s.label);
  for (size_t i = 1; i < parts.size(); ++i) {
    const std::string& p = parts[i];
    const auto eq = p.find('=');
    if (eq == std::string::npos) throw_input_error("solver \"{}\": \"{}\" is not key=value", s.label, p);
    const std::string key = p.substr(0, eq), value = p.substr(eq + 1);
    if (key.empty()) throw_input_error("solver \"{}\": \"{}\" has no key", s.label, p);
    if (value.empty()) throw_input_error("solver \"{}\": {}: empty value", s.label, key);
    if (s.config.params.contains(key)) throw_input_error("solver \"{}\": {} is given twice", s.label, key);
    s.config.params[key] = parse_scalar(s.label, key, value);
  }
  return s;
}

std::vector<SolverSpec> parse_solver_list(const std::string& list) {
  if (trim(list).empty()) throw_input_error("the solver list is empty");
  std::vector<SolverSpec> specs;
  for (const std::string& item : split(list, ',')) {
    if (trim(item).empty()) throw_input_error("solver list \"{}\": empty entry", list);
    specs.push_back(parse_solver_spec(item));
  }
  return specs;
}

bool check_solver_spec(const SolverSpec& spec) {
  return solvers::make_solver(spec.config, fmt::format("solver \"{}\"", spec.label), spec.config.name)->energy_forms().front() ==
         physics::EnergyForm::Projective;
}

bool frozen_group_is_scenes(const sim::Scene& scene) { return scene.cloth_contact.enabled && !scene.cloths.empty(); }

double relative_energy_error(double energy, double initial_energy, double min_energy) {
  const double range = initial_energy - min_energy;
  if (!(range > 0.0)) return kNaN;
  return (energy - min_energy) / range;
}

sim::Scene with_vertex_count(sim::Scene scene, Index vertices) {
  if (vertices < 4 || vertices > 5'000'000)
    throw_input_error("vertex count must be within [4, 5000000] (got {})", vertices);
  for (size_t i = 0; i < scene.cloths.size(); ++i) {
    bodies::MeshSource& m = scene.cloths[i].mesh;
    if (!m.file.empty())
      throw_input_error("{}: cloths[{}] (\"{}\"): the mesh is read from {}; only generated meshes can be given a vertex count",
                        scene.file, i, scene.cloths[i].name, m.file);
    if (m.generator == "tube") {
      if (vertices < 8) throw_input_error("vertex count: a tube needs at least 8 vertices (got {})", vertices);
      m.tube.target_vertices = vertices;
    } else {
      m.rectangle.target_vertices = vertices;
    }
  }
  return scene;
}

SimState simulator_state(const sim::Simulator& sim) {
  SimState st;
  st.step = sim.step_count();
  st.frame = static_cast<int>(st.step / sim.scene().substeps);
  for (const auto& b : sim.bodies()) {  // every body, shells too: Simulator::set_state takes them all
    st.x.push_back(b->x());
    st.v.push_back(b->v());
  }
  return st;
}

Json state_cache_key(const sim::Scene& scene) {
  Json s = to_json(scene);
  for (const char* unrelated : {"frames", "threads", "output"}) s.erase(unrelated);
  for (auto& c : s["cloths"])
    if (c["mesh"].contains("file")) {
      std::error_code ec;
      const fs::path f = c["mesh"]["file"].get<std::string>();
      c["mesh"]["file_size"] = static_cast<long long>(fs::file_size(f, ec));
      c["mesh"]["file_time"] = static_cast<long long>(fs::last_write_time(f, ec).time_since_epoch().count());
    }
  return s;
}

std::optional<SimState> load_state_cache(const fs::path& file, const Json& key) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return std::nullopt;
  std::string header;
  if (!std::getline(in, header)) return std::nullopt;
  const Json h = Json::parse(header, nullptr, false);
  if (h.is_discarded() || !h.is_object() || h.value("format", "") != "mgcloth state cache 1" || !h.contains("key") ||
      h["key"] != key)
    return std::nullopt;
  SimState st;
  try {
    st.frame = h.at("frame").get<int>();
    st.step = h.at("step").get<long>();
    for (const auto& n : h.at("dofs")) {
      const auto dofs = n.get<Index>();
      for (auto* vectors : {&st.x, &st.v}) {
        VecX v(dofs);
        in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(sizeof(double) * dofs));
        vectors->push_back(std::move(v));
      }
    }
  } catch (const Json::exception&) {
    return std::nullopt;
  }
  if (!in || in.peek() != std::char_traits<char>::eof()) return std::nullopt;
  return st;
}

void save_state_cache(const fs::path& file, const Json& key, const SimState& state) {
  Json dofs = Json::array();
  for (const auto& x : state.x) dofs.push_back(x.size());
  const Json header = {{"format", "mgcloth state cache 1"}, {"key", key}, {"frame", state.frame}, {"step", state.step},
                       {"dofs", dofs}};
  write_file_atomic(
      file,
      [&](std::ostream& out) {
        out << header.dump() << '\n';
        for (size_t c = 0; c < state.x.size(); ++c)
          for (const VecX* v : {&state.x[c], &state.v[c]})
            out.write(reinterpret_cast<const char*>(v->data()), static_cast<std::streamsize>(sizeof(double) * v->size()));
      },
      /*binary=*/true);
}

std::optional<double> time_to_error(const std::vector<ConvergenceRow>& rows, const std::string& solver, double level) {
  for (const auto& r : rows)
    if (r.solver == solver && r.rel_energy_error <= level) return r.wall_s;
  return std::nullopt;
}

namespace {

/// The non-convex step problems (buckling cloth) have several local minima; a solver may settle in a lower one
/// than the reference did from x0. Its final iterate is kept, per form, to polish E* after all runs.
struct Lowest {
  double energy = kInf;
  VecX x;
  std::string solver;
};

/// What the parts of one convergence study share. Forms are indexed 0 (elastic) and 1 (projective).
struct Study {
  const sim::Scene& scene;
  const ConvergenceOptions& opt;
  size_t body = 0;                 ///< study_body(scene, opt.body)
  size_t group = 0;                ///< its group in the study's simulators (study_group)
  std::vector<bool> projective;    ///< per opt.solvers: whether it minimizes the Projective Dynamics form
  SolverSpec elastic;              ///< gives the elastic form's E*
  SolverSpec warmup{};             ///< simulates steps 1 … K − 1
  Json key{};                      ///< what the state at the start of step K depends on
  SimState state{};                ///< the state at the start of step K
  VecX x0{};                       ///< the frozen problem's start point, the same for every solver
  std::array<int, 2> ref_index{-1, -1};  ///< per form: its E*'s place in result.references (-1: no solver of it)
  std::array<Lowest, 2> lowest{};
  const sim::Checkpoint* checkpoint = nullptr;  ///< ConvergenceOptions::checkpoint, read

  bool any(bool pd) const { return std::find(projective.begin(), projective.end(), pd) != projective.end(); }
  /// The reference solver of a form and its iteration cap.
  SolverSpec reference_solver(bool pd) const { return pd ? parse_solver_spec("pd-direct") : elastic; }
  int reference_max_iters(bool pd) const { return pd ? opt.pd_reference_max_iters : opt.reference_max_iters; }
};

/// Every check that needs no simulation: the options, the body, and every solver spec built once, so that a typo
/// fails before anything is simulated. Returns per spec whether it is projective.
std::vector<bool> check_study(const sim::Scene& scene, const ConvergenceOptions& opt) {
  check_options(opt);
  const size_t body = study_body(scene, opt.body);
  std::vector<bool> projective;
  for (const auto& spec : opt.solvers) projective.push_back(check_solver_spec(spec));
  // Refused here, all at once, rather than by the first prepare_problem after minutes of simulated steps.
  const bool contact = scene.cloth_contact.enabled && (body < scene.cloths.size() || scene.solve_jointly);
  std::vector<std::string> refused;
  for (const auto& spec : opt.solvers)
    if (contact && !solvers::make_solver(spec.config, spec.label, spec.config.name)->supports_step_limits())
      refused.push_back(fmt::format("\"{}\"", spec.label));
  if (!refused.empty())
    throw_input_error("{}: the frozen step has cloth contact, and solver{} {} do{} not keep {} trial points "
                      "intersection-free; those that do: {}", scene.file, refused.size() > 1 ? "s" : "",
                      fmt::join(refused, ", "), refused.size() > 1 ? "" : "es", refused.size() > 1 ? "their" : "its",
                      fmt::join(solvers::step_limiting_solvers(), ", "));
  const bool any_projective = std::find(projective.begin(), projective.end(), true) != projective.end();
  if (any_projective && !has_solver("pd-direct"))
    throw_input_error("the Projective Dynamics solvers need \"pd-direct\" for their E*, and this build has no such "
                      "solver (available: {})", fmt::join(solvers::solver_names(), ", "));
  return projective;
}

/// The state at the start of step K: simulated with the warm-up solver and the scene's stop criteria, or cached.
SimState start_of_step(const Study& st, ConvergenceResult& result) {
  const long steps_before = st.opt.step - 1;
  if (const sim::Checkpoint* c = st.checkpoint) {
    result.start_state = "checkpoint";
    SimState from;
    from.frame = static_cast<int>(c->frame);
    from.step = static_cast<long>(c->step);
    for (const auto& b : c->bodies) {
      from.x.push_back(b.x);
      from.v.push_back(b.v);
    }
    logger().info("state at the start of step {} read from {}", st.opt.step, st.opt.checkpoint);
    return from;
  }
  std::optional<SimState> state;
  if (!st.opt.state_cache.empty()) state = load_state_cache(st.opt.state_cache, st.key);
  if (state) {
    result.start_state = "cache";
    logger().info("state at the start of step {} read from {}", st.opt.step, st.opt.state_cache);
    return *state;
  }
  result.start_state = "simulated";
  sim::Simulator sim(with_solver(st.scene, st.warmup, st.opt.threads));
  Timer timer;
  while (sim.step_count() < steps_before) {
    sim.step();
    logger().info("step {}/{} simulated with {} ({:.1f} s)", sim.step_count(), steps_before, st.warmup.label,
                  timer.seconds());
  }
  state = simulator_state(sim);
  if (!st.opt.state_cache.empty()) {
    save_state_cache(st.opt.state_cache, st.key, *state);
    logger().info("state at the start of step {} cached in {}", st.opt.step, st.opt.state_cache);
  }
  return *state;
}

/// The frozen problem's start point, from a simulator of the elastic form, with its group, its bodies and, with
/// cloth contact, the contact there.
VecX frozen_start(Study& st, ConvergenceResult& result) {
  VecX x0;
  auto sim = simulator_at(st.scene, st.elastic, st.opt.threads, st.state);
  st.group = study_group(*sim, st.scene, st.opt.body);
  (void)sim->prepare_problem(st.group, x0);
  const bodies::Assembly& group = sim->group(st.group);
  for (const bodies::Body* b : group.bodies()) result.bodies.push_back(b->name());
  result.cloth_contact = group.cloth_contact() != nullptr;
  result.start = contact_check(group.cloth_contact(), x0);
  return x0;
}

/// E* per energy form that some solver minimizes, in result.references (st.ref_index says where).
void find_references(Study& st, ConvergenceResult& result) {
  for (const bool pd : {false, true}) {
    if (!st.any(pd)) continue;
    st.ref_index[pd ? 1 : 0] = static_cast<int>(result.references.size());
    result.references.push_back(reference_energy(st.scene, st.reference_solver(pd), pd, st.reference_max_iters(pd),
                                                 st.opt, st.state, st.x0, st.key));
  }
}

/// A solver that diverges is a result, not the end of the benchmark: its trace up to the failure is kept and its
/// status says why it stopped.
void record_divergence(const SolveError& err, const solvers::Trace& so_far, const SolverSpec& spec,
                       SolverSummary& summary) {
  logger().warn("{}: {}", spec.label, err.what());
  summary.status = fmt::format("diverged: {}", err.what());
  summary.iterations = so_far.empty() ? 0 : so_far.back().iteration;
  summary.final_error = kNaN;
}

/// Warm-up: one iteration on a copy of x0 does the set-up a simulation does once (analyses, colorings,
/// hierarchies), so the timed run measures what every step costs. False (with the summary saying why) when the
/// solver diverged or cannot run on this problem.
bool warm_up(solvers::NonlinearSolver& solver, solvers::Problem& problem, const VecX& x0, const SolverSpec& spec,
             SolverSummary& summary) {
  try {
    VecX x = x0;
    solvers::Stop stop;
    stop.rel_grad = kTimedRelGrad;
    stop.max_iters = 1;
    solver.minimize(problem, x, stop, nullptr);
  } catch (const SolveError& err) {
    record_divergence(err, {}, spec, summary);
    return false;
  } catch (const InputError&) {
    throw;
  } catch (const Error& err) {
    // A solver that cannot run on this problem (e.g. a smoother that needs what the hierarchy does not provide)
    // is recorded as such; the other solvers' results are still measured and written.
    logger().warn("{}: {}", spec.label, err.what());
    summary.status = fmt::format("error: {}", err.what());
    summary.final_error = kNaN;
    return false;
  }
  return true;
}

/// The rows of one solver's trace, measured against E* = `min_energy`, and its summary's errors.
void add_rows(const solvers::Trace& trace, const std::string& solver, double min_energy, SolverSummary& summary,
              ConvergenceResult& result) {
  const double e0 = trace.front().energy;
  for (const auto& t : trace)
    result.rows.push_back({solver, t.iteration, t.wall_ms / 1e3, t.energy, t.grad_norm,
                           relative_energy_error(t.energy, e0, min_energy)});
  summary.final_error = result.rows.back().rel_energy_error;
  for (size_t l = 0; l < kErrorLevels.size(); ++l) summary.time_to[l] = time_to_error(result.rows, solver, kErrorLevels[l]);
}

/// The timed run of solver i from x0 to the budget or the iteration cap: its rows, its summary, and its final
/// iterate where it is the lowest of its form so far.
void timed_run(Study& st, size_t i, solvers::NonlinearSolver& solver, solvers::Problem& problem,
               const physics::ClothContact* contact, const ReferenceEnergy& ref, SolverSummary& summary,
               ConvergenceResult& result) {
  const SolverSpec& spec = st.opt.solvers[i];
  VecX x = st.x0;
  solvers::Stop stop;
  stop.rel_grad = kTimedRelGrad;
  stop.max_iters = st.opt.max_iters;
  stop.max_seconds = st.opt.budget_seconds;
  solvers::Trace trace;
  solvers::SolveReport report;
  Timer timer;
  bool failed = false;
  try {
    report = solver.minimize(problem, x, stop, &trace);
  } catch (const SolveError& err) {
    record_divergence(err, trace, spec, summary);
    summary.seconds = timer.seconds();
    failed = true;
  }
  if (trace.empty()) {
    if (!failed) throw_error("{}: the solver recorded no trace", spec.label);
    return;
  }
  add_rows(trace, spec.label, ref.energy, summary, result);
  if (failed) return;
  Lowest& low = st.lowest[st.projective[i] ? 1 : 0];
  if (trace.back().energy < low.energy) low = {trace.back().energy, x, spec.label};
  summary.iterations = report.iterations;
  summary.final_rel_grad = rel_grad_of(report);
  summary.seconds = report.wall_ms / 1e3;
  summary.status = report.status;
  summary.counters = report.counters;
  summary.contact = contact_check(contact, x);
  logger().info("{}: {} iterations in {:.2f} s ({}), relative energy error {:.2e}", spec.label, summary.iterations,
                summary.seconds, summary.status, summary.final_error);
  if (contact)
    logger().info("{}: at its end {} contact pairs, min distance {:.3e} m, {} intersections", spec.label,
                  summary.contact.pairs, summary.contact.min_distance, summary.contact.intersections);
}

/// Solver i on its own simulator, so that it gets the problem it gets in a simulation (hierarchy, coarse
/// objectives, energy form), from the same x0 as every other: warmed up, then timed.
void run_solver(Study& st, size_t i, ConvergenceResult& result) {
  const SolverSpec& spec = st.opt.solvers[i];
  const ReferenceEnergy& ref = result.references[static_cast<size_t>(st.ref_index[st.projective[i] ? 1 : 0])];
  auto sim = simulator_at(st.scene, spec, st.opt.threads, st.state);
  VecX own_start;
  solvers::Problem problem = sim->prepare_problem(st.group, own_start);
  if (own_start.size() != st.x0.size())
    throw_error("{}: its simulator has {} dofs, the reference's {}", spec.label, own_start.size(), st.x0.size());
  if ((own_start - st.x0).cwiseAbs().maxCoeff() > 1e-12)
    logger().warn("{}: its simulator predicts a different start point; every solver starts from the same x0", spec.label);
  solvers::NonlinearSolver& solver = sim->solver(st.group);
  SolverSummary summary;
  summary.solver = spec.label;
  summary.form = ref.form;
  Timer timer;
  if (warm_up(solver, problem, st.x0, spec, summary)) {
    summary.warmup_seconds = timer.seconds();
    timed_run(st, i, solver, problem, sim->group(st.group).cloth_contact(), ref, summary, result);
  }
  result.summaries.push_back(summary);
}

/// The rows and summaries of every solver of form `pd` measured again against `ref`.
void rescore(const Study& st, bool pd, const ReferenceEnergy& ref, ConvergenceResult& result) {
  for (size_t i = 0; i < st.opt.solvers.size(); ++i) {
    if (st.projective[i] != pd) continue;
    SolverSummary& s = result.summaries[i];
    double e0 = kNaN;
    for (auto& row : result.rows)
      if (row.solver == s.solver) {
        if (row.iteration == 0) e0 = row.energy;
        row.rel_energy_error = relative_energy_error(row.energy, e0, ref.energy);
        s.final_error = row.rel_energy_error;
      }
    for (size_t l = 0; l < kErrorLevels.size(); ++l) s.time_to[l] = time_to_error(result.rows, s.solver, kErrorLevels[l]);
  }
}

/// E* polished: where a solver ended below the reference's minimum, the reference solver continues from that
/// iterate to the same tolerance, and the lower of the two minima is E* for every solver of that form.
void polish_references(const Study& st, ConvergenceResult& result) {
  for (const bool pd : {false, true}) {
    const int index = st.ref_index[pd ? 1 : 0];
    if (index < 0) continue;
    ReferenceEnergy& ref = result.references[static_cast<size_t>(index)];
    const Lowest& low = st.lowest[pd ? 1 : 0];
    if (!(low.energy < ref.energy - 1e-9 * std::abs(ref.initial_energy - ref.energy))) continue;
    logger().info("{} ended at {:.15e}, below E* of the {} form: polishing E* from its final iterate", low.solver,
                  low.energy, ref.form);
    ReferenceEnergy polished = solve_reference(st.scene, st.reference_solver(pd), pd, st.reference_max_iters(pd),
                                               st.opt, st.state, st.x0, low.x);
    if (!(polished.energy < ref.energy)) continue;
    polished.polished_from = low.solver;
    polished.unpolished_energy = ref.energy;
    ref = polished;
    rescore(st, pd, ref, result);
  }
}

/// A run's checkpoint, checked against the scene and, when set, the step it must end.
sim::Checkpoint read_run_checkpoint(const sim::Scene& scene, const fs::path& file, int step) {
  if (!fs::exists(file)) throw_input_error("{}: no such checkpoint", file.string());
  sim::Checkpoint c = sim::decode_checkpoint(read_file(file), file);
  if (c.fingerprint != sim::scene_fingerprint(scene))
    throw_input_error("{}: written by a run of a different scene than {} (physics, cloths, obstacles or solver "
                      "differ)", file.string(), scene.file);
  const size_t bodies = scene.cloths.size() + scene.shells.size();
  if (c.bodies.size() != bodies)
    throw_input_error("{}: has {} bodies, {} has {}", file.string(), c.bodies.size(), scene.file, bodies);
  if (step != 0 && c.step + 1 != step)
    throw_input_error("--step {}: the checkpoint {} holds the start of step {}", step, file.string(), c.step + 1);
  return c;
}

}  // namespace

ConvergenceResult run_convergence(const sim::Scene& scene, const ConvergenceOptions& options) {
  ConvergenceOptions opt = options;
  std::optional<sim::Checkpoint> checkpoint;
  if (!opt.checkpoint.empty()) {
    checkpoint = read_run_checkpoint(scene, opt.checkpoint, opt.step);
    opt.step = static_cast<int>(checkpoint->step + 1);
  }
  Study st{.scene = scene, .opt = opt, .projective = check_study(scene, opt), .elastic = elastic_reference()};
  st.checkpoint = checkpoint ? &*checkpoint : nullptr;
  st.body = study_body(scene, opt.body);
  st.warmup = opt.warmup.label.empty() ? st.elastic : opt.warmup;
  if (opt.threads > 0) set_num_threads(opt.threads);

  ConvergenceResult result;
  result.scene = scene.file;
  result.cloth = st.body < scene.cloths.size() ? scene.cloths[st.body].name
                                               : scene.shells[st.body - scene.cloths.size()].name;
  result.step = opt.step;
  result.warmup_solver = st.warmup.label;
  if (scene.cloths.size() + scene.shells.size() > 1 && !frozen_group_is_scenes(scene))
    logger().info("{}: {} bodies; the benchmark freezes the objective of \"{}\" (--body) only", scene.file,
                  scene.cloths.size() + scene.shells.size(), result.cloth);

  st.key = {{"purpose", "start of a benchmarked step"},
            {"scene", state_cache_key(with_solver(scene, st.warmup, 0))},
            {"steps", static_cast<long>(opt.step - 1)}};
  st.state = start_of_step(st, result);
  st.x0 = frozen_start(st, result);
  result.vertices = static_cast<Index>(st.x0.size() / 3);
  logger().info("{}: step {} of {} ({} points{})", scene.file, opt.step, fmt::join(result.bodies, " + "),
                result.vertices, result.bodies.size() > 1 ? ", jointly: cloth contact couples them" : "");
  if (result.cloth_contact)
    logger().info("at x0: {} contact pairs, min distance {:.3e} m, {} intersections", result.start.pairs,
                  result.start.min_distance, result.start.intersections);

  find_references(st, result);
  for (size_t i = 0; i < opt.solvers.size(); ++i) run_solver(st, i, result);
  polish_references(st, result);
  return result;
}

std::string convergence_csv(const ConvergenceResult& result) {
  std::string out = "solver,iteration,wall_s,energy,grad_norm,rel_energy_error\n";
  for (const auto& r : result.rows)
    out += fmt::format("{},{},{:.9g},{:.17g},{:.17g},{:.17g}\n", r.solver, r.iteration, r.wall_s, r.energy, r.grad_norm,
                       r.rel_energy_error);
  return out;
}

namespace {
Json number_or_null(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }
Json number_or_null(const std::optional<double>& v) { return v ? Json(*v) : Json(nullptr); }
std::string level_key(double level) { return fmt::format("{:.0e}", level); }
Json contact_json(const ContactCheck& c) {
  // +inf (no pair within the contact's reach) is written as null, like every non-finite number here.
  return {{"contact_pairs", c.pairs}, {"min_distance", number_or_null(c.min_distance)}, {"intersections", c.intersections}};
}
}  // namespace

Json to_json(const ConvergenceResult& result, const ConvergenceOptions& opt) {
  Json refs = Json::array();
  for (const auto& r : result.references) {
    Json j = reference_report(r);
    j["how"] = fmt::format("{} from {} to relative gradient {:.0e}{}", r.solver,
                           r.polished_from.empty() ? "x0" : r.polished_from + "'s final iterate (a lower minimum than from x0)",
                           opt.reference_rel_grad, r.reached ? "" : " (not reached: its final energy is used)");
    refs.push_back(std::move(j));
  }
  Json solvers = Json::array();
  for (const auto& s : result.summaries) {
    Json time_to = Json::object();
    for (size_t l = 0; l < kErrorLevels.size(); ++l) time_to[level_key(kErrorLevels[l])] = number_or_null(s.time_to[l]);
    Json counters = Json::object();
    for (const auto& [name, value] : s.counters) counters[name] = number_or_null(value);
    solvers.push_back({{"solver", s.solver},
                       {"form", s.form},
                       {"iterations", s.iterations},
                       {"seconds", s.seconds},
                       {"warmup_seconds", s.warmup_seconds},
                       {"status", s.status},
                       {"final_error", number_or_null(s.final_error)},
                       {"final_rel_grad", s.final_rel_grad},
                       {"time_to", time_to},
                       {"counters", counters}});
    if (result.cloth_contact) solvers.back()["contact_at_end"] = contact_json(s.contact);
  }
  Json specs = Json::array();
  for (const auto& s : opt.solvers) specs.push_back({{"label", s.label}, {"name", s.config.name}, {"params", s.config.params}});
  Json out = {{"scene", result.scene},
             {"cloth", result.cloth},
             {"bodies", result.bodies},
             {"vertices", result.vertices},
             {"cloth_contact", result.cloth_contact},
             {"step", result.step},
             {"start_state", result.start_state},
             {"steps_before_by", result.warmup_solver},
             {"rel_energy_error", "(E_k - E*)/(E_0 - E*), E* of the solver's energy form"},
             {"timing", "each solver is warmed up by one untimed iteration on a copy of x0 (one-time set-up), then timed"},
             {"options",
              {{"step", opt.step},
               {"body", result.cloth},
               {"budget_seconds", opt.budget_seconds},
               {"max_iters", opt.max_iters},
               {"threads", opt.threads > 0 ? opt.threads : num_threads()},
               {"state_cache", opt.state_cache},
               {"checkpoint", opt.checkpoint},
               {"reference_rel_grad", opt.reference_rel_grad},
               {"reference_max_iters", opt.reference_max_iters},
               {"pd_reference_max_iters", opt.pd_reference_max_iters},
               {"reference_max_seconds", opt.reference_max_seconds},
               {"solvers", specs}}},
             {"references", refs},
             {"solvers", solvers}};
  if (result.cloth_contact) out["contact_at_x0"] = contact_json(result.start);
  return out;
}

std::vector<ScalabilityRow> run_scalability(const sim::Scene& scene, const ScalabilityOptions& opt) {
  if (opt.vertices.empty()) throw_input_error("vertices: the list is empty");
  if (opt.steps < 1) throw_input_error("steps: must be at least 1 (got {})", opt.steps);
  if (opt.warmup < 0) throw_input_error("warm-up steps: must be non-negative (got {})", opt.warmup);
  if (!(opt.rel_grad > 0.0 && opt.rel_grad < 1.0)) throw_input_error("relative gradient: must be in (0, 1) (got {})", opt.rel_grad);
  if (opt.threads < 0) throw_input_error("threads: must be non-negative (got {})", opt.threads);
  (void)check_solver_spec(opt.solver);
  for (Index n : opt.vertices) (void)with_vertex_count(scene, n);  // every count is checked before the first run
  if (opt.threads > 0) set_num_threads(opt.threads);

  std::vector<ScalabilityRow> rows;
  for (Index n : opt.vertices) {
    sim::Scene s = with_solver(with_vertex_count(scene, n), opt.solver, opt.threads);
    s.solver.stop.rel_grad = opt.rel_grad;
    s.solver.stop.abs_grad = 0.0;
    ScalabilityRow row;
    row.target_vertices = n;
    row.solver = opt.solver.label;
    Timer timer;
    sim::Simulator sim(std::move(s));
    row.setup_ms = timer.ms();
    for (const auto& c : sim.cloths()) row.vertices += c->mesh().num_vertices();
    for (int k = 0; k < opt.warmup; ++k) sim.step();
    long iterations = 0;
    double step_ms = 0.0, solve_ms = 0.0;
    for (int k = 0; k < opt.steps; ++k) {
      timer.reset();
      const auto stats = sim.step();
      step_ms += timer.ms();
      bool converged = true;
      for (const auto& st : stats) {
        iterations += st.report.iterations;
        solve_ms += st.report.wall_ms;
        converged = converged && st.report.converged;
        for (const auto& [name, value] : st.report.counters) {
          if (!name.ends_with("_ms") && !name.ends_with("_per_s")) continue;
          auto it = std::find_if(row.phases.begin(), row.phases.end(), [&n = name](const auto& p) { return p.first == n; });
          if (it == row.phases.end()) row.phases.push_back({name, value});
          else it->second += value;
        }
      }
      row.unconverged_steps += converged ? 0 : 1;
    }
    for (auto& p : row.phases) p.second /= static_cast<double>(opt.steps);
    row.ms_per_step = step_ms / opt.steps;
    row.solve_ms_per_step = solve_ms / opt.steps;
    row.iterations_per_step = static_cast<double>(iterations) / opt.steps;
    logger().info("{} vertices: {:.1f} ms per step, {:.1f} iterations per step ({})", row.vertices, row.ms_per_step,
                  row.iterations_per_step, row.solver);
    rows.push_back(row);
  }
  return rows;
}

std::string scalability_csv(const std::vector<ScalabilityRow>& rows, const ScalabilityOptions& opt) {
  std::string out = "vertices,solver,ms_per_step,iterations_per_step,solve_ms_per_step,unconverged_steps,target_vertices,"
                    "steps,warmup,rel_grad,threads,setup_ms,ms_per_iteration,phases\n";
  const int threads = opt.threads > 0 ? opt.threads : num_threads();
  for (const auto& r : rows) {
    std::string phases;
    for (const auto& [name, value] : r.phases) phases += fmt::format("{}{}={:.4g}", phases.empty() ? "" : ";", name, value);
    const double per_iteration = r.iterations_per_step > 0.0 ? r.solve_ms_per_step / r.iterations_per_step : 0.0;
    out += fmt::format("{},{},{:.6g},{:.6g},{:.6g},{},{},{},{},{:g},{},{:.6g},{:.6g},\"{}\"\n", r.vertices, r.solver,
                       r.ms_per_step, r.iterations_per_step, r.solve_ms_per_step, r.unconverged_steps, r.target_vertices,
                       opt.steps, opt.warmup, opt.rel_grad, threads, r.setup_ms, per_iteration, phases);
  }
  return out;
}

}  // namespace mgcloth::studies
