#include <mgcloth/core/error.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/physics/cloth_friction.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth::physics {

namespace {

void check_coefficient(double mu, const std::string& what) {
  if (!(mu >= 0.0) || !std::isfinite(mu))
    throw_input_error("cloth friction: {} must be non-negative and finite (got {})", what, mu);
}

}  // namespace

ClothFriction::ClothFriction(Index num_points, const std::vector<std::string>& surfaces,
                             const ClothFrictionParams& params)
    : m_n(num_points), m_surfaces(static_cast<Index>(surfaces.size())), m_params(params) {
  check_coefficient(params.friction, "the friction coefficient");
  if (!(params.static_velocity > 0.0) || !std::isfinite(params.static_velocity))
    throw_input_error("cloth friction: the static friction velocity must be positive and finite (got {})",
                      params.static_velocity);
  m_mu.assign(static_cast<size_t>(m_surfaces * m_surfaces), params.friction);
  // A pair names cloths of the whole scene; those of another group (solved separately) are not here.
  const auto find = [&](const std::string& name) -> Index {
    const auto it = std::find(surfaces.begin(), surfaces.end(), name);
    return it == surfaces.end() ? -1 : static_cast<Index>(it - surfaces.begin());
  };
  for (const ClothFrictionPair& p : params.pairs) {
    check_coefficient(p.friction, fmt::format("the coefficient of \"{}\" and \"{}\"", p.a, p.b));
    const Index a = find(p.a), b = find(p.b);
    if (a < 0 || b < 0) continue;
    m_mu[static_cast<size_t>(a * m_surfaces + b)] = m_mu[static_cast<size_t>(b * m_surfaces + a)] = p.friction;
  }
}

double ClothFriction::element_energy(double mu_lambda, double eps, const Vec2& u, Vec2* g, Mat2* H) {
  const double y = u.norm();
  if (y >= eps) {
    // Sliding: f0 = y, force μλ along u; the curvature (I − ûûᵀ)/y turns the force with u and is PSD.
    const Vec2 uh = u / y;
    if (g) *g = mu_lambda * uh;
    if (H) *H = mu_lambda / y * (Mat2::Identity() - uh * uh.transpose());
    return mu_lambda * y;
  }
  // Sticking: ∇ = μλ f1(y)/y · u with f1(y)/y = 2/ε − y/ε², finite at u = 0. Its Hessian
  // μλ (f1/y · I + (f1/y)'/y · u uᵀ) = μλ ((2/ε − y/ε²) I − (y/ε²) ûûᵀ) has eigenvalues μλ(2/ε − 2y/ε²) along u and
  // μλ(2/ε − y/ε²) across it, both >= 0 for y < ε: PSD without projection.
  const double f1_over_y = 2.0 / eps - y / (eps * eps);
  if (g) *g = mu_lambda * f1_over_y * u;
  if (H) {
    *H = mu_lambda * f1_over_y * Mat2::Identity();
    if (y > 0.0) *H -= mu_lambda / (eps * eps * y) * u * u.transpose();
  }
  return mu_lambda * (-y * y * y / (3.0 * eps * eps) + y * y / eps + eps / 3.0);
}

Vec2 ClothFriction::displacement(const Element& e, const VecX& x) const {
  Vec3 r = -e.base;
  for (int i = 0; i < 4; ++i)
    if (e.v[static_cast<size_t>(i)] < m_n)
      r += e.c[static_cast<size_t>(i)] * x.segment<3>(3 * e.v[static_cast<size_t>(i)]);
  return e.T.transpose() * r;
}

double ClothFriction::value(const VecX& x) const {
  return parallel_sum(static_cast<Index>(m_elements.size()), [&](Index k) {
    const Element& e = m_elements[static_cast<size_t>(k)];
    return element_energy(e.weight, m_eps, displacement(e, x), nullptr, nullptr);
  });
}

void ClothFriction::add_gradient(const VecX& x, VecX& g) const {
  std::vector<Vec3> ge(m_elements.size());
  parallel_for(static_cast<Index>(m_elements.size()), [&](Index k) {
    const Element& e = m_elements[static_cast<size_t>(k)];
    Vec2 gu;
    element_energy(e.weight, m_eps, displacement(e, x), &gu, nullptr);
    ge[static_cast<size_t>(k)] = e.T * gu;
  });
  // ∂u/∂x_i = c_i Tᵀ: each point gets c_i times the pair's tangential force.
  for (size_t k = 0; k < m_elements.size(); ++k) {
    const Element& e = m_elements[k];
    for (int i = 0; i < 4; ++i)
      if (e.v[static_cast<size_t>(i)] < m_n) g.segment<3>(3 * e.v[static_cast<size_t>(i)]) += e.c[static_cast<size_t>(i)] * ge[k];
  }
}

