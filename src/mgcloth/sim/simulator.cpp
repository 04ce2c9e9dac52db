#include <mgcloth/collision/intersections.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/out_of_memory.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
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
  bodies::ClothEnvironment env = cloth_environment(m_scene);
  env.obstacles = m_obstacles;  // with their steerable motions
  for (size_t i = 0; i < m_scene.cloths.size(); ++i) {
    const auto& c = m_scene.cloths[i];
    std::unique_ptr<ClothBody> body;
    try {
      building([&] { return fmt::format("cloth \"{}\" ({}: cloths[{}])", c.name, m_scene.file, i); },
               [&] { body = std::make_unique<ClothBody>(c, env, i < meshes.size() ? meshes[i].get() : nullptr); });
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: cloths[{}] (\"{}\"): {}", m_scene.file, i, c.name, e.what()));
    }
    check_start_outside_obstacles(i, *body);
    m_bodies.push_back(std::move(body));
  }
  for (size_t i = 0; i < m_scene.shells.size(); ++i) {
    const auto& spec = m_scene.shells[i];
    try {
      building([&] { return fmt::format("shell \"{}\" ({}: shells[{}], level {})", spec.name, m_scene.file, i, spec.level); },
               [&] { m_bodies.push_back(std::make_unique<ShellBody>(spec, m_scene.gravity, m_scene.file)); });
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: shells[{}] (\"{}\"): {}", m_scene.file, i, spec.name, e.what()));
    }
  }
  std::vector<Body*> all;
  for (auto& b : m_bodies) all.push_back(b.get());
  if (m_scene.solve_jointly && !all.empty()) {
    m_groups.push_back(std::make_unique<bodies::Assembly>(all));
    m_group_of.assign(all.size(), 0);
  } else {
    for (size_t b = 0; b < all.size(); ++b) {
      m_groups.push_back(std::make_unique<bodies::Assembly>(std::vector<Body*>{all[b]}));
      m_group_of.push_back(b);
    }
  }
  for (size_t g = 0; g < m_groups.size(); ++g)
    m_solvers.push_back(solvers::make_solver(m_scene.solver, m_scene.file, "solver.params"));
  if (m_scene.cloth_contact.enabled) add_cloth_contact();
}

void Simulator::add_cloth_contact() {
  for (auto& group : m_groups) {
    std::vector<double> thickness;
    for (const Body* b : group->bodies()) {
      double t = m_scene.cloth_contact.thickness;
      for (const auto& c : m_scene.cloths)
        if (c.name == b->name() && c.contact_thickness > 0.0) t = c.contact_thickness;
      thickness.push_back(t);
    }
    std::vector<geometry::Obstacle> meshes;
    for (const geometry::Obstacle& o : m_obstacles)
      if (o.mesh) {
        meshes.push_back(o);
        if (!(meshes.back().contact_thickness > 0.0)) meshes.back().contact_thickness = m_scene.cloth_contact.thickness;
      }
    // Cloth on an obstacle mesh slides with the obstacle's coefficient, as on a shape.
    physics::ClothFrictionParams friction = m_scene.cloth_contact.friction;
    for (const geometry::Obstacle& o : meshes)
      for (const Body* b : group->bodies()) friction.pairs.push_back({o.name, b->name(), o.friction});
    group->add_cloth_contact(m_scene.cloth_contact.params, thickness, std::move(meshes), time());
    group->add_cloth_friction(friction);
    const physics::ClothContact* contact = group->cloth_contact();
    if (!contact) continue;
    size_t count = 0;
    const VecX all = contact->with_kinematic(group->x());
    const auto found = collision::find_intersections(all, contact->triangles(), 5, &count,
                                                     contact->cloth_triangles(), &contact->joined_points());
    if (found.empty()) continue;
    std::vector<std::string> named;
    const auto side = [&](Index t) {
      const auto [s, own] = contact->triangle_owner(t);
      const auto& surface = contact->surfaces()[s];
      return fmt::format("{} \"{}\" triangle {}", surface.kinematic ? "obstacle" : "cloth", surface.name, own);
    };
    for (const auto& p : found) named.push_back(fmt::format("{} and {}", side(p.a), side(p.b)));
    throw InputError(fmt::format("{}: the cloths intersect {}at the start, which cloth contact cannot undo: {} triangle "
                                 "pairs intersect ({}{}); move or rotate them apart (the contact layer is {} m)",
                                 m_scene.file, contact->num_kinematic() > 0 ? "each other or an obstacle mesh " : "",
                                 count, fmt::join(named, "; "), count > found.size() ? "; …" : "",
                                 m_scene.cloth_contact.thickness));
  }
}

