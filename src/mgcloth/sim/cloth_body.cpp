#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/seam.hpp>
#include <mgcloth/sim/cloth_body.hpp>

namespace mgcloth::sim {

VecX lumped_vertex_area(const mesh::TriMesh& mesh) {
  VecX a = VecX::Zero(mesh.num_vertices());
  for (Index t = 0; t < mesh.num_triangles(); ++t)
    for (Index v : mesh.tris[t]) a[v] += std::abs(mesh.material_area(t)) / 3.0;
  return a;
}

namespace {

mesh::TriMesh load_mesh(const ClothSpec& spec) {
  if (!spec.mesh.file.empty()) return mesh::read_obj(spec.mesh.file, spec.mesh.material_scale);
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

}  // namespace

ClothBody::ClothBody(const ClothSpec& spec, const std::vector<geometry::Obstacle>& obstacles,
                     const physics::ContactParams& contact, const Vec3& gravity, bool projective)
    : m_name(spec.name), m_mesh(load_mesh(spec)), m_material_scale(spec.mesh.material_scale), m_pin_specs(spec.pins) {
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

  if (projective) throw InputError("the Projective Dynamics formulation is not available yet");
  m_objective = physics::Objective(n);
  m_inertia = &m_objective.add(std::make_unique<physics::InertiaTerm>(m_mass));
  m_objective.add(std::make_unique<physics::GravityTerm>(m_mass, gravity));
  if (spec.material.membrane == physics::MembraneModel::StVK)
    m_objective.add(std::make_unique<physics::StVKMembrane>(m_mesh, spec.material));
  else
    m_objective.add(std::make_unique<physics::MassSpringMembrane>(m_mesh, m_topology, spec.material));
  if (spec.material.bending == physics::BendingModel::Hinge)
    m_objective.add(std::make_unique<physics::HingeBending>(m_mesh, m_topology, spec.material));
  else if (spec.material.bending == physics::BendingModel::Quadratic)
    m_objective.add(std::make_unique<physics::QuadraticBending>(m_mesh, m_topology, spec.material));

  if (!m_topology.stitch_groups.empty())
    m_objective.add(std::make_unique<physics::SeamTerm>(m_topology.stitch_groups, spec.seam_stiffness, n));

  std::vector<double> stiffness;
  for (size_t k = 0; k < m_pin_specs.size(); ++k) {
    const PinSpec& p = m_pin_specs[k];
    geometry::PointCurve curve;
    if (p.motion == "keyframes") curve = geometry::PointCurve(p.key_times, p.key_offsets);
    m_pin_curves.push_back(curve);
    for (Index v : select_pins(p, m_mesh, m_name, k)) {
      m_pin_vertices.push_back(v);
      m_pin_rest.push_back(m_x.segment<3>(3 * v));
      m_pin_spec.push_back(k);
      stiffness.push_back(p.stiffness);
    }
  }
  if (!m_pin_vertices.empty())
    m_pins = &m_objective.add(std::make_unique<physics::AttachmentTerm>(m_pin_vertices, stiffness, n));
  if (!obstacles.empty())
    m_contact = &m_objective.add(std::make_unique<physics::ObstacleContact>(m_area, obstacles, contact));
  m_objective.finalize();
}

const hierarchy::TriangleHierarchy& ClothBody::hierarchy(const hierarchy::HierarchyParams& params) {
  if (!m_hierarchy) {
    hierarchy::HierarchyParams p = params;
    p.keep.insert(p.keep.end(), m_pin_vertices.begin(), m_pin_vertices.end());  // pins are exact on every level
    m_hierarchy = std::make_unique<hierarchy::TriangleHierarchy>(hierarchy::build_triangle_hierarchy(m_mesh, p));
  }
  return *m_hierarchy;
}

std::vector<const hierarchy::TransferTable*> prolongations(const hierarchy::TriangleHierarchy& h) {
  std::vector<const hierarchy::TransferTable*> p;
  for (Index l = 0; l + 1 < h.num_levels(); ++l) p.push_back(&h.prolongation(l));
  return p;
}

std::vector<Vec3> ClothBody::pin_targets(double t) const {
  std::vector<Vec3> targets(m_pin_vertices.size());
  for (size_t p = 0; p < targets.size(); ++p) {
    const PinSpec& s = m_pin_specs[m_pin_spec[p]];
    Vec3 offset = Vec3::Zero();
    if (s.motion == "constant_velocity") offset = s.velocity * t;
    if (s.motion == "keyframes") offset = m_pin_curves[m_pin_spec[p]](t);
    targets[p] = m_pin_rest[p] + offset;
  }
  return targets;
}

VecX ClothBody::prepare_step(double t, double h) {
  const double t_next = t + h;
  VecX y = m_x + h * m_v;
  m_inertia->set_prediction(y, h);
  if (m_pins) m_pins->set_targets(pin_targets(t_next));
  if (m_contact) {
    m_contact->set_time(t_next);
    physics::project_out_of_obstacles(y, m_contact->obstacles(), m_contact->poses());
  }
  return y;
}

void ClothBody::finish_step(VecX& x_new, double t_next, double h) {
  VecX pushed = VecX::Zero(m_mesh.num_vertices());
  if (m_contact) physics::project_out_of_obstacles(x_new, m_contact->obstacles(), m_contact->poses(), &pushed);
  m_v = (x_new - m_x) / h;
  if (m_contact) physics::apply_friction(x_new, m_v, m_mass, *m_contact, h, pushed, t_next);
  m_x = x_new;
}

}  // namespace mgcloth::sim
