#include <mgcloth/core/error.hpp>
#include <mgcloth/physics/contact.hpp>
#include <mgcloth/physics/element_kernels.hpp>

namespace mgcloth::physics {

ObstaclePenalty::ObstaclePenalty(VecX area, std::vector<geometry::Obstacle> obstacles, const ContactParams& params)
    : m_area(std::move(area)), m_obstacles(std::move(obstacles)), m_params(params) {
  const Index n = static_cast<Index>(m_area.size());
  std::vector<Element> els(n);
  for (Index i = 0; i < n; ++i) els[i] = {i};
  set_elements(std::move(els), n);
  set_time(0.0);
}

void ObstaclePenalty::set_time(double t) {
  m_poses.resize(m_obstacles.size());
  m_data.resize(m_obstacles.size());
  for (size_t o = 0; o < m_obstacles.size(); ++o) {
    m_poses[o] = m_obstacles[o].motion->pose(t);
    m_data[o] = m_obstacles[o].data(m_poses[o]);
  }
}

ObstacleContact::ObstacleContact(VecX area, std::vector<geometry::Obstacle> obstacles, const ContactParams& params)
    : ObstaclePenalty(std::move(area), std::move(obstacles), params) {}

double ObstacleContact::element(Index i, const Local& xe, Local* g, LocalHessian* H) const {
  const double d = params().thickness, k = vertex_stiffness(i);
  double energy = 0.0;
  if (g) g->setZero();
  if (H) H->setZero();
  for (size_t o = 0; o < obstacles().size(); ++o) {
    if (d - obstacles()[o].distance(xe, poses()[o]) <= 0.0) continue;
    const geometry::SdfSample s = obstacles()[o].sdf(xe, poses()[o]);
    const double gap = d - s.phi;
    if (gap <= 0.0) continue;
    energy += k * gap * gap * gap / (3.0 * d);
    if (g) *g -= (k / d) * gap * gap * s.grad;
    if (H) *H += (k / d) * (2.0 * gap * s.grad * s.grad.transpose() - gap * gap * s.hess);
  }
  return energy;
}

void ObstacleContact::element_psd_hessian(Index i, const Local& xe, LocalHessian& H) const {
  H.setZero();
  for (const hd::ObstacleData& o : obstacle_data())
    hd::contact_psd(o, xe.data(), vertex_stiffness(i), params().thickness, nullptr, H.data());
}

Index project_out_of_obstacles(VecX& x, const std::vector<geometry::Obstacle>& obstacles,
                               const std::vector<geometry::Pose>& poses, VecX* pushed) {
  const Index n = static_cast<Index>(x.size() / 3);
  if (pushed) pushed->setZero(n);
  std::vector<char> moved(n, 0);
  parallel_for(n, [&](Index i) {
    // A vertex may touch several obstacles; a few passes settle it where their surfaces meet.
    for (int pass = 0; pass < 4; ++pass) {
      bool inside = false;
      for (size_t o = 0; o < obstacles.size(); ++o) {
        const Vec3 p = x.segment<3>(3 * i);
        if (obstacles[o].distance(p, poses[o]) >= 0.0) continue;
        const geometry::SdfSample s = obstacles[o].sdf(p, poses[o]);
        if (s.phi >= 0.0) continue;
        inside = true;
        x.segment<3>(3 * i) = p - s.phi * s.grad;
        if (pushed) (*pushed)[i] -= s.phi;
        moved[i] = 1;
      }
      if (!inside) break;
    }
  });
  Index count = 0;
  for (char c : moved) count += c;
  return count;
}

void apply_friction(const VecX& x, VecX& v, const VecX& mass, const ObstaclePenalty& contact, double h,
                    const VecX& pushed, double t) {
  const auto& obstacles = contact.obstacles();
  const auto& poses = contact.poses();
  const double d = contact.params().thickness;
  const Index n = static_cast<Index>(x.size() / 3);
  parallel_for(n, [&](Index i) {
    const Vec3 p = x.segment<3>(3 * i);
    for (size_t o = 0; o < obstacles.size(); ++o) {
      if (d - obstacles[o].distance(p, poses[o]) <= 0.0) continue;
      const geometry::SdfSample s = obstacles[o].sdf(p, poses[o]);
      const double gap = d - s.phi;
      if (gap <= 0.0) continue;
      const Vec3 nrm = s.grad;
      const Vec3 v_obs = obstacles[o].motion->point_velocity(t, p);
      Vec3 v_rel = v.segment<3>(3 * i) - v_obs;
      double vn = v_rel.dot(nrm);
      // The normal velocity change the contact produced this step: penalty impulse plus projection push.
      const double dvn = h * contact.normal_force(i, gap) / mass[i] + pushed[i] / h;
      if (vn < 0.0) vn = 0.0;  // no velocity into the obstacle survives the step
      Vec3 vt = v_rel - v_rel.dot(nrm) * nrm;
      const double vt_norm = vt.norm();
      const double mu = obstacles[o].friction;
      if (mu > 0.0 && vt_norm > 0.0) vt *= std::max(0.0, 1.0 - mu * dvn / vt_norm);
      v.segment<3>(3 * i) = v_obs + vn * nrm + vt;
    }
  });
}

}  // namespace mgcloth::physics