void ClothFriction::add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool /*project_psd*/) const {
  // The exact Hessian is PSD (element_energy): there is nothing to project.
  if (m_stencils_pending || m_slots.size() != m_stencils.size())
    throw_error("cloth friction: assembled before its pattern was bound (update_stencils not called)");
  std::vector<Mat3> He(m_elements.size());
  parallel_for(static_cast<Index>(m_elements.size()), [&](Index k) {
    const Element& e = m_elements[static_cast<size_t>(k)];
    Mat2 Hu;
    element_energy(e.weight, m_eps, displacement(e, x), nullptr, &Hu);
    He[static_cast<size_t>(k)] = e.T * Hu * e.T.transpose();
  });
  for (size_t k = 0; k < m_elements.size(); ++k) {
    const Element& e = m_elements[k];
    const auto& slots = m_slots[static_cast<size_t>(e.stencil)];
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        if (slots[static_cast<size_t>(4 * a + b)] >= 0)
          H.block(slots[static_cast<size_t>(4 * a + b)]) +=
              (e.c[static_cast<size_t>(a)] * e.c[static_cast<size_t>(b)]) * He[k];
  }
}

std::vector<std::array<Index, 4>> ClothFriction::stencils() const {
  std::vector<std::array<Index, 4>> out;
  out.reserve(m_elements.size());
  for (const Element& e : m_elements) out.push_back(e.v);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

void ClothFriction::collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const {
  collect_stencil_pattern(m_stencils, pairs, m_n);
}

void ClothFriction::bind(const linalg::BlockMatrix3& pattern) {
  m_slots = stencil_slots(m_stencils, pattern, "cloth friction", m_n);
}

bool ClothFriction::update_stencils(const VecX& /*x*/) {
  const bool changed = m_stencils_pending;
  m_stencils_pending = false;
  return changed;
}

void ClothFriction::start_step(const VecX& x0, const std::vector<ClothContact::ContactFrame>& frames, double h,
                               const VecX* kinematic_motion) {
  if (x0.size() != 3 * m_n) throw_error("cloth friction: x0 has {} entries for {} points", x0.size(), m_n);
  if (!(h > 0.0)) throw_error("cloth friction: step size must be positive (got {})", h);
  // The threshold is a displacement: ε_v h is how far a contact creeps in one step under static friction.
  m_eps = m_params.static_velocity * h;
  m_elements.clear();
  for (const auto& f : frames) {
    if (f.surface_a < 0 || f.surface_b < 0 || f.surface_a >= m_surfaces || f.surface_b >= m_surfaces)
      throw_error("cloth friction: a contact frame names surface {} or {} of {}", f.surface_a, f.surface_b, m_surfaces);
    const double weight = friction(f.surface_a, f.surface_b) * f.normal_force;
    if (!(weight > 0.0)) continue;  // frictionless pairs add nothing, not even to the pattern
    Element e{f.v, f.c, f.tangent, Vec3::Zero(), weight, -1};
    // A kinematic point's displacement over the step is known: it enters the base with the opposite sign, so that
    // u measures the cloth's motion relative to the obstacle's.
    for (int i = 0; i < 4; ++i) {
      const size_t a = static_cast<size_t>(i);
      const Index v = f.v[a];
      if (v < m_n) {
        e.base += f.c[a] * x0.segment<3>(3 * v);
      } else if (kinematic_motion) {
        if (3 * (v - m_n) + 3 > kinematic_motion->size())
          throw_error("cloth friction: kinematic point {} has no motion ({} coordinates)", v - m_n,
                      kinematic_motion->size());
        e.base -= f.c[a] * kinematic_motion->segment<3>(3 * (v - m_n));
      }
    }
    m_elements.push_back(e);
  }
  // The pattern changes only when the set of stencils does (the slots, per stencil, stay valid otherwise).
  auto fresh = stencils();
  if (fresh != m_stencils) {
    m_stencils = std::move(fresh);
    m_stencils_pending = true;
  }
  for (Element& e : m_elements)
    e.stencil = static_cast<Index>(std::lower_bound(m_stencils.begin(), m_stencils.end(), e.v) - m_stencils.begin());
}

}  // namespace mgcloth::physics
