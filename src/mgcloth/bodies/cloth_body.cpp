#include <mgcloth/core/error.hpp>
#include <mgcloth/core/out_of_memory.hpp>
#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/seam.hpp>
#include <mgcloth/bodies/cloth_body.hpp>
#include <mgcloth/mesh/pattern.hpp>

namespace mgcloth::bodies {

VecX lumped_vertex_area(const mesh::TriMesh& mesh) {
  VecX a = VecX::Zero(mesh.num_vertices());
  for (Index t = 0; t < mesh.num_triangles(); ++t)
    for (Index v : mesh.tris[t]) a[v] += std::abs(mesh.material_area(t)) / 3.0;
  return a;
}

namespace {

mesh::TriMesh load_mesh(const ClothSpec& spec, const mesh::TriMesh* given) {
  if (given) {
    mesh::TriMesh m = *given;
    mesh::validate(m, "mesh arrays");
    return m;
  }
  if (!spec.mesh.file.empty()) return mesh::read_obj(spec.mesh.file, spec.mesh.material_scale);
  // Panels in their placements, stitched edges sharing source vertices: the seam springs sew them.
  if (!spec.mesh.pattern.empty())
    return mesh::triangulate_pattern(mesh::read_pattern(spec.mesh.pattern), spec.mesh.pattern_resolution).mesh;
  if (spec.mesh.generator == "tube") return mesh::make_tube(spec.mesh.tube);
  return mesh::make_rectangle(spec.mesh.rectangle);
}

std::vector<Index> select_pins(const PinSpec& p, const mesh::TriMesh& m, const std::string& cloth, size_t k) {
  std::vector<Index> out;
  for (Index v : p.vertices) {
    if (v >= m.num_vertices())
      throw InputError(fmt::format("cloth \"{}\": pins[{}]: vertex {} out of range (the mesh has {} vertices)", cloth, k, v,
                                   m.num_vertices()));
    out.push_back(v);
  }
  for (const Vec2& q : p.points) {
    Index best = 0;
    (m.u.colwise() - q).colwise().squaredNorm().minCoeff(&best);
    out.push_back(best);
  }
  if (p.region) {
    const size_t before = out.size();
    for (Index i = 0; i < m.num_vertices(); ++i) {
      const Vec2 u = m.u.col(i);
      if ((u.array() >= p.region->first.array() - 1e-12).all() && (u.array() <= p.region->second.array() + 1e-12).all())
        out.push_back(i);
    }
    if (out.size() == before)
      throw InputError(fmt::format("cloth \"{}\": pins[{}]: region selects no vertex", cloth, k));
  }
  return out;
}

/// The obstacles a cloth's own penalty acts on: those of a signed-distance shape. Mesh obstacles touch cloth through
/// the cloth-contact term (bodies::Assembly::add_cloth_contact).
std::vector<geometry::Obstacle> shape_obstacles(const std::vector<geometry::Obstacle>& all) {
  std::vector<geometry::Obstacle> out;
  for (const auto& o : all)
    if (o.shape) out.push_back(o);
  return out;
}

}  // namespace

ClothBody::ClothBody(const ClothSpec& spec, const ClothEnvironment& env, const mesh::TriMesh* mesh)
    : m_name(spec.name),
      m_mesh(load_mesh(spec, mesh)),
      m_material_scale(spec.mesh.material_scale),
      m_material(spec.material),
      m_gravity(env.gravity),
      m_seam_stiffness(spec.seam_stiffness),
      m_obstacles(shape_obstacles(env.obstacles)),
      m_contact_params(env.contact),
      m_hierarchy_params(env.hierarchy),
      m_projective(env.energy_form == physics::EnergyForm::Projective),
      m_pin_specs(spec.pins) {
  m_topology = mesh::build_topology(m_mesh, spec.mesh.file.empty() ? spec.name : spec.mesh.file);
  // Initial world state: the mesh's own positions, placed by the cloth's transform.
  const Eigen::Quaterniond R = spec.transform.rotation();
  for (Index i = 0; i < m_mesh.num_vertices(); ++i)
    m_mesh.x.col(i) = R * Vec3(m_mesh.x.col(i)) + spec.transform.translation;
  const Index n = m_mesh.num_vertices();
  m_x = as_stacked(m_mesh.x);
  m_v = spec.initial_velocity.replicate(n, 1);
  m_area = lumped_vertex_area(m_mesh);
  m_mass = m_area * spec.material.areal_density();

  for (size_t k = 0; k < m_pin_specs.size(); ++k) {
    const PinSpec& p = m_pin_specs[k];
    geometry::PointCurve curve;
    if (p.motion == "keyframes") curve = geometry::PointCurve(p.key_times, p.key_offsets);
    m_pin_curves.push_back(curve);
    for (Index v : select_pins(p, m_mesh, m_name, k)) {
      m_pin_vertices.push_back(v);
      m_pin_rest.push_back(m_x.segment<3>(3 * v));
      m_pin_spec.push_back(k);
      m_pin_stiffness.push_back(p.stiffness);
    }
  }
  m_levels.push_back(build_objective(m_mesh, m_topology, m_area, m_pin_vertices));
}

ClothBody::LevelObjective ClothBody::build_objective(const mesh::TriMesh& mesh, const mesh::Topology& topology,
                                                     const VecX& area, const std::vector<Index>& pins) const {
  const Index n = mesh.num_vertices();
  const VecX mass = area * m_material.areal_density();
  LevelObjective lv;
  lv.objective = std::make_unique<physics::Objective>(n);
  physics::Objective& obj = *lv.objective;
  lv.inertia = &obj.add(std::make_unique<physics::InertiaTerm>(mass));
  obj.add(std::make_unique<physics::GravityTerm>(mass, m_gravity));
  if (m_projective)
    obj.add(std::make_unique<physics::PDStrainMembrane>(mesh, m_material));
  else if (m_material.membrane == physics::MembraneModel::StVK)
    obj.add(std::make_unique<physics::StVKMembrane>(mesh, m_material));
  else
    obj.add(std::make_unique<physics::MassSpringMembrane>(mesh, topology, m_material));
  // Hinge bending is not a PD constraint (its matrix changes with x); a quadratic model is the PD bending
  // constraint of Bouaziz et al. 2014 for a flat rest state, so the PD form takes the quadratic one for the hinge.
  if (auto bending = physics::make_bending(mesh, topology, m_material, m_projective)) obj.add(std::move(bending));

  if (!topology.stitch_groups.empty())
    obj.add(std::make_unique<physics::SeamTerm>(topology.stitch_groups, m_seam_stiffness, n));
  if (!pins.empty()) lv.pins = &obj.add(std::make_unique<physics::AttachmentTerm>(pins, m_pin_stiffness, n));
  if (!m_obstacles.empty()) {
    if (m_projective) {
      // Active-set margin d: a vertex predicted within 2d of an obstacle keeps w I in the step's matrix, so vertices
      // that move up to d beyond their prediction towards the obstacle are already in it.
      lv.pd_contact = &obj.add(std::make_unique<physics::PDObstacleContact>(area, m_obstacles, m_contact_params,
                                                                            m_contact_params.thickness));
      lv.contact = lv.pd_contact;
    } else {
      lv.contact = &obj.add(std::make_unique<physics::ObstacleContact>(area, m_obstacles, m_contact_params));
    }
  }
  obj.finalize();
  return lv;
}

std::string ClothBody::size_text() const { return fmt::format("{} vertices", m_mesh.num_vertices()); }

const hierarchy::TriangleHierarchy& ClothBody::hierarchy() {
  if (!m_hierarchy) {
    hierarchy::HierarchyParams p = m_hierarchy_params;
    p.keep.insert(p.keep.end(), m_pin_vertices.begin(), m_pin_vertices.end());  // pins are exact on every level
    m_hierarchy = building(
        [&] { return fmt::format("the multigrid hierarchy of cloth \"{}\" ({} vertices)", m_name, m_mesh.num_vertices()); },
        [&] { return std::make_unique<hierarchy::TriangleHierarchy>(hierarchy::build_triangle_hierarchy(m_mesh, p)); });
  }
  return *m_hierarchy;
}

std::vector<const physics::Objective*> ClothBody::level_objectives() {
  const hierarchy::TriangleHierarchy& h = hierarchy();
  if (!m_coarse_built) {
    const double fine_area = m_area.sum();
    for (Index l = 1; l < h.num_levels(); ++l) {
      const hierarchy::Level& level = h.level(l);
      const mesh::Topology topology = mesh::build_topology(level.mesh, fmt::format("{} (level {})", m_name, l));
      // Lumped coarse areas, scaled to the fine total: equal for polygonal panels whose corners every level keeps,
      // and the total mass and weight stay exact where a coarse boundary cuts a curved one.
      VecX area = lumped_vertex_area(level.mesh);
      area *= fine_area / area.sum();
      std::vector<Index> on_level(m_mesh.num_vertices(), -1);
      for (Index i = 0; i < level.mesh.num_vertices(); ++i) on_level[level.to_finest[i]] = i;
      std::vector<Index> pins(m_pin_vertices.size());
      for (size_t p = 0; p < pins.size(); ++p) {
        pins[p] = on_level[m_pin_vertices[p]];
        if (pins[p] < 0) throw_error("cloth \"{}\": pinned vertex {} missing on level {}", m_name, m_pin_vertices[p], l);
      }
      m_levels.push_back(build_objective(level.mesh, topology, area, pins));
    }
    m_coarse_built = true;
    if (m_step_h > 0.0)
      for (size_t l = 1; l < m_levels.size(); ++l) set_coarse_step(l);
  }
  std::vector<const physics::Objective*> out;
  for (size_t l = 1; l < m_levels.size(); ++l) out.push_back(m_levels[l].objective.get());
  return out;
}

hierarchy::Hierarchy ClothBody::solver_hierarchy(bool rediscretized) {
  hierarchy::Hierarchy h = hierarchy().levels_for_solvers();
  h.levels[0].objective = &objective();
  if (!rediscretized) return h;
  const auto coarse = level_objectives();
  m_lsq.resize(h.num_levels());
  for (size_t l = 0; l < h.num_levels(); ++l) {
    if (l > 0) h.levels[l].objective = coarse[l - 1];
    if (l + 1 == h.num_levels()) continue;
    const linalg::StencilTable* P = h.levels[l].prolongation;
    auto* lsq = &m_lsq[l];
    h.levels[l].project_lsq = [lsq, P](const VecX& fine, VecX& coarse_x) {
      if (!*lsq) *lsq = std::make_unique<hierarchy::LeastSquaresProjection>(*P);
      (*lsq)->apply(fine, coarse_x);
    };
  }
  return h;
}

std::vector<Vec3> ClothBody::pin_targets(double t) const {
  if (!m_script_to.empty()) {
    if (!(t > m_script_t0)) return m_script_from;
    if (t >= m_script_t1) return m_script_to;
    const double s = (t - m_script_t0) / (m_script_t1 - m_script_t0);
    std::vector<Vec3> targets(m_script_to.size());
    for (size_t p = 0; p < targets.size(); ++p) targets[p] = m_script_from[p] + s * (m_script_to[p] - m_script_from[p]);
    return targets;
  }
  std::vector<Vec3> targets(m_pin_vertices.size());
  for (size_t p = 0; p < targets.size(); ++p) {
    const PinSpec& s = m_pin_specs[m_pin_spec[p]];
    Vec3 offset = Vec3::Zero();
    if (s.motion == "constant_velocity") offset = s.velocity * t;
    if (s.motion == "keyframes") offset = m_pin_curves[m_pin_spec[p]](t);
    if (s.motion == "rotation") {
      const double tr = std::min(t, s.duration);
      const Eigen::AngleAxisd turn(s.angular_velocity * tr, s.axis.normalized());
      targets[p] = s.center + s.velocity * tr + turn * (m_pin_rest[p] - s.center);
      continue;
    }
    targets[p] = m_pin_rest[p] + offset;
  }
  return targets;
}

void ClothBody::set_pin_targets(const std::vector<Vec3>& targets, double t0, double t1) {
  if (targets.size() != m_pin_vertices.size())
    throw_input_error("cloth \"{}\": {} pin targets given for {} pinned vertices", m_name, targets.size(),
                      m_pin_vertices.size());
  for (size_t p = 0; p < targets.size(); ++p)
    if (!targets[p].allFinite())
      throw_input_error("cloth \"{}\": pin target {} (vertex {}) is not finite", m_name, p, m_pin_vertices[p]);
  if (!(t1 > t0)) throw_error("cloth \"{}\": pin targets must be reached after t0 = {} (got t1 = {})", m_name, t0, t1);
  // Evaluated before the switch: the targets start where the pins pulled at t0, so they move without a jump.
  std::vector<Vec3> from = pin_targets(t0);
  m_script_from = std::move(from);
  m_script_to = targets;
  m_script_t0 = t0;
  m_script_t1 = t1;
}

VecX ClothBody::set_step(LevelObjective& lv, VecX y, double h, double t_next, const std::vector<Vec3>& targets) {
  lv.inertia->set_prediction(y, h);
  if (lv.pins) lv.pins->set_targets(targets);
  if (lv.contact) {
    lv.contact->set_time(t_next);
    physics::project_out_of_obstacles(y, lv.contact->obstacle_data());
    if (lv.pd_contact) lv.pd_contact->set_active(y);
  }
  return y;
}

void ClothBody::set_coarse_step(size_t l) {
  // Coarse vertex sets are nested: a coarse vertex's prediction is the fine prediction of the same vertex.
  const std::vector<Index>& to_finest = m_hierarchy->level(static_cast<Index>(l)).to_finest;
  VecX y(3 * to_finest.size());
  for (size_t i = 0; i < to_finest.size(); ++i) y.segment<3>(3 * i) = m_prediction.segment<3>(3 * to_finest[i]);
  set_step(m_levels[l], std::move(y), m_step_h, m_step_end, pin_targets(m_step_end));
}

VecX ClothBody::prepare_step(double t, double h) {
  m_step_end = t + h;
  m_step_h = h;
  m_prediction = m_x + h * m_v;
  for (size_t l = 1; l < m_levels.size(); ++l) set_coarse_step(l);
  return set_step(m_levels[0], m_prediction, h, m_step_end, pin_targets(m_step_end));
}

void ClothBody::finish_step(VecX& x_new, double h) {
  VecX pushed = VecX::Zero(m_mesh.num_vertices());
  const physics::ObstaclePenalty* c = contact();
  if (c && m_project_obstacles) physics::project_out_of_obstacles(x_new, c->obstacle_data(), &pushed);
  m_v = (x_new - m_x) / h;
  if (c) physics::apply_friction(x_new, m_v, m_mass, *c, h, pushed);
  m_x = x_new;
}

std::function<Index(VecX&)> ClothBody::feasibility_projection() const {
  const physics::ObstaclePenalty* c = contact();
  if (!c || !m_project_obstacles) return {};
  return [c](VecX& y) { return physics::project_out_of_obstacles(y, c->obstacle_data()); };
}

std::optional<physics::ContactSurface> ClothBody::contact_surface(double thickness) const {
  physics::ContactSurface s;
  s.name = m_name;
  s.tris = m_mesh.tris;
  s.material = m_mesh.u;
  s.stitch_groups = m_topology.stitch_groups;
  s.area = m_area;
  s.thickness = thickness;
  return s;
}

void ClothBody::accept_step(const VecX& x_new, const VecX& v_new) {
  if (x_new.size() != m_x.size() || v_new.size() != m_x.size())
    throw_error("cloth \"{}\": the step's end has {} and {} entries for {} dofs", name(), x_new.size(), v_new.size(),
                m_x.size());
  m_x = x_new;
  m_v = v_new;
}

}  // namespace mgcloth::bodies
