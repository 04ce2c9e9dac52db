#include <mgcloth/core/error.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/bodies/cloth_spec.hpp>
#include <mgcloth/bodies/shell_body.hpp>

#include <Eigen/Geometry>
#include <algorithm>
#include <map>
#include <cmath>

namespace mgcloth::bodies {

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
    : m_spec(spec), m_source(source), m_gravity(gravity) {
  mesh::QuadMesh coarse = coarse_mesh(spec.mesh);
  const Transform placement{spec.translation, spec.rotation_deg};
  const Mat3 R = placement.rotation().toRotationMatrix();
  for (Index i = 0; i < coarse.num_vertices(); ++i) coarse.x.col(i) = R * coarse.x.col(i) + spec.translation;
  m_hierarchy = hierarchy::SubdivisionHierarchy(coarse, spec.level);
  const int L = m_hierarchy.num_levels();
  m_levels.resize(static_cast<size_t>(L));
  m_reverse.resize(static_cast<size_t>(L));
  m_reverse_tried.assign(static_cast<size_t>(L), 0);
  m_lsq.resize(static_cast<size_t>(L));
  m_levels.back() = build_level(L - 1);
  const mesh::QuadMesh& fine = m_hierarchy.finest();

  m_x = as_stacked(fine.x);
  m_v = VecX::Zero(m_x.size());
  m_display = surface().tessellate(spec.display_samples);
  for (const Vec2& p : spec.probes) {
    m_probe_stencils.push_back(locate(finest(), p, "probes"));
    m_probe_rest.push_back(m_probe_stencils.back().apply(fine.x, 0));
  }
}

ShellBody::~ShellBody() = default;

std::unique_ptr<ShellBody::Level> ShellBody::build_level(int index) const {
  auto lv = std::make_unique<Level>();
  lv->index = index;
  const mesh::QuadMesh& m = m_hierarchy.mesh(index);
  lv->surface = std::make_unique<mesh::LimitSurface>(m);
  double length = 0.0;
  Index edges = 0;
  for (Index f : lv->surface->real_faces())
    for (int k = 0; k < 4; ++k, ++edges) length += (m.u.col(m.quads[f][k]) - m.u.col(m.quads[f][(k + 1) % 4])).norm();
  lv->h = length / static_cast<double>(edges);
  // §7.1: β = h^-σ with h the finest mesh size. β is part of the problem (3.6), not of its discretization: the
  // coarse levels rediscretize the same penalty. (With each level's own h, β drops 2^σ = 32-fold per level, the
  // coarse models let the boundary move, and RMTR rejected every coarse correction of the Trampoline: ρ < 0.)
  const double h_finest = index == m_hierarchy.num_levels() - 1 ? lv->h : finest().h;
  lv->beta = m_spec.beta > 0.0 ? m_spec.beta : std::pow(h_finest, -m_spec.sigma);
  lv->objective = std::make_unique<physics::Objective>(m.num_vertices());
  lv->shell = &lv->objective->add(std::make_unique<physics::ShellTerm>(*lv->surface, m_spec.material, m_gravity, m_spec.quadrature));
  lv->samples = &lv->objective->add(std::make_unique<physics::ShellSampleTerm>(m.num_vertices()));
  // Boundary conditions and loads are sampled where the finest level samples them and restricted through the
  // composed S: they are linear in the control points, so a coarse state is then held exactly as its prolongation
  // would be. (Sampled on the coarse surface itself, a coarse solution could bend its held edges between the few
  // coarse samples; the Re-entrant corner's coarsest solution then cost 1.3 J of penalty once prolongated, and
  // nested iteration had to discard it.)
  const bool finest_level = index == m_hierarchy.num_levels() - 1;
  build_boundary(finest_level ? *lv : finest(), *lv);
  build_loads(finest_level ? *lv : finest(), *lv);
  lv->objective->finalize();
  return lv;
}

physics::Objective& ShellBody::level_objective(int level) {
  if (level < 0 || level >= num_levels())
    throw_error("shell \"{}\": level {} out of range (the hierarchy has {})", name(), level, num_levels());
  // Built from the finest down, so that prepare_step() can project its state level by level.
  VecX x = m_x, y = m_y;
  for (int l = num_levels() - 2; l >= level; --l) {
    auto& lv = m_levels[static_cast<size_t>(l)];
    if (lv && !m_prepared) continue;
    if (m_prepared) {
      VecX xc, yc;
      project(l, x, xc);
      project(l, y, yc);
      x.swap(xc);
      y.swap(yc);
    }
    if (lv) continue;
    lv = build_level(l);
    // Join the current step: this level's state and inertial prediction from the finest one's.
    if (m_prepared) prepare_level(*lv, m_t_next, m_step_h, m_load_factor, x, y);
  }
  return *m_levels[static_cast<size_t>(level)]->objective;
}

const linalg::StencilTable* ShellBody::reverse_subdivision(int level) {
  if (level < 0 || level + 1 >= num_levels())
    throw_error("shell \"{}\": no projection from level {} (the hierarchy has {})", name(), level + 1, num_levels());
  const size_t l = static_cast<size_t>(level);
  if (!m_reverse_tried[l]) {
    m_reverse_tried[l] = 1;
    try {
      m_reverse[l] = std::make_unique<linalg::StencilTable>(
          hierarchy::reverse_subdivision(m_hierarchy.mesh(level), m_hierarchy.step(level)));
    } catch (const Error& e) {
      logger().info("shell \"{}\": level {}: no reverse subdivision ({}); iterates are projected by least squares",
                    name(), level, e.what());
    }
  }
  return m_reverse[l].get();
}

const hierarchy::LeastSquaresProjection& ShellBody::least_squares(int level) {
  if (level < 0 || level + 1 >= num_levels())
    throw_error("shell \"{}\": no projection from level {} (the hierarchy has {})", name(), level + 1, num_levels());
  auto& p = m_lsq[static_cast<size_t>(level)];
  if (!p) p = std::make_unique<hierarchy::LeastSquaresProjection>(m_hierarchy.subdivision(level));
  return *p;
}

const std::vector<std::vector<Index>>& ShellBody::patches(int level) {
  if (level < 0 || level >= num_levels())
    throw_error("shell \"{}\": level {} out of range (the hierarchy has {})", name(), level, num_levels());
  if (m_patches.size() != static_cast<size_t>(num_levels())) m_patches.resize(static_cast<size_t>(num_levels()));
  auto& out = m_patches[static_cast<size_t>(level)];
  if (out.empty()) {
    const mesh::QuadMesh& m = m_hierarchy.mesh(level);
    out.assign(static_cast<size_t>(m.num_vertices()), {});
    for (const auto& q : m.quads)
      for (Index v : q) out[static_cast<size_t>(v)].insert(out[static_cast<size_t>(v)].end(), q.begin(), q.end());
    for (Index v = 0; v < m.num_vertices(); ++v) {
      auto& p = out[static_cast<size_t>(v)];
      p.push_back(v);
      std::sort(p.begin(), p.end());
      p.erase(std::unique(p.begin(), p.end()), p.end());
    }
  }
  return out;
}

void ShellBody::project(int level, const VecX& fine, VecX& coarse) {
  if (const auto* q = reverse_subdivision(level)) {
    q->apply(fine, coarse);
  } else {
    least_squares(level).apply(fine, coarse);
  }
}

std::vector<std::pair<Index, double>> ShellBody::control_point_on_level(Index v, int level) const {
  std::vector<std::pair<Index, double>> row{{v, 1.0}};
  for (int l = num_levels() - 2; l >= level; --l) {
    const linalg::StencilTable& S = m_hierarchy.subdivision(l);
    std::vector<std::pair<Index, double>> next;
    for (const auto& [i, w] : row)
      for (Index k = S.offsets[i]; k < S.offsets[i + 1]; ++k) {
        auto it = std::find_if(next.begin(), next.end(), [&](const auto& e) { return e.first == S.indices[k]; });
        if (it == next.end()) next.push_back({S.indices[k], w * S.weights[k]});
        else it->second += w * S.weights[k];
      }
    row.swap(next);
  }
  return row;
}

mesh::LimitStencil ShellBody::locate(const Level& lv, const Vec2& u, const std::string& what) const {
  Index face;
  double s, t;
  if (!lv.surface->locate(u, face, s, t))
    throw InputError(fmt::format("{}: shell \"{}\": {}: material point ({}, {}) is not on the shell", m_source, name(),
                                 what, u.x(), u.y()));
  mesh::LimitStencil st;
  lv.surface->stencil(face, s, t, st);
  return st;
}

std::vector<ShellBody::EdgeSample> ShellBody::edge_samples(const Level& lv, Index face, int k) const {
  std::vector<double> z, w;
  physics::line_gauss_rule(m_spec.quadrature, z, w);
  const Vec2 a = kCorner[k], d = kCorner[(k + 1) % 4] - kCorner[k];
  std::vector<EdgeSample> out;
  for (size_t i = 0; i < z.size(); ++i) {
    EdgeSample e;
    const Vec2 p = a + z[i] * d;
    lv.surface->stencil(face, p.x(), p.y(), e.stencil);
    const Mat3X& rest = lv.mesh(*this).x;
    const Vec3 tangent = d.x() * e.stencil.apply(rest, 1) + d.y() * e.stencil.apply(rest, 2);
    e.ds = w[i] * tangent.norm();
    e.cross = k % 2 == 0 ? 2 : 1;  // edges 0, 2 run along s: across is ∂t
    out.push_back(std::move(e));
  }
  return out;
}

std::vector<std::pair<Index, int>> ShellBody::select_segments(const Level& lv, const ShellSelection& sel,
                                                              const std::string& what) const {
  const auto all = mesh::real_boundary_edges(lv.mesh(*this));
  const Mat2X& u = lv.mesh(*this).u;
  struct Segment {
    Vec2 a, b, mid;
  };
  std::vector<Segment> seg;
  Vec2 lo = Vec2::Constant(kInf), hi = Vec2::Constant(-kInf);
  mesh::LimitStencil st;
  for (const auto& [f, k] : all) {
    Segment s;
    lv.surface->stencil(f, kCorner[k].x(), kCorner[k].y(), st);
    s.a = st.apply(u, 0);
    lv.surface->stencil(f, kCorner[(k + 1) % 4].x(), kCorner[(k + 1) % 4].y(), st);
    s.b = st.apply(u, 0);
    const Vec2 m = 0.5 * (kCorner[k] + kCorner[(k + 1) % 4]);
    lv.surface->stencil(f, m.x(), m.y(), st);
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

physics::ShellSample ShellBody::sample_on(const Level& geo, const Level& lv, const mesh::LimitStencil& st, int column,
                                          std::map<Index, std::vector<std::pair<Index, double>>>& rows) const {
  physics::ShellSample s;
  if (geo.index == lv.index) {
    for (Index k = 0; k < st.size(); ++k) {
      if (st.w(k, column) == 0.0) continue;
      s.points.push_back(st.points[k]);
      s.w.push_back(st.w(k, column));
    }
    return s;
  }
  std::map<Index, double> combined;
  for (Index k = 0; k < st.size(); ++k) {
    if (st.w(k, column) == 0.0) continue;
    auto it = rows.find(st.points[k]);
    if (it == rows.end()) it = rows.emplace(st.points[k], control_point_on_level(st.points[k], lv.index)).first;
    for (const auto& [i, w] : it->second) combined[i] += st.w(k, column) * w;
  }
  for (const auto& [i, w] : combined) {
    s.points.push_back(i);
    s.w.push_back(w);
  }
  return s;
}

void ShellBody::build_boundary(const Level& geo, Level& lv) const {
  const Mat3X& rest = geo.mesh(*this).x;
  const double beta = lv.beta;
  std::map<Index, std::vector<std::pair<Index, double>>> rows;
  const auto stencil_sample = [&](const mesh::LimitStencil& st, int column, double c, const Vec3& b) {
    physics::ShellSample s = sample_on(geo, lv, st, column, rows);
    s.c = c;
    s.b = b;
    return s;
  };
  for (size_t i = 0; i < m_spec.boundary.size(); ++i) {
    const ShellBoundarySpec& bc = m_spec.boundary[i];
    const std::string what = fmt::format("boundary[{}]", i);
    for (const auto& [f, k] : select_segments(geo, bc.where, what))
      for (const EdgeSample& e : edge_samples(geo, f, k)) {
        const Vec3 b = e.stencil.apply(rest, 0);
        const Index s = lv.samples->add(stencil_sample(e.stencil, 0, beta * e.ds, b));
        lv.targets.push_back({s, b, bc.displacement, bc.ramp_time});
        // Clamped: the derivative across the boundary held too, so the tangent plane stays (eq. 3.6 on x,n).
        if (bc.type == "clamped") lv.samples->add(stencil_sample(e.stencil, e.cross, beta * e.ds, e.stencil.apply(rest, e.cross)));
      }
    for (const Vec2& p : bc.where.points) {
      const mesh::LimitStencil st = locate(geo, p, what);
      const Vec3 b = st.apply(rest, 0);
      const Index s = lv.samples->add(stencil_sample(st, 0, beta, b));
      lv.targets.push_back({s, b, bc.displacement, bc.ramp_time});
      if (bc.type == "clamped")
        for (int d : {1, 2}) lv.samples->add(stencil_sample(st, d, beta, st.apply(rest, d)));
    }
    const Mat3X& finest_rest = m_hierarchy.finest().x;
    for (Index v : bc.where.control_points) {
      if (v < 0 || v >= finest_rest.cols())
        throw InputError(fmt::format("{}: shell \"{}\": {}: control point {} out of range (level {} has {})", m_source,
                                     name(), what, v, m_spec.level, finest_rest.cols()));
      // On a coarse level the finest control point is the combination of coarse ones that subdivision makes it.
      physics::ShellSample s;
      for (const auto& [i, w] : control_point_on_level(v, lv.index)) {
        s.points.push_back(i);
        s.w.push_back(w);
      }
      s.c = beta;
      s.b = finest_rest.col(v);
      lv.targets.push_back({lv.samples->add(s), finest_rest.col(v), bc.displacement, bc.ramp_time});
    }
  }
}

void ShellBody::build_loads(const Level& geo, Level& lv) const {
  const Mat3X& rest = geo.mesh(*this).x;
  std::map<Index, std::vector<std::pair<Index, double>>> rows;
  const auto load_sample = [&](const mesh::LimitStencil& st, const Vec3& f, double ramp_time) {
    lv.loads.push_back({lv.samples->add(sample_on(geo, lv, st, 0, rows)), Vec3::Zero(), f, ramp_time});
  };
  for (size_t i = 0; i < m_spec.loads.size(); ++i) {
    const ShellLoadSpec& l = m_spec.loads[i];
    const std::string what = fmt::format("loads[{}]", i);
    if (l.type == "point") {
      for (const Vec2& p : l.where.points) load_sample(locate(geo, p, what), l.force, l.ramp_time);
    } else if (l.type == "edge") {
      for (const auto& [f, k] : select_segments(geo, l.where, what))
        for (const EdgeSample& e : edge_samples(geo, f, k)) load_sample(e.stencil, e.ds * l.force, l.ramp_time);
    } else {
      // Pressure as a dead load along the reference normal: f = p n̄ dĀ at each Gauss point.
      std::vector<Vec2> pts;
      std::vector<double> wts;
      physics::square_gauss_rule(m_spec.quadrature, pts, wts);
      mesh::LimitStencil st;
      for (Index f : geo.surface->real_faces())
        for (size_t g = 0; g < pts.size(); ++g) {
          geo.surface->stencil(f, pts[g].x(), pts[g].y(), st);
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

void ShellBody::prepare_level(Level& lv, double t_next, double h, double load_factor, const VecX& x, const VecX& y) {
  const bool stat = is_static();
  for (const Driven& d : lv.targets) lv.samples->set_target(d.sample, d.rest + factor(t_next, d.ramp_time, stat, load_factor) * d.vector);
  for (const Driven& d : lv.loads) lv.samples->set_load(d.sample, factor(t_next, d.ramp_time, stat, load_factor) * d.vector);
  if (stat) {
    lv.shell->set_inertia(0.0, x);
    lv.shell->set_gravity_scale(load_factor);
  } else {
    lv.shell->set_inertia(h, y);
    lv.shell->set_gravity_scale(1.0);
  }
}

VecX ShellBody::prepare_step(double t_next, double h, double load_factor) {
  m_t_next = t_next;
  m_step_h = h;
  m_load_factor = load_factor;
  m_prepared = true;
  m_y = is_static() ? m_x : VecX(m_x + h * m_v);
  VecX x = m_x, y = m_y;
  for (int l = num_levels() - 1; l >= 0; --l) {
    if (l < num_levels() - 1) {
      if (!m_levels[static_cast<size_t>(l)]) break;  // coarse levels are built from the finest down
      VecX xc, yc;
      project(l, x, xc);
      project(l, y, yc);
      x.swap(xc);
      y.swap(yc);
    }
    if (m_levels[static_cast<size_t>(l)]) prepare_level(*m_levels[static_cast<size_t>(l)], t_next, h, load_factor, x, y);
  }
  // The solve starts from the last state, not from the prediction y: at dt = 1 s, y = x + h v overshoots by the
  // whole step's motion and can land in a crumpled or nearly degenerate state, from which the trust region
  // crawls (the Drape at level 1 took > 10^4 iterations from y and converges from x).
  return m_x;
}

std::string ShellBody::size_text() const { return fmt::format("{} control points", m_x.size() / 3); }

void ShellBody::finish_step(VecX& x_new, double h) {
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

hierarchy::Hierarchy ShellBody::solver_hierarchy(bool rediscretized) {
  const int L = num_levels();
  hierarchy::Hierarchy h;
  for (int k = 0; k < L; ++k) {
    const int level = L - 1 - k;
    hierarchy::Hierarchy::Level lv;
    lv.num_points = m_hierarchy.mesh(level).num_vertices();
    if (level > 0) lv.prolongation = &m_hierarchy.subdivision(level - 1);
    if (rediscretized) {
      lv.objective = &level_objective(level);
      lv.patches = &patches(level);
      if (level > 0) {
        lv.project = [this, level](const VecX& fine, VecX& coarse) { project(level - 1, fine, coarse); };
        lv.project_lsq = [this, level](const VecX& fine, VecX& coarse) { least_squares(level - 1).apply(fine, coarse); };
      }
    }
    h.levels.push_back(std::move(lv));
  }
  if (!rediscretized) h.levels[0].objective = &objective();
  return h;
}

}  // namespace mgcloth::bodies