namespace {
/// Solves of one step after which mesh obstacles still short of their poses are an error (Simulator::step).
constexpr int kObstacleRounds = 50;
/// A group in messages: `cloth "sheet"`, or `bodies "sheet", "skirt"`.
std::string group_label(const bodies::Assembly& g) {
  if (g.bodies().size() == 1) return fmt::format("{} \"{}\"", g.bodies()[0]->kind(), g.bodies()[0]->name());
  std::vector<std::string> names;
  for (const Body* b : g.bodies()) names.push_back(fmt::format("\"{}\"", b->name()));
  return fmt::format("bodies {}", fmt::join(names, ", "));
}
std::string group_size(const bodies::Assembly& g) {
  std::vector<std::string> sizes;
  for (const Body* b : g.bodies()) sizes.push_back(b->size_text());
  return fmt::format("{}", fmt::join(sizes, " + "));
}
/// StepStats::seam_gap of one cloth: a stitch group is every point sewn together (a corner where two seams meet
/// has more than two), so the group's widest pair, not only its stitched pairs, is measured.
double widest_seam_gap(const ClothBody& c) {
  const auto& groups = c.topology().stitch_groups;
  if (groups.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto x = as_columns(c.x());
  double gap = 0.0;
  for (const auto& g : groups)
    for (size_t a = 0; a < g.size(); ++a)
      for (size_t b = a + 1; b < g.size(); ++b) gap = std::max(gap, (x.col(g[a]) - x.col(g[b])).norm());
  return gap;
}
/// The cloth mass of a group (kg), the M of Stop::decrement_tol = M·velocity_rms_tol², and its smallest vertex mass;
/// both 0 when a body of the group is not a cloth (a shell's unknowns carry no inertia term, so the decrement bounds
/// nothing of them).
struct ClothMass {
  double total = 0.0, smallest = 0.0;
};
ClothMass cloth_mass(const bodies::Assembly& g) {
  ClothMass m{0.0, std::numeric_limits<double>::infinity()};
  for (const Body* b : g.bodies()) {
    const auto* c = dynamic_cast<const ClothBody*>(b);
    if (!c) return {};
    m.total += c->mass().sum();
    if (c->mass().size() > 0) m.smallest = std::min(m.smallest, c->mass().minCoeff());
  }
  if (!std::isfinite(m.smallest)) m.smallest = 0.0;
  return m;
}
/// What a gradient norm |g| guarantees of the mass-weighted RMS velocity error, for solvers that measure no Newton
/// decrement: where the step's Hessian is at least its inertia M/h², the minimizer is within ‖g‖_{(M/h²)⁻¹} of x in
/// the M/h² norm, so the velocity error's ‖δv‖_M ≤ h‖g‖_{M⁻¹} ≤ h|g|/√m_min, and its RMS over the mass M_c is at most
/// h|g|/√(m_min·M_c). Infinite when the group has no mass.
double rms_velocity_bound(double grad_norm, double h, double mass, double min_mass) {
  return mass > 0.0 && min_mass > 0.0 ? h * grad_norm / std::sqrt(min_mass * mass)
                                      : std::numeric_limits<double>::infinity();
}
}  // namespace

size_t Simulator::body_index(const std::string& name) const {
  std::vector<std::string> names;
  for (size_t b = 0; b < m_bodies.size(); ++b) {
    if (m_bodies[b]->name() == name) return b;
    names.push_back(fmt::format("\"{}\"", m_bodies[b]->name()));
  }
  throw InputError(fmt::format("{}: no body named \"{}\" (the scene has {})", m_scene.file, name,
                               names.empty() ? std::string("none") : fmt::format("{}", fmt::join(names, ", "))));
}

std::vector<ClothBody*> Simulator::cloths() const {
  std::vector<ClothBody*> out;
  for (const auto& b : m_bodies)
    if (auto* c = dynamic_cast<ClothBody*>(b.get())) out.push_back(c);
  return out;
}

std::vector<ShellBody*> Simulator::shells() const {
  std::vector<ShellBody*> out;
  for (const auto& b : m_bodies)
    if (auto* s = dynamic_cast<ShellBody*>(b.get())) out.push_back(s);
  return out;
}

void Simulator::check_start_outside_obstacles(size_t c, const ClothBody& body) const {
  // A cloth that starts deep inside an obstacle cannot be simulated: projecting its vertices out piles them onto the
  // surface (degenerate triangles, non-finite bending), and the first solve fails far from the cause. Within the
  // contact layer the projection is a small push, so only depths beyond the layer's thickness are refused.
  const VecX& x = body.x();
  const double limit = m_scene.contact.thickness;
  for (size_t o = 0; o < m_obstacles.size(); ++o) {
    if (!m_obstacles[o].shape) continue;  // a mesh: the cloth-contact term's start check covers it
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

solvers::Problem Simulator::prepare_problem(size_t g, VecX& x0, double* load_factor) {
  bodies::Assembly& group = *m_groups[g];
  // Static shells step the load: step k of K applies k/K of it (Kopaničáková 2019 §7).
  const double lambda = std::min(1.0, static_cast<double>(m_step + 1) / static_cast<double>(std::max(1L, m_scene.total_steps())));
  x0 = group.prepare_step({time(), m_scene.step_size(), lambda});
  if (load_factor) {
    *load_factor = 1.0;
    for (const Body* b : group.bodies())
      if (b->is_static()) *load_factor = lambda;
  }
  solvers::Problem problem;
  problem.objective = &group.objective();
  const solvers::NonlinearSolver& solver = *m_solvers[g];
  if (solver.needs_hierarchy() || solver.needs_level_objectives())
    problem.hierarchy = group.solver_hierarchy(solver.needs_level_objectives());
  problem.project = group.feasibility_projection();
  solvers::check_step_limits(solver, *problem.objective, m_scene.file);
  if (m_scene.solver.velocity_tol > 0.0 && !solver.estimates_step_error())
    throw InputError(fmt::format("{}: solver.velocity_tol: solver \"{}\" is a single-level smoother, whose steps do "
                                 "not show how far it is from the solution; use rel_grad with it, or a multilevel or "
                                 "Newton solver (fmg, newton, newton-mg, ...) with velocity_tol",
                                 m_scene.file, solver.name()));
  if (m_scene.solver.velocity_rms_tol > 0.0 && !(cloth_mass(group).total > 0.0))
    throw InputError(fmt::format("{}: solver.velocity_rms_tol: {} is not a group of cloths with mass (a shell's "
                                 "unknowns carry no inertia term); use velocity_tol or rel_grad",
                                 m_scene.file, group_label(group)));
  return problem;
}

std::vector<StepStats> Simulator::step() {
  const double h = m_scene.step_size();
  const double t = time();
  std::vector<StepStats> out;
  size_t probes_before = 0;  // probes of the groups before this one
  for (size_t g = 0; g < m_groups.size(); ++g) {
    Timer timer;
    bodies::Assembly& group = *m_groups[g];
    solvers::NonlinearSolver& solver = *m_solvers[g];
    StepStats s;
    VecX x;
    if (const physics::ClothContact* contact = group.cloth_contact()) contact->take_times();
    solvers::Problem problem = prepare_problem(g, x, &s.load_factor);
    const auto solve = [&](solvers::Trace* trace, const solvers::Stop& stop) {
      try {
        return building(
            [&] {
              return fmt::format("the solve of step {} of {} ({}, solver {}: its matrices and levels)", m_step + 1,
                                 group_label(group), group_size(group), solver.name());
            },
            [&] { return solver.minimize(problem, x, stop, trace); });
      } catch (const SolveError& e) {
        throw SolveError(fmt::format("{}: {}, frame {}, step {} (t = {:.4f} s): {}", m_scene.file, group_label(group),
                                     m_frame + 1, m_step + 1, t + h, e.what()));
      }
    };
    solvers::Stop stop = m_scene.solver.stop;
    stop.step_tol = m_scene.solver.velocity_tol * h;
    const ClothMass cm = cloth_mass(group);
    const double mass = cm.total, min_mass = cm.smallest;
    const double rms_tol = m_scene.solver.velocity_rms_tol;
    stop.decrement_tol = mass * rms_tol * rms_tol;
    // A solver that measures no decrement stops where the gradient bounds the error (rms_velocity_bound): a gradient
    // norm of rms_tol·√(m_min·M)/h. A stricter rule than the decrement's (the bound holds for the whole Hessian's
    // stiffness, not only its inertia), but one every solver checks.
    if (rms_tol > 0.0 && !solver.estimates_decrement())
      stop.abs_grad = std::max(stop.abs_grad, rms_tol * std::sqrt(min_mass * mass) / h);
    s.report = solve(m_record_trace ? &s.trace : nullptr, stop);
    // Mesh obstacles the start point's motion could not take all the way go on from the solve's result, and the
    // step is solved again from there, until they are where their motion puts them.
    for (int round = 1; group.obstacles_behind(); ++round) {
      if (round > kObstacleRounds)
        throw SolveError(fmt::format("{}: {}, frame {}, step {} (t = {:.4f} s): the obstacle meshes could not reach "
                                     "their poses in {} solves: cloth is caught between them or moves too little "
                                     "out of their way; use a smaller time step or slow the obstacles",
                                     m_scene.file, group_label(group), m_frame + 1, m_step + 1, t + h, kObstacleRounds));
      group.advance_obstacles(x);
      // The step's criterion stays relative to the gradient it started with, not to the smaller one of this start.
      solvers::Stop again = stop;
      again.abs_grad = std::max(again.abs_grad, again.rel_grad * s.report.initial_grad_norm);
      const solvers::SolveReport more = solve(nullptr, again);
      s.report.iterations += more.iterations;
      s.report.wall_ms += more.wall_ms;
      s.obstacle_rounds = round;
      s.report.status = more.status;
      s.report.grad_norm = more.grad_norm;
      s.report.step_error = more.step_error;
      if (!std::isnan(more.decrement)) s.report.decrement = more.decrement;
    }
    s.velocity_error = s.report.step_error / h;
    if (!solver.estimates_decrement()) {
      const double bound = rms_velocity_bound(s.report.grad_norm, h, mass, min_mass);
      if (std::isfinite(bound)) s.velocity_rms_error = bound;
    } else if (mass > 0.0) {
      s.velocity_rms_error = std::sqrt(s.report.decrement / mass);
    }
    if (!m_checkers.empty()) check_accuracy(g, problem, x, h, s);
    const VecX before = x;
    VecX v;
    if (solver.finish_step(group.x(), h, x, v))
      group.accept_step(x, v);
    else
      group.finish_step(x, h);
    s.projected = static_cast<Index>(((x - before).array() != 0.0).reshaped(3, x.size() / 3).colwise().any().count());
    if (const physics::ClothContact* contact = group.cloth_contact()) {
      const VecX end = group.x();
      const physics::ContactStats cs = contact->stats(end);
      s.contact_pairs = cs.pairs;
      s.min_distance = cs.min_distance;
      s.contact_detection_ms = contact->take_times().detection_ms();
      if (m_scene.cloth_contact.check_intersections) {
        const Timer check;
        size_t count = 0;
        const VecX all = contact->with_kinematic(end);
        collision::find_intersections(all, contact->triangles(), 0, &count, contact->cloth_triangles(),
                                      &contact->joined_points());
        s.intersections = static_cast<Index>(count);
        s.check_ms = check.ms();
      }
    }
    std::vector<std::string> names;
    for (const Body* b : group.bodies()) {
      if (const auto* c = dynamic_cast<const ClothBody*>(b)) {
        const double gap = widest_seam_gap(*c);
        if (!std::isnan(gap)) s.seam_gap = std::isnan(s.seam_gap) ? gap : std::max(s.seam_gap, gap);
      }
      names.push_back(b->name());
      for (auto& p : b->probes()) s.probes.push_back(p);
    }
    s.first_probe = probes_before;
    probes_before += s.probes.size();
    s.frame = m_frame + 1;
    s.step = m_step + 1;
    s.sim_time = t + h;
    s.body = fmt::format("{}", fmt::join(names, "+"));
    s.solver = solver.name();
    s.wall_ms = timer.ms();
    out.push_back(std::move(s));
  }
  ++m_step;
  return out;
}

void Simulator::set_accuracy_check(bool on) {
  m_checkers.clear();
  if (!on) return;
  solvers::SolverConfig config;
  config.name = "newton-direct";
  for (size_t g = 0; g < m_groups.size(); ++g) m_checkers.push_back(solvers::make_solver(config, m_scene.file, "check"));
}

void Simulator::check_accuracy(size_t g, const solvers::Problem& problem, const VecX& x, double h, StepStats& s) {
  solvers::NonlinearSolver& checker = *m_checkers[g];
  VecX ref = x;
  solvers::Stop tight;
  tight.rel_grad = 0.0;
  tight.abs_grad = 1e-8 * s.report.initial_grad_norm;
  tight.max_iters = 100;
  try {
    // Without the feasibility projection: it moves vertices after each accepted step, outside the objective, so
    // Newton's iterates would not converge to the objective's minimizer (the drape's steps stalled at 1e-4).
    solvers::Problem plain;
    plain.objective = problem.objective;
    const solvers::SolveReport r = checker.minimize(plain, ref, tight, nullptr);
    // Newton converges quadratically: where it stops short of 1e-8 it is at the round-off floor, which lies far
    // below the errors that stop rules leave (1e-3 of the initial gradient and more).
    if (!r.converged && !(r.grad_norm <= 1e-6 * s.report.initial_grad_norm)) {
      logger().warn("{}: the accuracy check of step {} stopped with status {} at |g| = {:.3e} ({:.3e} of the step's "
                    "initial gradient); its error is not recorded",
                    m_scene.file, m_step + 1, r.status, r.grad_norm, r.grad_norm / s.report.initial_grad_norm);
      return;
    }
  } catch (const SolveError& e) {
    logger().warn("{}: the accuracy check of step {} failed: {}", m_scene.file, m_step + 1, e.what());
    return;
  }
  s.true_velocity_error = solvers::max_vertex_distance(x, ref) / h;
  s.true_velocity_rms = (x - ref).norm() / std::sqrt(std::max<double>(1.0, static_cast<double>(x.size() / 3))) / h;
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
  auto* cloth = c < m_bodies.size() ? dynamic_cast<ClothBody*>(m_bodies[c].get()) : nullptr;
  if (!cloth) throw_input_error("cloth {} out of range (the scene has {} cloths)", c, m_scene.cloths.size());
  cloth->set_pin_targets(targets, time(), time() + m_scene.frame_time);
}

void Simulator::set_obstacle_pose(size_t o, const geometry::Pose& pose) {
  if (o >= m_steering.size()) throw_input_error("obstacle {} out of range (the scene has {} obstacles)", o, m_steering.size());
  if (!pose.translation.allFinite())
    throw_input_error("obstacle \"{}\": position must be finite (got [{}, {}, {}])", m_obstacles[o].name,
                      pose.translation.x(), pose.translation.y(), pose.translation.z());
  m_steering[o]->steer(time(), time() + m_scene.frame_time, pose);
}

void Simulator::set_state(int frame, long step, const std::vector<VecX>& x, const std::vector<VecX>& v) {
  if (x.size() != m_bodies.size() || v.size() != x.size())
    throw InputError(fmt::format("the state has {} bodies, the scene has {} cloths and {} shells", x.size(),
                                 m_scene.cloths.size(), m_scene.shells.size()));
  for (size_t b = 0; b < m_bodies.size(); ++b) {
    Body& body = *m_bodies[b];
    if (x[b].size() != body.x().size() || v[b].size() != body.v().size())
      throw InputError(fmt::format("{} \"{}\" has {} dofs, the scene's has {}", body.kind(), body.name(), x[b].size(),
                                   body.x().size()));
  }
  for (size_t b = 0; b < m_bodies.size(); ++b) {
    m_bodies[b]->x() = x[b];
    m_bodies[b]->v() = v[b];
  }
  m_frame = frame;
  m_step = step;
  // A step always ends with the obstacle meshes at their poses (step()), so a state at a step is theirs then, at
  // the time as that step computed it (t + h, which need not round to step · h), so that a resumed run repeats.
  const double h = m_scene.step_size();
  const double end = m_step > 0 ? static_cast<double>(m_step - 1) * h + h : 0.0;
  for (auto& g : m_groups) g->place_obstacles(end);
}

std::string Simulator::solver_state(size_t body) const {
  if (body >= m_bodies.size()) throw_error("solver state of body {}, the scene has {} bodies", body, m_bodies.size());
  const size_t g = m_group_of[body];
  if (m_groups[g]->bodies().front() != m_bodies[body].get()) return {};
  return m_solvers[g]->carried_state();
}

void Simulator::set_solver_state(size_t body, std::string_view state) {
  if (body >= m_bodies.size())
    throw InputError(fmt::format("solver state for body {}, the scene has {} bodies", body, m_bodies.size()));
  const size_t g = m_group_of[body];
  const Body& b = *m_bodies[body];
  if (m_groups[g]->bodies().front() != &b) {
    if (!state.empty())
      throw InputError(fmt::format("{} \"{}\": a solver state for a body solved jointly with \"{}\", which keeps "
                                   "its group's", b.kind(), b.name(), m_groups[g]->bodies().front()->name()));
    return;
  }
  try {
    m_solvers[g]->restore_carried_state(state);
  } catch (const InputError& e) {
    throw InputError(fmt::format("{} \"{}\": {}", b.kind(), b.name(), e.what()));
  }
}

}  // namespace mgcloth::sim
