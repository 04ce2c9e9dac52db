#include <mgcloth/core/log.hpp>
#include <mgcloth/core/out_of_memory.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <algorithm>
#include <memory>

namespace mgcloth::sim {

SteerableMotion::SteerableMotion(std::shared_ptr<const geometry::RigidMotion> scene_motion)
    : m_scene(std::move(scene_motion)) {}

geometry::KeyframedMotion SteerableMotion::segment(double t) const {
  // The first key at or after t.
  const auto k1 = std::lower_bound(m_keys.begin(), m_keys.end(), t,
                                   [](const geometry::Keyframe& key, double time) { return key.time < time; });
  return geometry::KeyframedMotion({*(k1 - 1), *k1});
}

geometry::Pose SteerableMotion::pose(double t) const {
  if (m_keys.empty() || !(t > m_keys.front().time)) return m_scene ? m_scene->pose(t) : geometry::Pose{};
  if (t >= m_keys.back().time) return m_keys.back().pose;
  return segment(t).pose(t);
}

void SteerableMotion::velocity(double t, Vec3& linear, Vec3& angular) const {
  linear.setZero();
  angular.setZero();
  if (m_keys.empty() || !(t > m_keys.front().time)) {
    if (m_scene) m_scene->velocity(t, linear, angular);
    return;
  }
  if (t > m_keys.back().time) return;
  // KeyframedMotion's velocity is right-continuous (zero at its last key), but the step that ends at a key moved
  // along the segment before it; the velocity is constant on a segment, so take it at the segment's start.
  const auto k1 = std::lower_bound(m_keys.begin(), m_keys.end(), t,
                                   [](const geometry::Keyframe& key, double time) { return key.time < time; });
  segment(t).velocity((k1 - 1)->time, linear, angular);
}

void SteerableMotion::steer(double t0, double t1, const geometry::Pose& target) {
  if (!(t1 > t0)) throw_error("steered obstacle: the pose must be reached after t0 = {} (got t1 = {})", t0, t1);
  const geometry::Pose now = pose(t0);
  (void)geometry::KeyframedMotion({{t0, now}, {t1, target}});  // a zero or non-finite rotation fails here, not in a step
  geometry::Pose unit = target;
  unit.rotation.normalize();
  while (!m_keys.empty() && m_keys.back().time >= t0) m_keys.pop_back();
  m_keys.push_back({t0, now});
  m_keys.push_back({t1, unit});
}

Simulator::Simulator(Scene scene) : Simulator(std::move(scene), {}) {}

Simulator::Simulator(Scene scene, const std::vector<std::shared_ptr<const mesh::TriMesh>>& meshes)
    : m_scene(std::move(scene)) {
  if (m_scene.threads > 0) set_num_threads(m_scene.threads);
  if (meshes.size() > m_scene.cloths.size())
    throw InputError(fmt::format("{}: {} meshes given for {} cloths", m_scene.file, meshes.size(), m_scene.cloths.size()));
  for (size_t i = 0; i < m_scene.obstacles.size(); ++i) {
    try {
      m_obstacles.push_back(m_scene.obstacles[i].build());
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: obstacles[{}] (\"{}\"): {}", m_scene.file, i, m_scene.obstacles[i].name, e.what()));
    }
    m_steering.push_back(std::make_shared<SteerableMotion>(m_obstacles.back().motion));
    m_obstacles.back().motion = m_steering.back();
  }
  for (size_t i = 0; i < m_scene.cloths.size(); ++i) {
    const auto& c = m_scene.cloths[i];
    // One solver per cloth: solvers keep per-pattern state (the CHOLMOD analysis).
    m_solvers.push_back(solvers::make_solver(m_scene.solver, m_scene.file, "solver.params"));
    try {
      building([&] { return fmt::format("cloth \"{}\" ({}: cloths[{}])", c.name, m_scene.file, i); }, [&] {
        m_cloths.push_back(std::make_unique<ClothBody>(c, m_obstacles, m_scene.contact, m_scene.gravity,
                                                       m_scene.energy_form == physics::EnergyForm::Projective,
                                                       i < meshes.size() ? meshes[i].get() : nullptr));
      });
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: cloths[{}] (\"{}\"): {}", m_scene.file, i, c.name, e.what()));
    }
    check_start_outside_obstacles(i);
  }
  for (size_t i = 0; i < m_scene.shells.size(); ++i) {
    const auto& spec = m_scene.shells[i];
    m_shell_solvers.push_back(solvers::make_solver(m_scene.solver, m_scene.file, "solver.params"));
    try {
      building([&] { return fmt::format("shell \"{}\" ({}: shells[{}], level {})", spec.name, m_scene.file, i, spec.level); },
               [&] { m_shells.push_back(std::make_unique<ShellBody>(spec, m_scene.gravity, m_scene.file)); });
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: shells[{}] (\"{}\"): {}", m_scene.file, i, spec.name, e.what()));
    }
  }
}

