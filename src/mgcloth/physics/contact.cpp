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
    m_data[o] = m_obstacles[o].data(t);
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

Index project_out_of_obstacles(VecX& x, const std::vector<hd::ObstacleData>& obstacles, VecX* pushed) {
  const Index n = static_cast<Index>(x.size() / 3);
  if (pushed) pushed->setZero(n);
  std::vector<char> moved(static_cast<size_t>(n), 0);
  const int count = static_cast<int>(obstacles.size());
  parallel_for(n, [&](Index i) {
    const double d = hd::project_vertex(obstacles.data(), count, x.data() + 3 * i);
    if (pushed) (*pushed)[i] = d;
    moved[static_cast<size_t>(i)] = d > 0.0;
  });
  Index count_moved = 0;
  for (char c : moved) count_moved += c;
  return count_moved;
}

void apply_friction(const VecX& x, VecX& v, const VecX& mass, const ObstaclePenalty& contact, double h,
                    const VecX& pushed) {
  const auto& obstacles = contact.obstacle_data();
  const double d = contact.params().thickness;
  const Index n = static_cast<Index>(x.size() / 3);
  parallel_for(n, [&](Index i) {
    for (const hd::ObstacleData& o : obstacles) {
      hd::V3 normal;
      const double gap = hd::contact_gap(o, x.data() + 3 * i, d, normal);
      if (gap <= 0.0) continue;
      // The normal velocity change the contact produced this step: penalty impulse plus projection push.
      const double dvn = h * contact.normal_force(i, gap) / mass[i] + pushed[i] / h;
      hd::filter_velocity(v.data() + 3 * i, hd::point_velocity(o, hd::load3(x.data() + 3 * i)), normal, dvn,
                          o.friction);
    }
  });
}


bool ObstacleContact::describe_device(DeviceObjective& out) const {
  out.claim(out.contact, name());
  out.thickness = params().thickness;
  out.contact_k.resize(static_cast<size_t>(out.n));
  for (Index i = 0; i < out.n; ++i) out.contact_k[static_cast<size_t>(i)] = vertex_stiffness(i);
  return true;
}

void ObstacleContact::describe_device_step(DeviceStep& out) const { out.obstacles = obstacle_data(); }

}  // namespace mgcloth::physics
