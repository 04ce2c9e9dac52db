#include <mgcloth/core/error.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/sim/shell_body.hpp>

#include <Eigen/Geometry>
#include <cmath>

namespace mgcloth::sim {

namespace {

/// The corners of a quad's parameter square, in the order of its points (LimitSurface's convention).
const Vec2 kCorner[4] = {Vec2(0, 0), Vec2(1, 0), Vec2(1, 1), Vec2(0, 1)};

mesh::QuadMesh coarse_mesh(const ShellMeshSpec& m) {
  if (!m.file.empty()) return mesh::read_quad_obj(m.file, m.material_scale, m.ghost_layer);
  if (m.generator == "notched_square") return mesh::make_notched_square(m.width, m.notch, m.cells_u, m.ghost_layer);
  return mesh::make_quad_rectangle(m.width, m.height, m.cells_u, m.cells_v, m.ghost_layer);
}

}  // namespace

ShellBody::ShellBody(const ShellSpec& spec, const Vec3& gravity, const std::string& source)
    : m_spec(spec), m_source(source) {
  mesh::QuadMesh coarse = coarse_mesh(spec.mesh);
  const Transform placement{spec.translation, spec.rotation_deg};
  const Mat3 R = placement.rotation().toRotationMatrix();
  for (Index i = 0; i < coarse.num_vertices(); ++i) coarse.x.col(i) = R * coarse.x.col(i) + spec.translation;
  m_hierarchy = hierarchy::SubdivisionHierarchy(coarse, spec.level);
  m_surface = std::make_unique<mesh::LimitSurface>(m_hierarchy.finest());
  const mesh::QuadMesh& fine = m_hierarchy.finest();

  double length = 0.0;
  Index edges = 0;
  for (Index f : m_surface->real_faces())
    for (int k = 0; k < 4; ++k, ++edges) length += (fine.u.col(fine.quads[f][k]) - fine.u.col(fine.quads[f][(k + 1) % 4])).norm();
  m_h = length / static_cast<double>(edges);
  m_beta = spec.beta > 0.0 ? spec.beta : std::pow(m_h, -spec.sigma);  // §7.1: β = h^-σ

  m_objective = std::make_unique<physics::Objective>(fine.num_vertices());
  m_shell = &m_objective->add(std::make_unique<physics::ShellTerm>(*m_surface, spec.material, gravity, spec.quadrature));
  m_samples = &m_objective->add(std::make_unique<physics::ShellSampleTerm>(fine.num_vertices()));
  build_boundary();
  build_loads();
  m_objective->finalize();

  m_x = as_stacked(fine.x);
  m_v = VecX::Zero(m_x.size());
  m_display = m_surface->tessellate(spec.display_samples);
  for (const Vec2& p : spec.probes) {
    m_probe_stencils.push_back(locate(p, "probes"));
    m_probe_rest.push_back(m_probe_stencils.back().apply(fine.x, 0));
  }
}

mesh::LimitStencil ShellBody::locate(const Vec2& u, const std::string& what) const {
  Index face;
  double s, t;
  if (!m_surface->locate(u, face, s, t))
    throw InputError(fmt::format("{}: shell \"{}\": {}: material point ({}, {}) is not on the shell", m_source, name(),
                                 what, u.x(), u.y()));
  mesh::LimitStencil st;
  m_surface->stencil(face, s, t, st);
  return st;
}

std::vector<ShellBody::EdgeSample> ShellBody::edge_samples(Index face, int k) const {
  std::vector<double> z, w;
  physics::line_gauss_rule(m_spec.quadrature, z, w);
  const Vec2 a = kCorner[k], d = kCorner[(k + 1) % 4] - kCorner[k];
  std::vector<EdgeSample> out;
  for (size_t i = 0; i < z.size(); ++i) {
    EdgeSample e;
    const Vec2 p = a + z[i] * d;
    m_surface->stencil(face, p.x(), p.y(), e.stencil);
    const Mat3X& rest = m_hierarchy.finest().x;
    const Vec3 tangent = d.x() * e.stencil.apply(rest, 1) + d.y() * e.stencil.apply(rest, 2);
    e.ds = w[i] * tangent.norm();
    e.cross = k % 2 == 0 ? 2 : 1;  // edges 0, 2 run along s: across is ∂t
    out.push_back(std::move(e));
  }
  return out;
}

std::vector<std::pair<Index, int>> ShellBody::select_segments(const ShellSelection& sel, const std::string& what) const {
  const auto all = mesh::real_boundary_edges(m_hierarchy.finest());
  const Mat2X& u = m_hierarchy.finest().u;
  struct Segment {
    Vec2 a, b, mid;
  };
  std::vector<Segment> seg;
  Vec2 lo = Vec2::Constant(kInf), hi = Vec2::Constant(-kInf);
  mesh::LimitStencil st;
  for (const auto& [f, k] : all) {
    Segment s;
    m_surface->stencil(f, kCorner[k].x(), kCorner[k].y(), st);
    s.a = st.apply(u, 0);
    m_surface->stencil(f, kCorner[(k + 1) % 4].x(), kCorner[(k + 1) % 4].y(), st);
    s.b = st.apply(u, 0);
    const Vec2 m = 0.5 * (kCorner[k] + kCorner[(k + 1) % 4]);
    m_surface->stencil(f, m.x(), m.y(), st);
    s.mid = st.apply(u, 0);
    lo = lo.cwiseMin(s.a).cwiseMin(s.b);
    hi = hi.cwiseMax(s.a).cwiseMax(s.b);
    seg.push_back(s);
  }
  const double tol = 1e-6 * (hi - lo).norm();
  std::vector<char> chosen(all.size(), 0);
  for (const std::string& side : sel.sides) {
    Index n = 0;
    for (size_t i = 0; i < seg.size(); ++i) {
      const Segment& s = seg[i];
      bool on = side == "all";
      if (side == "left") on = std::abs(s.a.x() - lo.x()) < tol && std::abs(s.b.x() - lo.x()) < tol;
      if (side == "right") on = std::abs(s.a.x() - hi.x()) < tol && std::abs(s.b.x() - hi.x()) < tol;
      if (side == "bottom") on = std::abs(s.a.y() - lo.y()) < tol && std::abs(s.b.y() - lo.y()) < tol;
      if (side == "top") on = std::abs(s.a.y() - hi.y()) < tol && std::abs(s.b.y() - hi.y()) < tol;
      if (on) {
        chosen[i] = 1;
        ++n;
      }
    }
    if (n == 0) throw InputError(fmt::format("{}: shell \"{}\": {}: side \"{}\" has no boundary segment", m_source, name(), what, side));
  }
  if (sel.region) {
    Index n = 0;
    for (size_t i = 0; i < seg.size(); ++i)
      if ((seg[i].mid.array() >= sel.region->first.array() - tol).all() &&
          (seg[i].mid.array() <= sel.region->second.array() + tol).all()) {
        chosen[i] = 1;
        ++n;
      }
    if (n == 0) throw InputError(fmt::format("{}: shell \"{}\": {}: the region selects no boundary segment", m_source, name(), what));
  }
  std::vector<std::pair<Index, int>> out;
  for (size_t i = 0; i < all.size(); ++i)
    if (chosen[i]) out.push_back(all[i]);
  return out;
}

void ShellBody::build_boundary() {
  const Mat3X& rest = m_hierarchy.finest().x;
  const auto stencil_sample = [](const mesh::LimitStencil& st, int column, double c, const Vec3& b) {
    physics::ShellSample s;
    for (Index k = 0; k < st.size(); ++k) {
      if (st.w(k, column) == 0.0) continue;
      s.points.push_back(st.points[k]);
      s.w.push_back(st.w(k, column));
    }
    s.c = c;
    s.b = b;
    return s;
  };
  for (size_t i = 0; i < m_spec.boundary.size(); ++i) {
    const ShellBoundarySpec& bc = m_spec.boundary[i];
    const std::string what = fmt::format("boundary[{}]", i);
    for (const auto& [f, k] : select_segments(bc.where, what))
      for (const EdgeSample& e : edge_samples(f, k)) {
        const Vec3 b = e.stencil.apply(rest, 0);
        const Index s = m_samples->add(stencil_sample(e.stencil, 0, m_beta * e.ds, b));
        m_targets.push_back({s, b, bc.displacement, bc.ramp_time});
        // Clamped: the derivative across the boundary held too, so the tangent plane stays (eq. 3.6 on x,n).
        if (bc.type == "clamped") m_samples->add(stencil_sample(e.stencil, e.cross, m_beta * e.ds, e.stencil.apply(rest, e.cross)));
      }
    for (const Vec2& p : bc.where.points) {
      const mesh::LimitStencil st = locate(p, what);
      const Vec3 b = st.apply(rest, 0);
      const Index s = m_samples->add(stencil_sample(st, 0, m_beta, b));
      m_targets.push_back({s, b, bc.displacement, bc.ramp_time});
      if (bc.type == "clamped")
        for (int d : {1, 2}) m_samples->add(stencil_sample(st, d, m_beta, st.apply(rest, d)));
    }
    for (Index v : bc.where.control_points) {
      if (v < 0 || v >= rest.cols())
        throw InputError(fmt::format("{}: shell \"{}\": {}: control point {} out of range (level {} has {})", m_source,
                                     name(), what, v, m_spec.level, rest.cols()));
      physics::ShellSample s;
      s.points = {v};
      s.w = {1.0};
      s.c = m_beta;
      s.b = rest.col(v);
      m_targets.push_back({m_samples->add(s), rest.col(v), bc.displacement, bc.ramp_time});
    }
  }
}

void ShellBody::build_loads() {
  const Mat3X& rest = m_hierarchy.finest().x;
  const auto load_sample = [&](const mesh::LimitStencil& st, const Vec3& f, double ramp_time) {
    physics::ShellSample s;
    for (Index k = 0; k < st.size(); ++k) {
      if (st.w(k, 0) == 0.0) continue;
      s.points.push_back(st.points[k]);
      s.w.push_back(st.w(k, 0));
    }
    m_loads.push_back({m_samples->add(s), Vec3::Zero(), f, ramp_time});
  };
  for (size_t i = 0; i < m_spec.loads.size(); ++i) {
    const ShellLoadSpec& l = m_spec.loads[i];
    const std::string what = fmt::format("loads[{}]", i);
    if (l.type == "point") {
      for (const Vec2& p : l.where.points) load_sample(locate(p, what), l.force, l.ramp_time);
    } else if (l.type == "edge") {
      for (const auto& [f, k] : select_segments(l.where, what))
        for (const EdgeSample& e : edge_samples(f, k)) load_sample(e.stencil, e.ds * l.force, l.ramp_time);
    } else {
      // Pressure as a dead load along the reference normal: f = p n̄ dĀ at each Gauss point.
      std::vector<Vec2> pts;
      std::vector<double> wts;
      physics::square_gauss_rule(m_spec.quadrature, pts, wts);
      mesh::LimitStencil st;
      for (Index f : m_surface->real_faces())
        for (size_t g = 0; g < pts.size(); ++g) {
          m_surface->stencil(f, pts[g].x(), pts[g].y(), st);
          const Vec3 m = st.apply(rest, 1).cross(st.apply(rest, 2));
          load_sample(st, wts[g] * l.pressure * m, l.ramp_time);
        }
    }
  }
}

double ShellBody::factor(double t, double ramp_time, bool is_static, double load_factor) {
  if (is_static) return load_factor;
  return ramp_time > 0.0 ? std::min(1.0, t / ramp_time) : 1.0;
}

VecX ShellBody::prepare_step(double t_next, double h, double load_factor) {
  const bool stat = is_static();
  for (const Driven& d : m_targets) m_samples->set_target(d.sample, d.rest + factor(t_next, d.ramp_time, stat, load_factor) * d.vector);
  for (const Driven& d : m_loads) m_samples->set_load(d.sample, factor(t_next, d.ramp_time, stat, load_factor) * d.vector);
  if (stat) {
    m_shell->set_inertia(0.0, m_x);
    m_shell->set_gravity_scale(load_factor);
    return m_x;
  }
  const VecX y = m_x + h * m_v;
  m_shell->set_inertia(h, y);
  m_shell->set_gravity_scale(1.0);
  // The solve starts from the last state, not from the prediction y: at dt = 1 s, y = x + h v overshoots by the
  // whole step's motion and can land in a crumpled or nearly degenerate state, from which the trust region
  // crawls (the Drape at level 1 took > 10^4 iterations from y and converges from x).
  return m_x;
}

void ShellBody::finish_step(const VecX& x_new, double h) {
  if (is_static() || !(h > 0.0)) {
    m_v.setZero();
  } else {
    m_v = (x_new - m_x) / h;
  }
  m_x = x_new;
}

std::vector<ProbeReading> ShellBody::probes() const {
  std::vector<ProbeReading> out;
  const Mat3X q = as_columns(m_x);
  for (size_t i = 0; i < m_probe_stencils.size(); ++i) {
    const Vec3 x = m_probe_stencils[i].apply(q, 0);
    out.push_back({m_spec.probes[i], x, x - m_probe_rest[i]});
  }
  return out;
}

}  // namespace mgcloth::sim