void Simulator::check_start_outside_obstacles(size_t c) const {
  // A cloth that starts deep inside an obstacle cannot be simulated: projecting its vertices out piles them onto the
  // surface (degenerate triangles, non-finite bending), and the first solve fails far from the cause. Within the
  // contact layer the projection is a small push, so only depths beyond the layer's thickness are refused.
  const ClothBody& body = *m_cloths[c];
  const VecX& x = body.x();
  const double limit = m_scene.contact.thickness;
  for (size_t o = 0; o < m_obstacles.size(); ++o) {
    const hd::ObstacleData od = m_obstacles[o].data(0.0);
    Index count = 0, worst = -1;
    double worst_phi = 0.0;
    for (Index v = 0; v < x.size() / 3; ++v) {
      const double phi = hd::sdf_distance(od.kind, od.param, hd::to_local(od, hd::load3(x.data() + 3 * v)));
      if (!(phi < -limit)) continue;
      ++count;
      if (phi < worst_phi) worst_phi = phi, worst = v;
    }
    if (count > 0)
      throw InputError(fmt::format("{}: cloths[{}] (\"{}\") starts inside obstacle \"{}\": {} vertices lie deeper than the "
                                   "contact thickness ({} m), the deepest vertex {} at ({:.4g}, {:.4g}, {:.4g}), {:.3g} m "
                                   "below the surface; move the cloth (transform) or the obstacle",
                                   m_scene.file, c, body.name(), m_obstacles[o].name, count, limit, worst,
                                   x[3 * worst], x[3 * worst + 1], x[3 * worst + 2], -worst_phi));
  }
}

solvers::Problem Simulator::prepare_shell_problem(size_t s, VecX& x0, double* load_factor) {
  const double lambda = std::min(1.0, static_cast<double>(m_step + 1) / static_cast<double>(std::max(1L, m_scene.total_steps())));
  ShellBody& body = *m_shells[s];
  x0 = body.prepare_step(time() + m_scene.step_size(), m_scene.step_size(), lambda);
  if (load_factor) *load_factor = body.is_static() ? lambda : 1.0;
  solvers::Problem problem;
  problem.objective = &body.objective();
  const solvers::NonlinearSolver& solver = *m_shell_solvers[s];
  if (solver.needs_hierarchy() || solver.needs_level_objectives())
    problem.hierarchy = body.solver_hierarchy(solver.needs_level_objectives());
  return problem;
}

solvers::Problem Simulator::prepare_problem(size_t c, VecX& x0) {
  ClothBody& body = *m_cloths[c];
  x0 = body.prepare_step(time(), m_scene.step_size());
  solvers::Problem problem;
  problem.objective = &body.objective();
  const solvers::NonlinearSolver& solver = *m_solvers[c];
  if (solver.needs_hierarchy() || solver.needs_level_objectives())
    problem.hierarchy = body.solver_hierarchy(m_scene.hierarchy, solver.needs_level_objectives());
  if (body.contact()) {
    const auto* contact = body.contact();
    problem.project = [contact](VecX& y) {
      return physics::project_out_of_obstacles(y, contact->obstacle_data());
    };
  }
  return problem;
}

std::vector<StepStats> Simulator::step() {
  const double h = m_scene.step_size();
  const double t = time();
  std::vector<StepStats> out;
  // The fields every body's row shares.
  const auto finish = [&](StepStats& s, const std::string& name, const solvers::NonlinearSolver& solver, const Timer& timer) {
    s.frame = m_frame + 1;
    s.step = m_step + 1;
    s.sim_time = t + h;
    s.cloth = name;
    s.solver = solver.name();
    s.wall_ms = timer.ms();
    out.push_back(std::move(s));
  };
  for (size_t c = 0; c < m_cloths.size(); ++c) {
    Timer timer;
    ClothBody& body = *m_cloths[c];
    VecX x;
    solvers::Problem problem = prepare_problem(c, x);
    StepStats s;
    try {
      s.report = building(
          [&] {
            return fmt::format("the solve of step {} of cloth \"{}\" ({} vertices, solver {}: its matrices and levels)",
                               m_step + 1, body.name(), body.mesh().num_vertices(), m_solvers[c]->name());
          },
          [&] { return m_solvers[c]->minimize(problem, x, m_scene.solver.stop, m_record_trace ? &s.trace : nullptr); });
    } catch (const SolveError& e) {
      throw SolveError(fmt::format("{}: cloth \"{}\", frame {}, step {} (t = {:.4f} s): {}", m_scene.file, body.name(),
                                   m_frame + 1, m_step + 1, t + h, e.what()));
    }
    const VecX before = x;
    VecX v;
    if (m_solvers[c]->finish_step(body.x(), h, x, v))
      body.accept_step(x, v);
    else
      body.finish_step(x, h);
    s.projected = static_cast<Index>(((x - before).array() != 0.0).reshaped(3, x.size() / 3).colwise().any().count());
    finish(s, body.name(), *m_solvers[c], timer);
  }
  for (size_t i = 0; i < m_shells.size(); ++i) {
    Timer timer;
    ShellBody& body = *m_shells[i];
    StepStats s;
    VecX x;
    solvers::Problem problem = prepare_shell_problem(i, x, &s.load_factor);
    try {
      s.report = building(
          [&] {
            return fmt::format("the solve of step {} of shell \"{}\" ({} control points, solver {}: its matrices and "
                               "levels)", m_step + 1, body.name(), body.x().size() / 3, m_shell_solvers[i]->name());
          },
          [&] { return m_shell_solvers[i]->minimize(problem, x, m_scene.solver.stop, m_record_trace ? &s.trace : nullptr); });
    } catch (const SolveError& e) {
      throw SolveError(fmt::format("{}: shell \"{}\", frame {}, step {} (t = {:.4f} s): {}", m_scene.file, body.name(),
                                   m_frame + 1, m_step + 1, t + h, e.what()));
    }
    body.finish_step(x, h);
    s.probes = body.probes();
    finish(s, body.name(), *m_shell_solvers[i], timer);
  }
  ++m_step;
  return out;
}

