#include <mgcloth/core/error.hpp>
#include <mgcloth/physics/element_kernels.hpp>
#include <mgcloth/physics/membrane.hpp>

namespace mgcloth::physics {

TriangleRest triangle_rest(const mesh::TriMesh& mesh, Index t) {
  const Tri& tri = mesh.tris[t];
  Mat2 dm;
  dm.col(0) = mesh.u.col(tri[1]) - mesh.u.col(tri[0]);
  dm.col(1) = mesh.u.col(tri[2]) - mesh.u.col(tri[0]);
  const double det = dm.determinant();
  if (!(det > 0.0)) throw_input_error("triangle {}: non-positive material area {}", t, 0.5 * det);
  return {dm.inverse(), 0.5 * det};
}

std::vector<TriangleRest> triangle_rests(const mesh::TriMesh& mesh) {
  std::vector<TriangleRest> rest;
  rest.reserve(mesh.tris.size());
  for (Index t = 0; t < mesh.num_triangles(); ++t) rest.push_back(triangle_rest(mesh, t));
  return rest;
}

double stvk_triangle(const Vec9& xe, const Mat2& dm_inv, double at, double mu, double lambda, Vec9* g, Mat9* H,
                     bool clamp_stress) {
  const double dm[4] = {dm_inv(0, 0), dm_inv(0, 1), dm_inv(1, 0), dm_inv(1, 1)};
  return hd::stvk_triangle(xe.data(), dm, at, mu, lambda, g ? g->data() : nullptr, H ? H->data() : nullptr,
                           clamp_stress);
}

StVKMembrane::StVKMembrane(const mesh::TriMesh& mesh, const Material& m)
    : m_thickness(m.thickness), m_mu(m.mu()), m_lambda(m.lambda_plane_stress()) {
  m_rest = triangle_rests(mesh);
  set_elements(std::vector<Element>(mesh.tris.begin(), mesh.tris.end()), mesh.num_vertices());
}

double StVKMembrane::element(Index e, const Local& xe, Local* g, LocalHessian* H) const {
  return stvk_triangle(xe, m_rest[e].dm_inv, m_rest[e].area * m_thickness, m_mu, m_lambda, g, H);
}

MassSpringMembrane::MassSpringMembrane(const mesh::TriMesh& mesh, const mesh::Topology& topo, const Material& m) {
  std::vector<Element> els(topo.edges.begin(), topo.edges.end());
  m_rest.resize(els.size());
  m_stiffness.resize(els.size());
  for (size_t e = 0; e < els.size(); ++e) {
    const double L = (mesh.u.col(els[e][1]) - mesh.u.col(els[e][0])).norm();
    double area = 0.0;
    for (Index t : topo.edge_tris[e])
      if (t >= 0) area += std::abs(mesh.material_area(t)) / 3.0;
    m_rest[e] = L;
    m_stiffness[e] = m.youngs_modulus * m.thickness * area / (L * L);
  }
  set_elements(std::move(els), mesh.num_vertices());
}

void StVKMembrane::element_psd_hessian(Index e, const Local& xe, LocalHessian& H) const {
  stvk_triangle(xe, m_rest[e].dm_inv, m_rest[e].area * m_thickness, m_mu, m_lambda, nullptr, &H, true);
}

double MassSpringMembrane::element(Index e, const Local& xe, Local* g, LocalHessian* H) const {
  const Vec3 d = xe.segment<3>(3) - xe.segment<3>(0);
  const double l = d.norm(), L = m_rest[e], k = m_stiffness[e];
  if (g) {
    const Vec3 f = l > 0.0 ? Vec3(k * (l - L) * d / l) : Vec3::Zero();
    g->segment<3>(0) = -f;
    g->segment<3>(3) = f;
  }
  if (H) {
    const Vec3 n = l > 0.0 ? Vec3(d / l) : Vec3::UnitX();
    const Mat3 nn = n * n.transpose();
    const Mat3 K = k * (nn + (l > 0.0 ? 1.0 - L / l : 0.0) * (Mat3::Identity() - nn));
    H->block<3, 3>(0, 0) = K;
    H->block<3, 3>(3, 3) = K;
    H->block<3, 3>(0, 3) = -K;
    H->block<3, 3>(3, 0) = -K;
  }
  return 0.5 * k * (l - L) * (l - L);
}


bool StVKMembrane::describe_device(DeviceObjective& out) const {
  out.claim(out.membrane, name());
  out.triangles.assign(elements().begin(), elements().end());
  out.mu = m_mu;
  out.lambda = m_lambda;
  out.dm_inv.clear();
  out.area_thickness.clear();
  for (const TriangleRest& r : m_rest) {
    out.dm_inv.push_back({r.dm_inv(0, 0), r.dm_inv(0, 1), r.dm_inv(1, 0), r.dm_inv(1, 1)});
    out.area_thickness.push_back(r.area * m_thickness);
  }
  return true;
}

}  // namespace mgcloth::physics
