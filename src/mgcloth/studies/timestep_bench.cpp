#include <mgcloth/core/log.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/studies/shell_bench.hpp>
#include <mgcloth/sim/simulator.hpp>
#include <mgcloth/studies/timestep_bench.hpp>

#include <algorithm>
#include <cmath>
#include <memory>

namespace mgcloth::studies {

namespace {

void check_options(const TimestepBenchOptions& opt) {
  if (opt.solvers.empty()) throw_input_error("time-step study: no solvers given");
  if (!(opt.window >= 0.0) || !std::isfinite(opt.window))
    throw_input_error("window: must be a non-negative number of seconds (got {})", opt.window);
  if (opt.max_iters < 0) throw_input_error("max_iters: must be non-negative (got {})", opt.max_iters);
  if (!(opt.max_seconds >= 0.0)) throw_input_error("max_seconds: must be non-negative (got {})", opt.max_seconds);
  if (!(opt.max_try_seconds >= 0.0))
    throw_input_error("max_try_seconds: must be non-negative (got {})", opt.max_try_seconds);
  if (!(opt.stall_rel_grad >= 0.0 && opt.stall_rel_grad < 1.0))
    throw_input_error("stall_rel_grad: must be in [0, 1) (got {})", opt.stall_rel_grad);
  if (!(opt.stall_abs_grad >= 0.0) || !std::isfinite(opt.stall_abs_grad))
    throw_input_error("stall_abs_grad: must be non-negative (got {})", opt.stall_abs_grad);
  if (opt.level < 0 || opt.level > 9) throw_input_error("level: {} is out of range [0, 9]", opt.level);
  timestep_ladder(opt);
}

double window_of(const sim::Scene& scene, const TimestepBenchOptions& opt) {
  if (opt.window > 0.0) return opt.window;
  return std::min(scene.frames * scene.frame_time, TimestepBenchOptions::kDefaultWindowCap);
}

int steps_for(double window, double dt) {
  // The tolerance keeps window / dt = 64 exactly from becoming 65 steps through round-off.
  return std::max(1, static_cast<int>(std::ceil(window / dt * (1.0 - 1e-12))));
}

TimestepBenchRow try_time_step(const sim::Scene& base, const SolverSpec& spec, double dt, const TimestepBenchOptions& opt) {
  ShellBenchOptions caps;
  caps.time_step = dt;
  caps.max_iters = opt.max_iters;
  caps.max_seconds = opt.max_seconds;
  caps.threads = opt.threads;
  sim::Scene scene = shell_bench_scene(base, opt.level, spec, caps);
  TimestepBenchRow row;
  row.scene = base.file;
  row.solver = spec.label;
  row.time_step = dt;
  row.window = window_of(base, opt);
  row.steps = steps_for(row.window, dt);
  scene.frames = row.steps;
  row.level = scene.shells.front().level;
  // A solver that cannot run on this problem (one that needs a hierarchy the scene does not give) is recorded,
  // and the study goes on with the other solvers.
  const auto cannot_run = [&](int step, const Error& e) {
    row.failed_step = step;
    row.status = "error";
    row.message = e.what();
    logger().warn("{} dt = {:g}: {}", row.solver, dt, e.what());
  };
  std::unique_ptr<sim::Simulator> owned;
  try {
    owned = std::make_unique<sim::Simulator>(scene);
  } catch (const InputError&) {
    throw;
  } catch (const Error& e) {
    cannot_run(1, e);
    return row;
  }
  sim::Simulator& sim = *owned;
  for (const auto& sh : sim.shells()) {
    row.shells += (row.shells.empty() ? "" : "+") + sh->name();
    row.dofs += static_cast<Index>(sh->x().size());
  }
  row.status = "converged";
  Timer timer;
  for (int k = 1; k <= row.steps && row.failed_step == 0; ++k) {
    if (k > 1 && opt.max_try_seconds > 0.0 && timer.seconds() >= opt.max_try_seconds) {
      row.failed_step = k;
      row.status = "try_time_limit";
      break;
    }
    ++row.steps_run;
    std::vector<sim::StepStats> stats;
    try {
      stats = sim.step();
    } catch (const SolveError& e) {
      // Criterion (7.1) is never met by a solve that throws: a non-finite energy or a failed line search.
      row.failed_step = k;
      row.status = "diverged";
      row.message = e.what();
      break;
    } catch (const InputError&) {
      throw;
    } catch (const Error& e) {
      cannot_run(k, e);
      break;
    }
    int step_iterations = 0;
    for (const sim::StepStats& s : stats) {
      const solvers::SolveReport& r = s.report;
      step_iterations += r.iterations;
      if (row.failed_step > 0) continue;
      row.grad_norm = r.grad_norm;
      row.initial_grad_norm = r.initial_grad_norm;
      if (!meets_criterion(r, opt.stall_rel_grad, opt.stall_abs_grad)) {
        row.failed_step = k;
        row.status = r.status;
      } else if (!r.converged) {
        ++row.stalled_steps;
      }
    }
    row.iterations += step_iterations;
    row.max_step_iterations = std::max(row.max_step_iterations, step_iterations);
  }
  row.passed = row.failed_step == 0;
  row.wall_s = timer.seconds();
  logger().info("{} level {} ({} dofs) {} dt = {:g}: {} after {}/{} steps, {} iterations in {:.2f} s", row.shells,
                row.level, row.dofs, row.solver, dt, row.passed ? "passed" : row.status, row.steps_run, row.steps,
                row.iterations, row.wall_s);
  return row;
}

}  // namespace

bool meets_criterion(const solvers::SolveReport& r, double stall_rel_grad, double stall_abs_grad) {
  return r.converged ||
         (r.status == "stalled" && r.grad_norm <= std::max(stall_rel_grad * r.initial_grad_norm, stall_abs_grad));
}

std::vector<double> timestep_ladder(const TimestepBenchOptions& opt) {
  if (!(opt.max_dt > 0.0) || !std::isfinite(opt.max_dt))
    throw_input_error("max_dt: must be a positive number of seconds (got {})", opt.max_dt);
  if (!(opt.min_dt > 0.0) || !std::isfinite(opt.min_dt))
    throw_input_error("min_dt: must be a positive number of seconds (got {})", opt.min_dt);
  if (opt.min_dt > opt.max_dt) throw_input_error("min_dt: {} is larger than max_dt = {}", opt.min_dt, opt.max_dt);
  std::vector<double> dts;
  // Halving is exact in binary, so 1/64 is reached exactly; the tolerance only guards a min_dt typed in decimal.
  for (double dt = opt.max_dt; dt >= opt.min_dt * (1.0 - 1e-12); dt *= 0.5) dts.push_back(dt);
  return dts;
}

std::vector<TimestepBenchRow> run_timestep_bench(const std::vector<sim::Scene>& scenes, const TimestepBenchOptions& opt,
                                                 const TimestepBenchProgress& on_row,
                                                 const std::vector<TimestepBenchRow>& previous) {
  check_options(opt);
  for (const sim::Scene& s : scenes)
    if (s.shells.empty()) throw_input_error("{}: the scene has no shells", s.file);
  if (opt.threads > 0) set_num_threads(opt.threads);
  const std::vector<double> dts = timestep_ladder(opt);
  std::vector<TimestepBenchRow> rows;
  // A try that ran longer than the try cap allows would have ended differently under it.
  const auto earlier = [&](const sim::Scene& base, const SolverSpec& spec, double dt) -> const TimestepBenchRow* {
    for (const TimestepBenchRow& r : previous)
      if (r.scene == base.file && r.solver == spec.label && r.time_step == dt &&
          r.level == (opt.level > 0 ? opt.level : base.shells.front().level) && r.window == window_of(base, opt) &&
          (opt.max_try_seconds <= 0.0 || r.wall_s < opt.max_try_seconds))
        return &r;
    return nullptr;
  };
  for (const sim::Scene& base : scenes)
    for (const SolverSpec& spec : opt.solvers)
      for (double dt : dts) {
        if (const TimestepBenchRow* r = earlier(base, spec, dt)) {
          logger().info("{} {} dt = {:g}: taken from the earlier run ({})", r->shells, r->solver, dt,
                        r->passed ? "passed" : r->status);
          rows.push_back(*r);
        } else {
          rows.push_back(try_time_step(base, spec, dt, opt));
        }
        if (on_row) on_row(rows);
        // A smaller step does not make a solver that cannot run on the problem able to.
        if (rows.back().passed || rows.back().status == "error") break;
      }
  return rows;
}

std::vector<TimestepBenchSummary> timestep_bench_summary(const std::vector<TimestepBenchRow>& rows) {
  std::vector<TimestepBenchSummary> out;
  for (const TimestepBenchRow& r : rows) {
    auto it = std::find_if(out.begin(), out.end(),
                           [&](const TimestepBenchSummary& s) { return s.scene == r.scene && s.solver == r.solver; });
    if (it == out.end()) {
      out.push_back({r.scene, r.shells, r.solver, r.dofs});
      it = out.end() - 1;
    }
    ++it->tries;
    it->total_wall_s += r.wall_s;
    if (r.passed && r.time_step > it->largest_dt) {
      it->largest_dt = r.time_step;
      it->iterations = r.iterations;
      it->wall_s = r.wall_s;
    }
  }
  return out;
}

std::string timestep_bench_csv(const std::vector<TimestepBenchRow>& rows) {
  std::string out =
      "scene,shells,level,dofs,solver,time_step,window,steps,steps_run,passed,failed_step,status,grad_norm,rel_grad,"
      "stalled_steps,iterations,max_step_iterations,wall_s\n";
  for (const auto& r : rows)
    out += fmt::format("{},{},{},{},{},{:g},{:g},{},{},{},{},{},{:.6e},{:.6e},{},{},{},{:.4f}\n", r.scene, r.shells,
                       r.level, r.dofs, r.solver, r.time_step, r.window, r.steps, r.steps_run, r.passed ? 1 : 0,
                       r.failed_step, r.status, r.grad_norm,
                       r.initial_grad_norm > 0 ? r.grad_norm / r.initial_grad_norm : 0.0, r.stalled_steps,
                       r.iterations, r.max_step_iterations, r.wall_s);
  return out;
}

Json timestep_bench_json(const std::vector<TimestepBenchRow>& rows, const TimestepBenchOptions& opt) {
  Json j;
  j["level"] = opt.level;
  j["solvers"] = Json::array();
  for (const auto& s : opt.solvers) j["solvers"].push_back(s.label);
  j["time_steps"] = timestep_ladder(opt);
  j["window"] = opt.window;
  j["max_iters"] = opt.max_iters;
  j["max_seconds"] = opt.max_seconds;
  j["max_try_seconds"] = opt.max_try_seconds;
  j["stall_rel_grad"] = opt.stall_rel_grad;
  j["stall_abs_grad"] = opt.stall_abs_grad;
  j["threads"] = opt.threads > 0 ? opt.threads : num_threads();
  j["results"] = Json::array();
  for (const auto& r : rows)
    j["results"].push_back({{"scene", r.scene}, {"shells", r.shells}, {"level", r.level}, {"dofs", r.dofs},
                            {"solver", r.solver}, {"time_step", r.time_step}, {"window", r.window},
                            {"steps", r.steps}, {"steps_run", r.steps_run}, {"passed", r.passed},
                            {"failed_step", r.failed_step}, {"status", r.status}, {"message", r.message},
                            {"grad_norm", r.grad_norm}, {"initial_grad_norm", r.initial_grad_norm},
                            {"stalled_steps", r.stalled_steps}, {"iterations", r.iterations},
                            {"max_step_iterations", r.max_step_iterations}, {"wall_s", r.wall_s}});
  j["summary"] = Json::array();
  for (const auto& s : timestep_bench_summary(rows))
    j["summary"].push_back({{"scene", s.scene}, {"shells", s.shells}, {"dofs", s.dofs}, {"solver", s.solver},
                            {"largest_dt", s.largest_dt}, {"iterations", s.iterations}, {"wall_s", s.wall_s},
                            {"tries", s.tries}, {"total_wall_s", s.total_wall_s}});
  return j;
}

std::vector<TimestepBenchRow> timestep_bench_rows(const Json& json) {
  std::vector<TimestepBenchRow> rows;
  for (const Json& j : json.at("results")) {
    TimestepBenchRow r;
    j.at("scene").get_to(r.scene);
    j.at("shells").get_to(r.shells);
    j.at("solver").get_to(r.solver);
    j.at("level").get_to(r.level);
    j.at("dofs").get_to(r.dofs);
    j.at("time_step").get_to(r.time_step);
    j.at("window").get_to(r.window);
    j.at("steps").get_to(r.steps);
    j.at("steps_run").get_to(r.steps_run);
    j.at("passed").get_to(r.passed);
    j.at("failed_step").get_to(r.failed_step);
    j.at("status").get_to(r.status);
    j.at("message").get_to(r.message);
    j.at("grad_norm").get_to(r.grad_norm);
    j.at("initial_grad_norm").get_to(r.initial_grad_norm);
    j.at("stalled_steps").get_to(r.stalled_steps);
    j.at("iterations").get_to(r.iterations);
    j.at("max_step_iterations").get_to(r.max_step_iterations);
    j.at("wall_s").get_to(r.wall_s);
    rows.push_back(std::move(r));
  }
  return rows;
}

}  // namespace mgcloth::studies