std::vector<StepStats> Simulator::advance_frame() {
  std::vector<StepStats> out;
  for (int s = 0; s < m_scene.substeps; ++s) {
    auto st = step();
    out.insert(out.end(), st.begin(), st.end());
  }
  ++m_frame;
  return out;
}

void Simulator::set_pin_targets(size_t c, const std::vector<Vec3>& targets) {
  if (c >= m_cloths.size()) throw_input_error("cloth {} out of range (the scene has {} cloths)", c, m_cloths.size());
  m_cloths[c]->set_pin_targets(targets, time(), time() + m_scene.frame_time);
}

void Simulator::set_obstacle_pose(size_t o, const geometry::Pose& pose) {
  if (o >= m_steering.size()) throw_input_error("obstacle {} out of range (the scene has {} obstacles)", o, m_steering.size());
  if (!pose.translation.allFinite())
    throw_input_error("obstacle \"{}\": position must be finite (got [{}, {}, {}])", m_obstacles[o].name,
                      pose.translation.x(), pose.translation.y(), pose.translation.z());
  m_steering[o]->steer(time(), time() + m_scene.frame_time, pose);
}

void Simulator::set_state(int frame, long step, const std::vector<VecX>& x, const std::vector<VecX>& v) {
  if (x.size() != m_cloths.size() + m_shells.size() || v.size() != x.size())
    throw InputError(fmt::format("the state has {} bodies, the scene has {} cloths and {} shells", x.size(),
                                 m_cloths.size(), m_shells.size()));
  for (size_t s = 0; s < m_shells.size(); ++s) {
    const size_t k = m_cloths.size() + s;
    if (x[k].size() != m_shells[s]->x().size() || v[k].size() != m_shells[s]->v().size())
      throw InputError(fmt::format("shell \"{}\" has {} dofs, the scene's shell has {}", m_shells[s]->name(),
                                   x[k].size(), m_shells[s]->x().size()));
    m_shells[s]->x() = x[k];
    m_shells[s]->v() = v[k];
  }
  for (size_t c = 0; c < m_cloths.size(); ++c) {
    if (x[c].size() != m_cloths[c]->x().size() || v[c].size() != m_cloths[c]->v().size())
      throw InputError(fmt::format("cloth \"{}\" has {} dofs, the scene's mesh has {}", m_cloths[c]->name(),
                                   x[c].size(), m_cloths[c]->x().size()));
    m_cloths[c]->x() = x[c];
    m_cloths[c]->v() = v[c];
  }
  m_frame = frame;
  m_step = step;
}

std::string Simulator::solver_state(size_t body) const {
  const size_t cloths = m_cloths.size();
  if (body >= cloths + m_shells.size())
    throw_error("solver state of body {}, the scene has {} cloths and {} shells", body, cloths, m_shells.size());
  return (body < cloths ? m_solvers[body] : m_shell_solvers[body - cloths])->carried_state();
}

void Simulator::set_solver_state(size_t body, std::string_view state) {
  const size_t cloths = m_cloths.size();
  if (body >= cloths + m_shells.size())
    throw InputError(fmt::format("solver state for body {}, the scene has {} cloths and {} shells", body, cloths,
                                 m_shells.size()));
  try {
    (body < cloths ? m_solvers[body] : m_shell_solvers[body - cloths])->restore_carried_state(state);
  } catch (const InputError& e) {
    throw InputError(fmt::format("{} \"{}\": {}", body < cloths ? "cloth" : "shell",
                                 body < cloths ? m_cloths[body]->name() : m_shells[body - cloths]->name(), e.what()));
  }
}

}  // namespace mgcloth::sim
