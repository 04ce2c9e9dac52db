// A flat square sheet as a contact surface, shared by the cloth contact and friction tests.
#pragma once
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/physics/cloth_contact.hpp>

#include <cmath>
#include <string>

namespace mgcloth::physics::fixtures {

/// A square sheet of side `side` (material = rest shape), flat at height z, appended to x; its points start at
/// `offset` in the unknown.
inline ContactSurface sheet(const std::string& name, double side, Index target, double z, Index offset, VecX& x,
                            double thickness = 1e-3) {
  mesh::RectangleSpec spec;
  spec.width = spec.height = side;
  spec.target_vertices = target;
  const mesh::TriMesh m = mesh::make_rectangle(spec);
  ContactSurface s;
  s.name = name;
  s.offset = offset;
  s.tris = m.tris;
  s.material = m.u;
  s.area = VecX::Zero(m.num_vertices());
  for (const Tri& t : m.tris) {
    const double a = std::abs(m.material_area(&t - m.tris.data())) / 3.0;
    for (Index v : t) s.area[v] += a;
  }
  s.thickness = thickness;
  const Index n0 = static_cast<Index>(x.size() / 3);
  x.conservativeResize(3 * (n0 + m.num_vertices()));
  for (Index i = 0; i < m.num_vertices(); ++i) x.segment<3>(3 * (n0 + i)) = Vec3(m.u(0, i), m.u(1, i), z);
  return s;
}

}  // namespace mgcloth::physics::fixtures
