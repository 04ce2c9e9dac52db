#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/interrupt.hpp>
#include <mgcloth/core/json.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/studies/shell_bench.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <optional>
#include <random>

namespace mgcloth::studies {

namespace {
double counter(const ShellBenchRow& r, const std::string& name) {
  for (const auto& [k, v] : r.counters)
    if (k == name) return v;
  return 0.0;
}
bool has_counter(const ShellBenchRow& r, const std::string& name) {
  for (const auto& [k, v] : r.counters)
    if (k == name) return true;
  return false;
}

namespace fs = std::filesystem;

fs::path state_path(const ShellBenchOptions& opt, const std::string& shell, int level, const std::string& solver) {
  std::string name = fmt::format("{}-L{}-{}", shell, level, solver);
  for (char& c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.')) c = '_';
  return fs::path(opt.states_dir) / (name + ".state.json");
}

void write_state(const fs::path& path, const ShellBenchRow& r, const VecX& x, const std::vector<VecX>& levels) {
  Json c = Json::object();
  for (const auto& [k, v] : r.counters) c[k] = v;
  Json j = {{"format", "mgcloth shell bench state 1"}, {"scene", r.scene}, {"shell", r.shell}, {"level", r.level},
            {"solver", r.solver}, {"dofs", r.dofs}, {"iterations", r.iterations}, {"converged", r.converged},
            {"status", r.status}, {"energy", r.energy}, {"grad_norm", r.grad_norm},
            {"initial_grad_norm", r.initial_grad_norm}, {"wall_s", r.wall_s}, {"counters", c}};
  j["x"] = std::vector<double>(x.data(), x.data() + x.size());
  // The solver's own iterates besides x (RMTR's coarse levels), so that a resumed solve goes on as it would have.
  Json lv = Json::array();
  for (const VecX& v : levels) lv.push_back(std::vector<double>(v.data(), v.data() + v.size()));
  j["level_states"] = lv;
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  write_file_atomic(path, j.dump() + "\n");
}

/// The row and iterate of an earlier part of this solve; throws InputError naming the file where it is not one.
ShellBenchRow read_state(const fs::path& path, const ShellBenchRow& expect, VecX& x, std::vector<VecX>& levels) {
  const std::string file = path.string();
  const Json j = load_json(file);
  const auto field = [&](const char* key) -> const Json& {
    if (!j.is_object() || !j.contains(key)) throw_input_error("{}: not a shell bench state (no \"{}\")", file, key);
    return j.at(key);
  };
  try {
    if (field("format").get<std::string>() != "mgcloth shell bench state 1")
      throw_input_error("{}: format \"{}\" is not \"mgcloth shell bench state 1\"", file, field("format").get<std::string>());
    ShellBenchRow r;
    r.scene = field("scene").get<std::string>();
    r.shell = field("shell").get<std::string>();
    r.level = field("level").get<int>();
    r.solver = field("solver").get<std::string>();
    r.dofs = field("dofs").get<Index>();
    if (r.shell != expect.shell || r.level != expect.level || r.solver != expect.solver || r.dofs != expect.dofs)
      throw_input_error("{}: the state of shell \"{}\" at level {} ({} dofs) by {}, not of this solve (\"{}\", level {}, "
                        "{} dofs, {})", file, r.shell, r.level, r.dofs, r.solver, expect.shell, expect.level,
                        expect.dofs, expect.solver);
    r.time_step = expect.time_step;
    r.iterations = field("iterations").get<int>();
    r.converged = field("converged").get<bool>();
    r.status = field("status").get<std::string>();
    r.energy = field("energy").get<double>();
    r.grad_norm = field("grad_norm").get<double>();
    r.initial_grad_norm = field("initial_grad_norm").get<double>();
    r.wall_s = field("wall_s").get<double>();
    for (const auto& [k, v] : field("counters").items()) r.counters.emplace_back(k, v.get<double>());
    const auto values = field("x").get<std::vector<double>>();
    if (static_cast<Index>(values.size()) != r.dofs)
      throw_input_error("{}: \"x\" has {} entries, the shell {} dofs", file, values.size(), r.dofs);
    x = Eigen::Map<const VecX>(values.data(), static_cast<Index>(values.size()));
    if (!x.allFinite()) throw_input_error("{}: \"x\" has a non-finite entry", file);
    levels.clear();
    if (j.contains("level_states")) {  // absent in states written before it existed
      for (const auto& v : j.at("level_states")) {
        const auto values = v.get<std::vector<double>>();
        levels.push_back(Eigen::Map<const VecX>(values.data(), static_cast<Index>(values.size())));
        if (!levels.back().allFinite()) throw_input_error("{}: \"level_states\" has a non-finite entry", file);
      }
    }
    if (r.iterations < 0 || !(r.wall_s >= 0.0)) throw_input_error("{}: negative iterations or wall_s", file);
    return r;
  } catch (const Json::exception& e) {
    throw_input_error("{}: {}", file, e.what());
  }
}
/// Counters of the first part of a solve that a resumed part keeps: its nested cycles and where it started from.
bool spent_by_first_part(const std::string& counter) {
  return counter.find("_nested_cycles") != std::string::npos || counter == "started_from_level";
}

}  // namespace

ShellBenchState read_shell_bench_state(const std::string& file) {
  const Json j = load_json(file);
  ShellBenchRow expect;
  try {
    if (!j.is_object() || !j.contains("shell") || !j.contains("level") || !j.contains("solver") || !j.contains("dofs"))
      throw_input_error("{}: not a shell bench state (it needs \"shell\", \"level\", \"solver\" and \"dofs\")", file);
    expect.shell = j.at("shell").get<std::string>();
    expect.level = j.at("level").get<int>();
    expect.solver = j.at("solver").get<std::string>();
    expect.dofs = j.at("dofs").get<Index>();
  } catch (const Json::exception& e) {
    throw_input_error("{}: {}", file, e.what());
  }
  ShellBenchState st;
  st.file = file;
  st.shell = expect.shell;
  st.level = expect.level;
  read_state(file, expect, st.x, st.levels);
  return st;
}

namespace {

/// x and the coarse-level states of a solve at the body's finest level from a coarser solve's state: the solution
/// prolongated level by level, and below it the state's own levels (Rmtr::resume_level_states order).
void start_from_coarser(const bodies::ShellBody& body, const ShellBenchState& st, VecX& x, std::vector<VecX>& levels) {
  const hierarchy::SubdivisionHierarchy& h = body.hierarchy();
  const int finest = body.num_levels() - 1, from = st.level - 1;  // hierarchy levels, 0 the coarsest
  if (from < 0 || from >= finest)
    throw_input_error("--start-from {}: level {} of shell \"{}\" is not coarser than this solve's level {}", st.file,
                      st.level, st.shell, finest + 1);
  const Index expected = 3 * h.subdivision(from).num_cols;
  if (st.x.size() != expected)
    throw_input_error("--start-from {}: {} dofs, level {} of shell \"{}\" has {}", st.file, st.x.size(), st.level,
                      st.shell, expected);
  levels = st.levels;
  if (static_cast<int>(levels.size()) != from) levels.clear();  // not an RMTR state of `from` levels below
  VecX v = st.x;
  for (int l = from; l < finest; ++l) {
    levels.push_back(v);
    VecX fine;
    h.subdivision(l).apply(v, fine);
    v.swap(fine);
  }
  x = std::move(v);
  if (levels.size() != static_cast<size_t>(finest)) levels.clear();
}
}  // namespace

sim::Scene shell_bench_scene(const sim::Scene& base, int level, const SolverSpec& spec, const ShellBenchOptions& opt) {
  sim::Scene scene = base;
  scene.cloths.clear();
  if (level > 0)
    for (auto& sh : scene.shells) sh.level = level;
  if (opt.time_step > 0.0) {
    scene.frame_time = opt.time_step;
    scene.substeps = 1;
  }
  scene.frames = 1;
  // The Simulator applies the scene's thread count, which would otherwise override the benchmark's.
  if (opt.threads > 0) scene.threads = opt.threads;
  scene.solver.name = spec.config.name;
  scene.solver.params = spec.config.params;
  if (opt.max_iters > 0) scene.solver.stop.max_iters = opt.max_iters;
  if (opt.max_seconds > 0.0) scene.solver.stop.max_seconds = opt.max_seconds;
  scene.solver.stop.interruptible = true;  // stops only where the caller installed mgcloth's signal handler
  return scene;
}

std::vector<ShellBenchRow> run_shell_bench(const std::vector<sim::Scene>& scenes, const ShellBenchOptions& opt,
                                           const ShellBenchProgress& on_row) {
  if (opt.threads > 0) set_num_threads(opt.threads);
  std::vector<ShellBenchState> starts;
  for (const std::string& f : opt.start_from) {
    starts.push_back(read_shell_bench_state(f));
    bool known = false;
    for (const sim::Scene& sc : scenes)
      for (const auto& sh : sc.shells) known = known || sh.name == starts.back().shell;
    if (!known) throw_input_error("--start-from {}: no scene has a shell named \"{}\"", f, starts.back().shell);
    if (std::none_of(opt.levels.begin(), opt.levels.end(), [&](int l) { return l > starts.back().level; }))
      throw_input_error("--start-from {}: level {} of shell \"{}\" is not coarser than this run's levels ({})", f,
                        starts.back().level, starts.back().shell, fmt::join(opt.levels, ","));
    for (size_t k = 0; k + 1 < starts.size(); ++k)
      if (starts[k].shell == starts.back().shell)
        throw_input_error("--start-from {}: shell \"{}\" already starts from {}", f, starts.back().shell, starts[k].file);
  }
  const auto start_for = [&](const std::string& shell, int level) -> const ShellBenchState* {
    for (const auto& st : starts)
      if (st.shell == shell && st.level < level) return &st;
    return nullptr;
  };
  std::vector<ShellBenchRow> rows;
  for (const sim::Scene& base : scenes) {
    if (base.shells.empty()) throw_input_error("{}: the scene has no shells", base.file);
    for (int level : opt.levels)
      for (const SolverSpec& spec : opt.solvers) {
        sim::Scene scene = shell_bench_scene(base, level, spec, opt);
        // A resumed solve goes on from its iterate: nested iteration would restart from the coarse problems.
        if (opt.resume && !opt.states_dir.empty()) {
          bool any = false;
          for (size_t s = 0; s < scene.shells.size(); ++s)
            if (fs::exists(state_path(opt, scene.shells[s].name, level, spec.label))) any = true;
          if (any && scene.solver.name.starts_with("rmtr")) scene.solver.params["initial"] = "fine";
        }
        // A solve that starts from a coarser solution skips nested iteration: projections of the prolongated
        // solution would restart the coarse levels from what it already solved, with coarse energies of 1e40 J
        // where the fine state is wrinkled. The scene's solver settings serve all its shells, so either all of
        // them start from coarser solves or none.
        size_t with_start = 0;
        for (const auto& sh : scene.shells) with_start += start_for(sh.name, level) ? 1 : 0;
        if (with_start > 0 && scene.solver.name.starts_with("rmtr")) {
          if (with_start < scene.shells.size())
            throw_input_error("--start-from: {} has {} shells and starts for {} of them at level {}; RMTR without "
                              "nested iteration needs a start for each", base.file, scene.shells.size(), with_start,
                              level);
          scene.solver.params["initial"] = "fine";
        }
        scene.solve_jointly = false;  // each shell is a row of its own
        sim::Simulator sim(scene);
        for (size_t s = 0; s < sim.shells().size(); ++s) {
          const size_t group = sim.group_of(sim.scene().cloths.size() + s);
          ShellBenchRow row;
          row.scene = base.file;
          row.shell = sim.shells()[s]->name();
          row.solver = spec.label;
          row.level = level;
          row.dofs = static_cast<Index>(sim.shells()[s]->x().size());
          row.time_step = scene.step_size();
          const fs::path state = opt.states_dir.empty() ? fs::path() : state_path(opt, row.shell, level, spec.label);
          std::optional<ShellBenchRow> before;
          VecX resumed;
          std::vector<VecX> resumed_levels;
          int started_from = 0;
          if (opt.resume && !state.empty() && fs::exists(state)) before = read_state(state, row, resumed, resumed_levels);
          if (before && before->converged) {
            logger().info("{} level {} {}: converged in an earlier run ({})", row.shell, level, spec.label, state.string());
            rows.push_back(*before);
            if (on_row) on_row(rows);
            continue;
          }
          VecX x;
          solvers::Problem problem = sim.prepare_problem(group, x);
          if (before) {
            x = resumed;
            sim.solver(group).resume_level_states(resumed_levels);
            logger().info("{} level {} {}: resumed after {} iterations ({}{})", row.shell, level, spec.label,
                          before->iterations, state.string(),
                          resumed_levels.empty() ? "" : fmt::format(", with {} coarse level states", resumed_levels.size()));
          } else if (const ShellBenchState* st = start_for(row.shell, level)) {
            std::vector<VecX> start_levels;
            start_from_coarser(*sim.shells()[s], *st, x, start_levels);
            sim.solver(group).resume_level_states(start_levels);
            started_from = st->level;
            logger().info("{} level {} {}: starts from the level-{} solution of {} ({} control points){}", row.shell,
                          level, spec.label, st->level, st->file, st->x.size() / 3,
                          start_levels.empty() ? "" : fmt::format(", with {} coarse level states", start_levels.size()));
          }
          Timer timer;
          solvers::Stop stop = scene.solver.stop;
          if (!state.empty() && opt.checkpoint_seconds > 0.0) {
            // A state every checkpoint_seconds, so that a run killed without warning (SIGKILL, a lost machine)
            // resumes from its last one; it is replaced by the solve's final state.
            VecX g0;
            problem.objective->gradient(x, g0);
            const double g0_norm = before ? before->initial_grad_norm : g0.norm();
            stop.checkpoint_seconds = opt.checkpoint_seconds;
            stop.checkpoint = [&, g0_norm](const VecX& xc, int iterations, double energy, double grad_norm) {
              ShellBenchRow c = row;
              c.iterations = iterations + (before ? before->iterations : 0);
              c.converged = false;
              c.status = "checkpoint";
              c.energy = energy;
              c.grad_norm = grad_norm;
              c.initial_grad_norm = g0_norm;
              c.wall_s = timer.seconds() + (before ? before->wall_s : 0.0);
              if (before)
                for (const auto& [k, v] : before->counters)
                  if (spent_by_first_part(k)) c.counters.emplace_back(k, v);
              if (started_from > 0) c.counters.emplace_back("started_from_level", started_from);
              write_state(state, c, xc, sim.solver(group).level_states());
              logger().debug("{} level {} {}: checkpoint after {} iterations ({})", row.shell, level, spec.label,
                             c.iterations, state.string());
            };
          }
          try {
            const auto rep = sim.solver(group).minimize(problem, x, stop, nullptr);
            row.iterations = rep.iterations;
            row.converged = rep.converged;
            row.status = rep.status;
            row.energy = rep.energy;
            row.grad_norm = rep.grad_norm;
            row.initial_grad_norm = rep.initial_grad_norm;
            row.counters = rep.counters;
          } catch (const SolveError& e) {
            row.status = "diverged";
            logger().info("{} level {} {}: {}", row.shell, level, spec.label, e.what());
          }
          row.wall_s = timer.seconds();
          if (before) {
            row.iterations += before->iterations;
            row.wall_s += before->wall_s;
            row.initial_grad_norm = before->initial_grad_norm;  // ‖g₀‖ of the step's start, for rel_grad
            // The nested cycles were spent by the first part only; its iterations include every part before.
            for (const auto& [k, v] : before->counters)
              if (spent_by_first_part(k)) row.counters.emplace_back(k, v);
            row.counters.emplace_back("resumed_iterations", before->iterations);
          }
          if (started_from > 0) row.counters.emplace_back("started_from_level", started_from);  // resumed: kept above
          if (!state.empty() && row.status != "diverged") write_state(state, row, x, sim.solver(group).level_states());
          logger().info("{} level {} ({} dofs) {}: {} iterations, {} in {:.2f} s", row.shell, level, row.dofs,
                        spec.label, row.iterations, row.status, row.wall_s);
          rows.push_back(std::move(row));
          if (on_row) on_row(rows);
          if (interrupted()) return rows;  // the interrupted solve's state is written; the rest is not started
        }
      }
  }
  return rows;
}

std::string shell_bench_csv(const std::vector<ShellBenchRow>& rows) {
  std::string out =
      "scene,shell,level,dofs,time_step,solver,iterations,converged,status,energy,grad_norm,rel_grad,wall_s,accepted,"
      "rejected,hessian_assemblies,qp_calls,cg_iterations,work_assembly,work_qp\n";
  for (const auto& r : rows) {
    // Multilevel rows count the finest level in the per-level columns; the work columns (eq. 7.3) cover all.
    const auto fine = [&](const std::string& name) {
      return has_counter(r, name) ? counter(r, name) : counter(r, "level0_" + name);
    };
    const double work_assembly = has_counter(r, "work_assembly") ? counter(r, "work_assembly") : fine("hessian_assemblies");
    const double work_qp = has_counter(r, "work_qp") ? counter(r, "work_qp") : fine("qp_calls");
    out += fmt::format("{},{},{},{},{:g},{},{},{},{},{:.17g},{:.6e},{:.6e},{:.4f},{:g},{:g},{:g},{:g},{:g},{:g},{:g}\n",
                       r.scene, r.shell, r.level, r.dofs, r.time_step, r.solver, r.iterations, r.converged ? 1 : 0,
                       r.status, r.energy, r.grad_norm, r.initial_grad_norm > 0 ? r.grad_norm / r.initial_grad_norm : 0.0,
                       r.wall_s, counter(r, "accepted"), counter(r, "rejected"), fine("hessian_assemblies"),
                       fine("qp_calls"), fine("cg_iterations"), work_assembly, work_qp);
  }
  return out;
}

Json shell_bench_json(const std::vector<ShellBenchRow>& rows, const ShellBenchOptions& opt) {
  Json j;
  j["levels"] = opt.levels;
  j["threads"] = opt.threads > 0 ? opt.threads : num_threads();
  if (!opt.start_from.empty()) j["start_from"] = opt.start_from;
  j["results"] = Json::array();
  for (const auto& r : rows) {
    Json c = Json::object();
    for (const auto& [k, v] : r.counters) c[k] = v;
    j["results"].push_back({{"scene", r.scene}, {"shell", r.shell}, {"level", r.level}, {"dofs", r.dofs},
                            {"time_step", r.time_step}, {"solver", r.solver}, {"iterations", r.iterations},
                            {"converged", r.converged}, {"status", r.status}, {"energy", r.energy},
                            {"grad_norm", r.grad_norm}, {"initial_grad_norm", r.initial_grad_norm},
                            {"wall_s", r.wall_s}, {"counters", c}});
  }
  return j;
}

std::vector<ProjectionBenchRow> run_projection_bench(const sim::Scene& scene) {
  if (scene.shells.empty()) throw_input_error("{}: the scene has no shells", scene.file);
  const bodies::ShellBody body(scene.shells.front(), scene.gravity, scene.file);
  const hierarchy::SubdivisionHierarchy& h = body.hierarchy();
  std::vector<ProjectionBenchRow> rows;
  std::mt19937 rng(11);
  std::normal_distribution<double> normal;
  for (int l = 0; l + 1 < h.num_levels(); ++l) {
    const linalg::StencilTable& S = h.subdivision(l);
    std::vector<VecX> q(3);
    for (auto& v : q) {
      v.resize(3 * S.num_cols);
      for (Index i = 0; i < v.size(); ++i) v[i] = normal(rng);
    }
    const auto measure = [&](ProjectionBenchRow row, const auto& apply) {
      row.fine_level = l + 2;
      row.fine_dofs = 3 * S.num_rows;
      row.coarse_dofs = 3 * S.num_cols;
      VecX fine, back;
      for (const VecX& v : q) {
        S.apply(v, fine);
        apply(fine, back);
        row.exactness = std::max(row.exactness, (back - v).norm() / v.norm());
      }
      const int reps = std::max(3, static_cast<int>(2'000'000 / std::max<Index>(1, S.num_rows)));
      Timer t;
      for (int k = 0; k < reps; ++k) apply(fine, back);
      row.apply_ms = t.ms() / reps;
      rows.push_back(row);
    };
    {
      ProjectionBenchRow row;
      row.operator_name = "reverse_subdivision";
      Timer t;
      try {
        const linalg::StencilTable Q = hierarchy::reverse_subdivision(h.mesh(l), h.step(l));
        row.build_ms = t.ms();
        row.memory_bytes = Q.memory_bytes();
        row.entries = Q.num_entries();
        measure(row, [&](const VecX& f, VecX& c) { Q.apply(f, c); });
      } catch (const Error& e) {
        logger().info("level {}: no reverse subdivision: {}", l + 2, e.what());
      }
    }
    {
      ProjectionBenchRow row;
      row.operator_name = "least_squares";
      Timer t;
      const hierarchy::LeastSquaresProjection P(S);
      row.build_ms = t.ms();
      row.memory_bytes = P.memory_bytes();
      row.entries = P.factor_nonzeros();
      measure(row, [&](const VecX& f, VecX& c) { P.apply(f, c); });
    }
  }
  return rows;
}

std::string projection_bench_csv(const std::vector<ProjectionBenchRow>& rows) {
  std::string out = "operator,fine_level,fine_dofs,coarse_dofs,build_ms,apply_ms,memory_bytes,entries,exactness\n";
  for (const auto& r : rows)
    out += fmt::format("{},{},{},{},{:.4f},{:.5f},{},{},{:.3e}\n", r.operator_name, r.fine_level, r.fine_dofs,
                       r.coarse_dofs, r.build_ms, r.apply_ms, r.memory_bytes, r.entries, r.exactness);
  return out;
}

}  // namespace mgcloth::studies
