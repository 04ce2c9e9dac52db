#include <mgcloth/core/error.hpp>
#include <mgcloth/physics/projective.hpp>

#include <Eigen/SVD>

#include <algorithm>

namespace mgcloth::physics {

namespace {

struct StrainSvd {
  Eigen::Matrix<double, 3, 2> U;
  Mat2 V;
  Vec2 sigma, clamped;
};

StrainSvd strain_svd(const Mat32& F, double sigma_min, double sigma_max) {
  // Full U because Eigen allows thin U only for dynamic sizes; its first two columns are the left singular vectors.
  // Jacobi SVD is exact for F = 0 (U = I, V = I, σ = 0), so collapsed triangles get no NaN.
  const Eigen::JacobiSVD<Mat32> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  StrainSvd s;
  s.U = svd.matrixU().leftCols<2>();
  s.V = svd.matrixV();
  s.sigma = svd.singularValues();
  s.clamped = s.sigma.cwiseMax(sigma_min).cwiseMin(sigma_max);
  return s;
}

}  // namespace

Mat32 project_strain(const Mat32& F, double sigma_min, double sigma_max) {
  const StrainSvd s = strain_svd(F, sigma_min, sigma_max);
  return s.U * s.clamped.asDiagonal() * s.V.transpose();
}

double pd_strain_triangle(const Vec9& xe, const Mat2& dm_inv, double wa, double sigma_min, double sigma_max, Vec9* g,
                          Mat9* H) {
  std::array<Vec2, 3> b;  // F = Σ_a x_a b_aᵀ
  b[1] = dm_inv.row(0).transpose();
  b[2] = dm_inv.row(1).transpose();
  b[0] = -b[1] - b[2];
  if (H)
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) H->block<3, 3>(3 * a, 3 * c) = wa * b[a].dot(b[c]) * Mat3::Identity();
  Mat32 ds;
  ds.col(0) = xe.segment<3>(3) - xe.segment<3>(0);
  ds.col(1) = xe.segment<3>(6) - xe.segment<3>(0);
  const StrainSvd s = strain_svd(ds * dm_inv, sigma_min, sigma_max);
  const Vec2 excess = s.sigma - s.clamped;
  if (g) {
    // F − P(F) from the singular values, not by subtraction: exact zero inside the constraint set.
    const Mat32 residual = s.U * excess.asDiagonal() * s.V.transpose();
    for (int a = 0; a < 3; ++a) g->segment<3>(3 * a) = wa * residual * b[a];
  }
  return 0.5 * wa * excess.squaredNorm();
}

PDStrainMembrane::PDStrainMembrane(const mesh::TriMesh& mesh, const Material& m)
    : m_weight(2.0 * m.mu() * m.thickness), m_sigma_min(m.pd_strain_min), m_sigma_max(m.pd_strain_max) {
  if (!(m_sigma_min >= 0.0 && m_sigma_min <= 1.0 && m_sigma_max >= 1.0))
    throw_input_error("strain limits [{}, {}] must satisfy 0 <= min <= 1 <= max", m_sigma_min, m_sigma_max);
  m_rest = triangle_rests(mesh);
  set_elements(std::vector<Element>(mesh.tris.begin(), mesh.tris.end()), mesh.num_vertices());
}

double PDStrainMembrane::element(Index e, const Local& xe, Local* g, LocalHessian* H) const {
  return pd_strain_triangle(xe, m_rest[e].dm_inv, m_weight * m_rest[e].area, m_sigma_min, m_sigma_max, g, H);
}

PDObstacleContact::PDObstacleContact(VecX area, std::vector<geometry::Obstacle> obstacles, const ContactParams& params,
                                     double margin)
    : ObstaclePenalty(std::move(area), std::move(obstacles), params), m_margin(margin) {
  if (!(margin >= 0.0)) throw_input_error("contact active-set margin must be non-negative (got {})", margin);
  m_active.assign(static_cast<size_t>(num_elements()) * this->obstacles().size(), 0);
}

void PDObstacleContact::set_active(const VecX& y) {
  if (y.size() != 3 * static_cast<Eigen::Index>(num_elements()))
    throw_error("PDObstacleContact::set_active: {} coordinates for {} vertices", y.size(), num_elements());
  const size_t m = obstacles().size();
  const double limit = params().thickness + m_margin;
  std::vector<char> active(m_active.size(), 0);
  parallel_for(num_elements(), [&](Index i) {
    for (size_t o = 0; o < m; ++o)
      active[static_cast<size_t>(i) * m + o] = obstacles()[o].distance(Vec3(y.segment<3>(3 * i)), poses()[o]) < limit;
  }, 1024);
  if (active != m_active) {
    m_active = std::move(active);
    ++m_version;
  }
}

Index PDObstacleContact::num_active() const {
  return static_cast<Index>(std::count(m_active.begin(), m_active.end(), char{1}));
}

double PDObstacleContact::element(Index i, const Local& xe, Local* g, LocalHessian* H) const {
  const double d = params().thickness, w = vertex_stiffness(i);
  double energy = 0.0;
  if (g) g->setZero();
  if (H) H->setZero();
  for (size_t o = 0; o < obstacles().size(); ++o) {
    if (H && active(i, o)) *H += w * Mat3::Identity();  // the PD matrix: the active set, not the iterate, decides
    if (d - obstacles()[o].distance(xe, poses()[o]) <= 0.0) continue;
    const geometry::SdfSample s = obstacles()[o].sdf(xe, poses()[o]);
    const double gap = d - s.phi;
    if (gap <= 0.0) continue;
    energy += 0.5 * w * gap * gap;
    if (g) *g -= w * gap * s.grad;
  }
  return energy;
}

std::uint64_t pd_matrix_version(const Objective& objective) {
  std::uint64_t version = 0;
  for (const auto& t : objective.terms())
    if (const auto* c = dynamic_cast<const PDObstacleContact*>(t.get())) version += c->active_set_version();
  return version;
}

}  // namespace mgcloth::physics
