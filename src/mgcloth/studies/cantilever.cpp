#include <mgcloth/studies/cantilever.hpp>

#include <mgcloth/core/error.hpp>

#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/attachment.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/inertia.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/solvers/newton.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>

namespace mgcloth::studies {

namespace {
constexpr int kSteps = 4000;  // RK4 steps along the strip: the shooting error is far below 1e-6 of the deflection

struct Shot {
  double end_slope_rate = 0.0;  // θ'(L)
  std::vector<double> z;        // deflection at the grid points s_i = i L / kSteps
};

// y = (θ, θ', x, z), θ below the horizontal, z the drop; y' = (θ', −(w/B)(L − s) cos θ, cos θ, sin θ).
Shot shoot(double kappa0, double a, double L) {
  using Y = std::array<double, 4>;
  const auto f = [&](double s, const Y& y) {
    return Y{y[1], -a * (L - s) * std::cos(y[0]), std::cos(y[0]), std::sin(y[0])};
  };
  const double ds = L / kSteps;
  Y y{0.0, kappa0, 0.0, 0.0};
  Shot out;
  out.z.reserve(kSteps + 1);
  out.z.push_back(0.0);
  for (int i = 0; i < kSteps; ++i) {
    const double s = i * ds;
    const auto add = [](const Y& p, const Y& q, double h) { return Y{p[0] + h * q[0], p[1] + h * q[1], p[2] + h * q[2], p[3] + h * q[3]}; };
    const Y k1 = f(s, y), k2 = f(s + ds / 2, add(y, k1, ds / 2)), k3 = f(s + ds / 2, add(y, k2, ds / 2)),
            k4 = f(s + ds, add(y, k3, ds));
    for (int c = 0; c < 4; ++c) y[c] += ds / 6 * (k1[c] + 2 * k2[c] + 2 * k3[c] + k4[c]);
    out.z.push_back(y[3]);
  }
  out.end_slope_rate = y[1];
  return out;
}

double interpolate(const std::vector<double>& z, double L, double s) {
  const double p = std::clamp(s / L, 0.0, 1.0) * kSteps;
  const int i = std::min(kSteps - 1, static_cast<int>(p));
  const double t = p - i;
  return (1 - t) * z[i] + t * z[i + 1];
}
// The triangles whose material centroid passes `keep`, with the vertices they use renumbered in order. Vertices
// where the cut left two triangle fans touching at one point carry more than two boundary edges: the triangles there
// are dropped until the strip is a manifold disc.
template <class Keep>
mesh::TriMesh keep_triangles(const Mat2X& u, const std::vector<Tri>& tris, Keep&& keep) {
  std::vector<Tri> kept;
  for (const Tri& t : tris)
    if (keep(Vec2((u.col(t[0]) + u.col(t[1]) + u.col(t[2])) / 3.0))) kept.push_back(t);
  for (bool changed = true; changed;) {
    changed = false;
    std::map<std::pair<Index, Index>, int> count;
    for (const Tri& t : kept)
      for (int k = 0; k < 3; ++k) ++count[std::minmax(t[k], t[(k + 1) % 3])];
    std::map<Index, int> boundary_edges;
    for (const auto& [e, n] : count)
      if (n == 1) ++boundary_edges[e.first], ++boundary_edges[e.second];
    std::vector<Tri> next;
    for (const Tri& t : kept) {
      const bool pinched = boundary_edges[t[0]] > 2 || boundary_edges[t[1]] > 2 || boundary_edges[t[2]] > 2;
      if (pinched) changed = true;
      else next.push_back(t);
    }
    kept.swap(next);
  }
  std::vector<Index> id(u.cols(), -1);
  Index n = 0;
  for (Tri& t : kept)
    for (Index& v : t) {
      if (id[v] < 0) id[v] = n++;
      v = id[v];
    }
  mesh::TriMesh out;
  out.u.resize(2, n);
  for (Index i = 0; i < u.cols(); ++i)
    if (id[i] >= 0) out.u.col(id[i]) = u.col(i);
  out.tris = std::move(kept);
  return out;
}
}  // namespace

std::vector<double> elastica_deflection(double B, double w, double L, const std::vector<double>& s) {
  const double a = w / B;
  // θ'(L) rises with θ'(0): negative at 0 (the strip would curl up), non-negative at the linear theory's a L²/2,
  // which cos θ ≤ 1 makes an upper bound.
  double lo = 0.0, hi = a * L * L / 2;
  for (int it = 0; it < 200 && hi - lo > 1e-15 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (shoot(mid, a, L).end_slope_rate < 0.0 ? lo : hi) = mid;
  }
  const Shot shot = shoot(0.5 * (lo + hi), a, L);
  std::vector<double> out(s.size());
  for (size_t i = 0; i < s.size(); ++i) out[i] = interpolate(shot.z, L, s[i]);
  return out;
}

double elastica_rigidity(double mean_drop, double w, double L, const std::vector<double>& s) {
  const auto mean = [&](double B) {
    const auto z = elastica_deflection(B, w, L, s);
    double sum = 0.0;
    for (double v : z) sum += v;
    return sum / static_cast<double>(z.size());
  };
  // The drop falls as B rises; bracket from the linear theory's B = w L⁴ / (8 drop), then bisect in log B.
  double lo = w * std::pow(L, 4) / (8.0 * mean_drop) / 64.0, hi = lo * 4096.0;
  for (int it = 0; it < 100; ++it) {
    const double mid = std::sqrt(lo * hi);
    (mean(mid) > mean_drop ? lo : hi) = mid;
    if (hi / lo - 1.0 < 1e-9) break;
  }
  return std::sqrt(lo * hi);
}

Strip make_strip(bool unstructured, double angle_deg, Index vertices, double length, double width) {
  Strip out;
  out.length = length;
  out.width = width;
  mesh::RectangleSpec spec;
  spec.unstructured = unstructured;
  if (angle_deg == 0.0 || angle_deg == 90.0) {
    const bool along_v = angle_deg == 90.0;
    spec.width = along_v ? width : length;
    spec.height = along_v ? length : width;
    spec.target_vertices = vertices;
    out.mesh = mesh::make_rectangle(spec);
    if (along_v)  // rotate by −90°: (u, v) → (v, width − u), so the strip runs along s
      for (Index i = 0; i < out.mesh.u.cols(); ++i)
        out.mesh.u.col(i) = Vec2(out.mesh.u(1, i), width - out.mesh.u(0, i));
  } else {
    // Cut from a rectangle whose axes are turned by angle_deg against the strip: the generator's rectangle, covering
    // the strip's bounding box, rotated about its centre; a triangle is kept when its centroid lies in the strip.
    const double c = std::cos(angle_deg * std::numbers::pi / 180), sn = std::sin(angle_deg * std::numbers::pi / 180);
    const double side = (length + width) * 1.02;
    const double density = vertices / (length * width);
    spec.width = spec.height = side;
    spec.target_vertices = static_cast<Index>(density * side * side);
    mesh::TriMesh big = mesh::make_rectangle(spec);
    const Vec2 centre(side / 2, side / 2), strip_centre(length / 2, width / 2);
    Mat2X u(2, big.u.cols());
    for (Index i = 0; i < big.u.cols(); ++i) {
      const Vec2 d = big.u.col(i) - centre;
      u.col(i) = strip_centre + Vec2(c * d.x() + sn * d.y(), -sn * d.x() + c * d.y());
    }
    out.mesh = keep_triangles(u, big.tris, [&](const Vec2& m) {
      return m.x() >= 0 && m.x() <= length && m.y() >= 0 && m.y() <= width;
    });
  }
  out.mesh.x.resize(3, out.mesh.u.cols());
  out.mesh.x.topRows(2) = out.mesh.u;
  out.mesh.x.row(2).setZero();
  mesh::validate(out.mesh, "strip");
  return out;
}

Mat3X hang_strip(const Strip& strip, const physics::Material& material, double clamp) {
  const mesh::TriMesh& m = strip.mesh;
  const mesh::Topology topo = mesh::build_topology(m);
  const Index n = m.num_vertices();
  VecX mass = VecX::Zero(n);
  for (Index t = 0; t < m.num_triangles(); ++t)
    for (Index v : m.tris[t]) mass[v] += std::abs(m.material_area(t)) / 3.0 * material.areal_density();
  physics::Objective obj(n);
  obj.add(std::make_unique<physics::GravityTerm>(mass, Vec3(0, 0, -9.81)));
  obj.add(std::make_unique<physics::StVKMembrane>(m, material));
  if (auto bending = physics::make_bending(m, topo, material, false)) obj.add(std::move(bending));
  std::vector<Index> pinned;
  std::vector<Vec3> targets;
  for (Index i = 0; i < n; ++i)
    if (m.u(0, i) <= clamp) pinned.push_back(i), targets.push_back(m.x.col(i));
  if (pinned.empty()) throw Error("hang_strip: no vertex in the clamp");
  // Stiff enough that the clamp does not turn: the pins hold the bending moment at the clamp line as forces ~M/h on
  // vertices h apart, and at 1e9 x the weight (the clamp moving ~1e-9 m) that turning softened a strip by 1.3% at
  // 12,000 vertices and by 8% at L/c = 0.5 (bench/RESULTS.md, "Bending rigidity").
  const double k = 1e13 * material.areal_density() * 9.81 * strip.length * strip.width / pinned.size();
  auto& pins = obj.add(std::make_unique<physics::AttachmentTerm>(pinned, std::vector<double>(pinned.size(), k), n));
  pins.set_targets(targets);
  obj.finalize();

  solvers::Newton newton;
  solvers::Problem problem;
  problem.objective = &obj;
  VecX x = m.x.reshaped();
  solvers::Stop stop;
  stop.rel_grad = 1e-10;
  stop.max_iters = 2000;
  const auto rep = newton.minimize(problem, x, stop, nullptr);
  if (!rep.converged && rep.status != "stalled" && rep.status != "stagnated")
    throw Error(fmt::format("hang_strip: Newton ended {} after {} iterations, relative gradient {:.3e}", rep.status,
                            rep.iterations, rep.grad_norm / rep.initial_grad_norm));
  return x.reshaped(3, n);
}

Strip truncate_strip(const Strip& strip, double length) {
  Strip out;
  out.length = length;
  out.width = strip.width;
  out.mesh = keep_triangles(strip.mesh.u, strip.mesh.tris, [&](const Vec2& m) { return m.x() <= length; });
  out.mesh.x.resize(3, out.mesh.u.cols());
  out.mesh.x.topRows(2) = out.mesh.u;
  out.mesh.x.row(2).setZero();
  mesh::validate(out.mesh, "truncated strip");
  return out;
}

namespace {
// Mean drop of the vertices within `tip` of the strip's free end, and their arc lengths from s = 0.
double tip_drop(const Strip& strip, const Mat3X& x, double tip, std::vector<double>& s) {
  s.clear();
  double drop = 0.0;
  for (Index i = 0; i < strip.mesh.u.cols(); ++i)
    if (strip.mesh.u(0, i) >= strip.length - tip) {
      s.push_back(strip.mesh.u(0, i));
      drop += -x(2, i);
    }
  return drop / static_cast<double>(s.size());
}

double mean_edge_length(const mesh::TriMesh& m) {
  double sum = 0.0;
  for (const Tri& t : m.tris)
    for (int k = 0; k < 3; ++k) sum += (m.u.col(t[(k + 1) % 3]) - m.u.col(t[k])).norm();
  return sum / (3.0 * static_cast<double>(m.tris.size()));
}

// The elastica's rigidity for a drop when the strip is clamped at s = at: arc lengths are measured from there.
double rigidity_clamped_at(double at, double drop, double w, double length, std::vector<double> s) {
  for (double& v : s) v = std::max(0.0, v - at);
  return elastica_rigidity(drop, w, length - at, s);
}
}  // namespace

CantileverResult cantilever(const Strip& strip, const physics::Material& material, double clamp, double tip) {
  const double w = material.areal_density() * 9.81;
  const Strip half = truncate_strip(strip, clamp + 0.5 * (strip.length - clamp));
  std::vector<double> s_long, s_short;
  const double drop_long = tip_drop(strip, hang_strip(strip, material, clamp), tip, s_long);
  const double drop_short = tip_drop(half, hang_strip(half, material, clamp), tip, s_short);

  CantileverResult r;
  r.edge_length = mean_edge_length(strip.mesh);
  r.drop = drop_long;
  {
    std::vector<double> s = s_long;
    for (double& v : s) v -= clamp;
    for (double v : elastica_deflection(material.bending_stiffness, w, strip.length - clamp, s))
      r.elastica_drop += v / static_cast<double>(s.size());
  }
  r.rigidity_at_pins = rigidity_clamped_at(clamp, drop_long, w, strip.length, s_long);
  // Where the clamp acts is a boundary effect of the discretization, within about an edge of the last pinned
  // vertices; a rigidity is a property of the bulk. The two overhangs share the clamp's mesh, so one clamp position
  // c* explains both drops with one B: B_long(c*) = B_short(c*). The short overhang's B falls faster as c* grows.
  const auto mismatch = [&](double at) {
    return rigidity_clamped_at(at, drop_short, w, half.length, s_short) -
           rigidity_clamped_at(at, drop_long, w, strip.length, s_long);
  };
  double lo = clamp - 3.0 * r.edge_length, hi = clamp + 3.0 * r.edge_length;
  if (mismatch(lo) < 0.0 || mismatch(hi) > 0.0)
    throw Error(fmt::format("cantilever: no clamp position within 3 edge lengths ({:.3g} m) of the pins explains both "
                            "overhangs' drops ({:.6g} m and {:.6g} m)", r.edge_length, drop_long, drop_short));
  for (int it = 0; it < 60 && hi - lo > 1e-6 * r.edge_length; ++it) {
    const double mid = 0.5 * (lo + hi);
    (mismatch(mid) > 0.0 ? lo : hi) = mid;
  }
  const double at = 0.5 * (lo + hi);
  r.clamp_offset = at - clamp;
  r.rigidity = rigidity_clamped_at(at, drop_long, w, strip.length, s_long);
  return r;
}

}  // namespace mgcloth::studies
