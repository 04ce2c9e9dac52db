#include <mgcloth/collision/ccd.hpp>
#include <mgcloth/collision/distance.hpp>
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/core/timer.hpp>
#include <mgcloth/physics/cloth_contact.hpp>
#include <mgcloth/physics/psd.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

namespace mgcloth::physics {

using Vec12 = collision::Vec12;
using Mat12 = collision::Mat12;

double ContactLayer::value(double d, double* d1, double* d2) const {
  if (!(d > 0.0)) {
    if (d1) *d1 = -kInf;
    if (d2) *d2 = kInf;
    return kInf;
  }
  if (d >= r) {
    if (d1) *d1 = 0.0;
    if (d2) *d2 = 0.0;
    return 0.0;
  }
  const double gap = r - d;
  double e = k / (3.0 * r) * gap * gap * gap;
  if (d1) *d1 = -k / r * gap * gap;
  if (d2) *d2 = 2.0 * k / r * gap;
  if (d < tau) {
    // IPC's barrier (Li et al. 2020, eq. 6) and its two derivatives.
    const double K = kappa(), L = std::log(d / tau), s = d - tau;
    e += -K * s * s * L;
    if (d1) *d1 += K * (-2.0 * s * L - s * s / d);
    if (d2) *d2 += K * (-2.0 * L - 4.0 * s / d + s * s / (d * d));
  }
  return e;
}

namespace {

Vec3 at(const VecX& x, Index i) { return x.segment<3>(3 * i); }

Vec3 lift(const Mat2X& u, Index i) { return Vec3(u(0, i), u(1, i), 0.0); }

}  // namespace

ClothContact::ClothContact(std::vector<ContactSurface> surfaces, Index num_points, const ClothContactParams& params,
                           VecX kinematic_positions)
    : m_surfaces(std::move(surfaces)), m_n(num_points), m_y(std::move(kinematic_positions)), m_params(params) {
  if (!(params.stiffness > 0.0) || !std::isfinite(params.stiffness))
    throw_input_error("cloth contact: stiffness must be positive and finite (got {})", params.stiffness);
  if (!(params.barrier_fraction > 0.0 && params.barrier_fraction <= 1.0))
    throw_input_error("cloth contact: barrier_fraction must be in (0, 1] (got {})", params.barrier_fraction);
  if (!(params.ccd_separation > 0.0 && params.ccd_separation < 1.0))
    throw_input_error("cloth contact: ccd_separation must be in (0, 1) (got {})", params.ccd_separation);
  if (m_y.size() % 3 != 0) throw_error("cloth contact: {} kinematic coordinates are not points", m_y.size());
  if (!m_y.allFinite()) throw_input_error("cloth contact: a kinematic point is not finite");
  m_m = static_cast<Index>(m_y.size() / 3);
  m_all = m_n + m_m;
  m_surface_of_point.assign(static_cast<size_t>(m_all), -1);
  m_stitch_first.resize(static_cast<size_t>(m_all));
  std::iota(m_stitch_first.begin(), m_stitch_first.end(), Index{0});
  m_seam_point = m_stitch_first;  // every seam open until close_seams sees it closed
  // Union–find over the triangles: the connected pieces.
  m_chart.resize(static_cast<size_t>(m_all));
  std::iota(m_chart.begin(), m_chart.end(), Index{0});
  const auto chart = [this](Index v) {
    std::vector<Index>& up = m_chart;
    while (up[static_cast<size_t>(v)] != v) {
      up[static_cast<size_t>(v)] = up[static_cast<size_t>(up[static_cast<size_t>(v)])];
      v = up[static_cast<size_t>(v)];
    }
    return v;
  };
  m_point_area = VecX::Zero(m_all);
  m_point_r = VecX::Zero(m_all);
  std::vector<Tri> tris;
  for (size_t s = 0; s < m_surfaces.size(); ++s) {
    const ContactSurface& c = m_surfaces[s];
    if (!(c.thickness > 0.0) || !std::isfinite(c.thickness))
      throw_input_error("cloth \"{}\": contact thickness must be positive and finite (got {})", c.name, c.thickness);
    m_max_r = std::max(m_max_r, c.thickness);
    m_min_r = std::min(m_min_r, c.thickness);
    m_triangle_start.push_back(static_cast<Index>(tris.size()));
    if (!c.kinematic && s > 0 && m_surfaces[s - 1].kinematic)
      throw_error("cloth contact: cloth \"{}\" follows a kinematic surface (they come last)", c.name);
    if (!c.kinematic) m_cloth_triangles = tris.size() + c.tris.size();
    const Index np = static_cast<Index>(c.area.size());
    if (c.offset < 0 || c.offset + np > (c.kinematic ? m_m : m_n) || (!c.kinematic && c.material.cols() != np))
      throw_error("cloth contact: surface \"{}\" does not fit the {}", c.name,
                  c.kinematic ? "kinematic points" : "unknown");
    const Index first = start(c);
    for (const Tri& t : c.tris)
      for (Index v : t)
        if (v < 0 || v >= np) throw_error("cloth contact: a triangle of surface \"{}\" has point {} of {}", c.name, v, np);
    for (Index i = 0; i < np; ++i) {
      m_surface_of_point[first + i] = static_cast<Index>(s);
      m_point_area[first + i] = c.area[i];
      m_point_r[first + i] = c.thickness;
    }
    for (const auto& group : c.stitch_groups)
      for (Index v : group) {
        if (v < 0 || v >= np) throw_error("cloth contact: a stitch of surface \"{}\" has point {} of {}", c.name, v, np);
        m_stitch_first[static_cast<size_t>(first + v)] = first + group.front();
      }
    for (const Tri& t : c.tris) {
      tris.push_back({t[0] + first, t[1] + first, t[2] + first});
      for (int k = 1; k < 3; ++k) m_chart[static_cast<size_t>(chart(t[k] + first))] = chart(t[0] + first);
    }
  }
  for (Index i = 0; i < m_all; ++i) m_chart[static_cast<size_t>(i)] = chart(i);
  m_triangle_start.push_back(static_cast<Index>(tris.size()));
  m_topology = collision::make_surface_topology(std::move(tris));
  // An edge stands for a third of the area of each triangle it borders, so edges cover the surface once.
  std::map<std::pair<Index, Index>, Index> edge_index;
  for (size_t e = 0; e < m_topology.edges.size(); ++e)
    edge_index[{m_topology.edges[e][0], m_topology.edges[e][1]}] = static_cast<Index>(e);
  m_edge_area = VecX::Zero(static_cast<Index>(m_topology.edges.size()));
  for (size_t s = 0; s < m_surfaces.size(); ++s) {
    const ContactSurface& c = m_surfaces[s];
    const Index first = start(c);
    // A cloth's areas are its material's; an obstacle's, its surface's where it starts.
    const auto corner = [&](Index v) { return c.kinematic ? at(m_y, c.offset + v) : lift(c.material, v); };
    for (const Tri& t : c.tris) {
      const Vec3 a = corner(t[0]), b = corner(t[1]), d = corner(t[2]);
      const double area = 0.5 * (b - a).cross(d - a).norm();
      for (int k = 0; k < 3; ++k) {
        Index i = t[k] + first, j = t[(k + 1) % 3] + first;
        if (i > j) std::swap(i, j);
        m_edge_area[edge_index.at({i, j})] += area / 3.0;
      }
    }
  }
  // Smaller margins rebuild more often but filter fewer candidates: on the layered drape (10K, 8 steps) δ = r/4 took
  // 0.76× the time of δ = r, δ = r/2 0.91×, and δ = 3r 1.7× (bench/RESULTS.md).
  m_delta = 0.25 * m_max_r;
  double edge_sum = 0.0;
  Index edge_count = 0;
  // The pieces measure the cloths' motion: obstacles hold still within a solve.
  for (const ContactSurface& c : m_surfaces)
    if (!c.kinematic)
      for (const Tri& t : c.tris)
        for (int k = 0; k < 3; ++k) {
          edge_sum += (lift(c.material, t[(k + 1) % 3]) - lift(c.material, t[k])).norm();
          ++edge_count;
        }
  // Pieces of one mesh spacing: on the 40K layered drape (9 steps, 1 thread) 0.84× the time and 0.88× the peak
  // memory of checking each step whole (bench/RESULTS.md).
  if (edge_count > 0) m_sweep_length = std::max(edge_sum / edge_count, m_max_r);
  m_broad = std::make_unique<collision::BroadPhase>(&m_topology);
}

ClothContact::~ClothContact() = default;

const VecX& ClothContact::extended(const VecX& x) const {
  if (x.size() != 3 * m_n) throw_error("cloth contact: x has {} entries for {} points", x.size(), m_n);
  if (m_m == 0) return x;
  m_extended.resize(3 * m_all);
  m_extended.head(3 * m_n) = x;
  m_extended.tail(3 * m_m) = m_y;
  return m_extended;
}

VecX ClothContact::with_kinematic(const VecX& x) const { return extended(x); }

void ClothContact::set_kinematic_positions(const VecX& y) {
  if (y.size() != 3 * m_m) throw_error("cloth contact: {} kinematic coordinates for {} points", y.size(), m_m);
  if (!y.allFinite()) throw_input_error("cloth contact: a kinematic point is not finite");
  // The cache checks its cover of every point it is asked about, the kinematic ones included: nothing to reset.
  m_y = y;
}

double ClothContact::max_joint_step(const VecX& x, const VecX& dx, const VecX& y_end) const {
  if (dx.size() != 3 * m_n || y_end.size() != 3 * m_m)
    throw_error("cloth contact: a joint motion of {} and {} coordinates for {} and {} points", dx.size(), y_end.size(),
                m_n, m_m);
  VecX X = extended(x), step(3 * m_all);
  step.head(3 * m_n) = dx;
  step.tail(3 * m_m) = y_end - m_y;
  return max_extended_step(X, step, 1.0);
}

std::pair<size_t, Index> ClothContact::triangle_owner(Index t) const {
  const auto it = std::upper_bound(m_triangle_start.begin(), m_triangle_start.end(), t);
  const size_t s = static_cast<size_t>(it - m_triangle_start.begin()) - 1;
  return {s, t - m_triangle_start[s]};
}

double ClothContact::distance(const Pair& p, const VecX& x) const {
  const double s = p.edge_edge
                       ? collision::edge_edge_distance_sq(at(x, p.v[0]), at(x, p.v[1]), at(x, p.v[2]), at(x, p.v[3]))
                       : collision::point_triangle_distance_sq(at(x, p.v[0]), at(x, p.v[1]), at(x, p.v[2]),
                                                               at(x, p.v[3]));
  return std::sqrt(s);
}

void ClothContact::close_seams(const VecX& x_unknown) {
  const VecX& x = extended(x_unknown);
  // A group is closed when all its points are: first mark the open points, then open their groups.
  std::vector<char> open(static_cast<size_t>(m_all), 0);
  for (Index v = 0; v < m_all; ++v) {
    const Index w = m_stitch_first[static_cast<size_t>(v)];
    if (w != v && (at(x, v) - at(x, w)).norm() > 2.0 * m_point_r[v]) open[static_cast<size_t>(w)] = 1;
  }
  for (Index v = 0; v < m_all; ++v) {
    const Index w = m_stitch_first[static_cast<size_t>(v)];
    m_seam_point[static_cast<size_t>(v)] = open[static_cast<size_t>(w)] ? v : w;
  }
  reset_near();
}

bool ClothContact::never_paired(const Pair& p) const {
  if (p.v[0] >= m_n && p.v[1] >= m_n && p.v[2] >= m_n && p.v[3] >= m_n) return true;
  const int first_b = p.edge_edge ? 2 : 1;
  for (int a = 0; a < first_b; ++a)
    for (int b = first_b; b < 4; ++b)
      if (m_seam_point[static_cast<size_t>(p.v[a])] == m_seam_point[static_cast<size_t>(p.v[b])]) return true;
  return false;
}

double ClothContact::material_layer(const Pair& p) const {
  const Index s = m_surface_of_point[p.v[0]];
  if (s != m_surface_of_point[p.v[1]] || s != m_surface_of_point[p.v[2]] || s != m_surface_of_point[p.v[3]])
    return p.r;
  const ContactSurface& c = m_surfaces[static_cast<size_t>(s)];
  if (c.kinematic) return p.r;
  // Pieces of one cloth (a pattern's panels) are charts of their own that may overlap in material space.
  const Index piece = m_chart[static_cast<size_t>(p.v[0])];
  for (int k = 1; k < 4; ++k)
    if (m_chart[static_cast<size_t>(p.v[k])] != piece) return p.r;
  // Primitives this near on the cloth sit inside a full layer at rest: where the mesh spacing is below the layer, it
  // would stiffen the cloth against in-plane compression, and without any energy nothing but the CCD keeps them
  // apart, so that a seam pulling a fine mesh squeezed them to rounding distances and stalled the solve. Their layer
  // is half their distance at rest: no force at rest, a barrier before they meet.
  const auto u = [&](int k) { return lift(c.material, p.v[k] - c.offset); };
  const double d2 = p.edge_edge ? collision::edge_edge_distance_sq(u(0), u(1), u(2), u(3))
                                : collision::point_triangle_distance_sq(u(0), u(1), u(2), u(3));
  return std::min(p.r, kNeighbourLayer * std::sqrt(d2));
}

double ClothContact::pair_energy(const Pair& p, const VecX& x, Vec12* g, Mat12* H, bool project_psd) const {
  const Vec3 a = at(x, p.v[0]), b = at(x, p.v[1]), c = at(x, p.v[2]), e = at(x, p.v[3]);
  Vec12 gs;
  Mat12 Hs;
  double s = 0.0;
  if (p.edge_edge) {
    const auto type = collision::edge_edge_type(a, b, c, e);
    s = collision::edge_edge_distance_sq(a, b, c, e, type, (g || H) ? &gs : nullptr, H ? &Hs : nullptr);
  } else {
    const auto type = collision::point_triangle_type(a, b, c, e);
    s = collision::point_triangle_distance_sq(a, b, c, e, type, (g || H) ? &gs : nullptr, H ? &Hs : nullptr);
  }
  const double d = std::sqrt(std::max(s, 0.0));
  if (d >= p.layer) {
    if (g) g->setZero();
    if (H) H->setZero();
    return 0.0;
  }
  const ContactLayer layer(p.layer, m_params.barrier_fraction, p.weight);
  double d1 = 0.0, d2 = 0.0;
  const double psi = layer.value(d, &d1, &d2);
  if (!std::isfinite(psi)) {
    if (g) g->setConstant(std::numeric_limits<double>::quiet_NaN());
    if (H) H->setConstant(std::numeric_limits<double>::quiet_NaN());
    return kInf;
  }
  // d = √s: ∇d = ∇s/(2d), ∇²d = ∇²s/(2d) − ∇s∇sᵀ/(4d³).
  if (g || H) {
    const Vec12 gd = gs / (2.0 * d);
    if (g) *g = d1 * gd;
    if (H) {
      *H = d2 * gd * gd.transpose() + d1 * (Hs / (2.0 * d) - gd * gd.transpose() / d);
      if (project_psd) physics::project_psd(*H);
    }
  }
  return psi;
}

std::vector<Index> ClothContact::escaped(const VecX& x, Vec3& c, double& t) const {
  // The cache covers x when x_i = x_b,i + c + t·s_i + e_i with |e_i| <= δ for one translation c and one t in [0, 1]
  // (s the cache's step less its mean). Distances do not change under a common translation, and with one t a pair
  // moves only by the differences of its points' steps. c is the mean displacement and t the least-squares fit, which
  // for the line search's points x_b + α(s + c̄) are exactly α c̄ and α.
  const auto X = as_columns(x);
  const auto B = as_columns(static_cast<const VecX&>(m_near_base));
  const auto S = as_columns(static_cast<const VecX&>(m_near_step));
  c = (X - B).rowwise().mean();
  const double ss = m_near_step.squaredNorm();
  t = ss > 0.0 ? std::clamp(((X - B).colwise() - c).cwiseProduct(S).sum() / ss, 0.0, 1.0) : 0.0;
  std::vector<Index> out;
  for (Index i = 0; i < m_all; ++i)
    if ((X.col(i) - B.col(i) - c - t * S.col(i)).squaredNorm() > m_delta * m_delta) out.push_back(i);
  return out;
}

bool ClothContact::near_valid(const VecX& x) const {
  if (m_near_base.size() != x.size()) return false;
  Vec3 c;
  double t;
  return escaped(x, c, t).empty();
}

void ClothContact::ensure_near(const VecX& x) const {
  if (x.size() != 3 * m_all) throw_error("cloth contact: x has {} entries for {} points", x.size(), m_all);
  if (m_near_base.size() != x.size()) return rebuild_near(x, nullptr);
  Vec3 c;
  double t;
  const std::vector<Index> out = escaped(x, c, t);
  if (out.empty()) return;
  if (static_cast<double>(out.size()) > kLocalUpdateFraction * static_cast<double>(m_all)) return rebuild_near(x, nullptr);
  update_near(x, out, c, t);
}

void ClothContact::update_near(const VecX& x, const std::vector<Index>& moved, const Vec3& c, double t) const {
  logger().debug("cloth contact: near pairs of {} points updated", moved.size());
  const Timer timer;
  // Each escaped point gets a new base, where it is now in the cache's frame; pairs of points that kept theirs keep
  // their guarantee, and the pairs of the others are found again at the new bases.
  auto B = as_columns(m_near_base);
  const auto S = as_columns(static_cast<const VecX&>(m_near_step));
  const auto X = as_columns(x);
  std::vector<char> mark(static_cast<size_t>(m_all), 0);
  for (Index i : moved) {
    B.col(i) = X.col(i) - c - t * S.col(i);
    mark[static_cast<size_t>(i)] = 1;
  }
  const auto touches = [&](const Pair& p) {
    return mark[p.v[0]] || mark[p.v[1]] || mark[p.v[2]] || mark[p.v[3]];
  };
  std::erase_if(m_near, touches);
  m_broad->find_touching(m_near_base, &m_near_step, 0.5 * m_max_r + m_delta, mark, m_candidates);
  add_near_pairs(m_near_base, m_near_step);
  ++m_near_generation;
  m_times.broad_phase_ms += timer.ms();
}

void ClothContact::rebuild_near(const VecX& x, const VecX* step) const {
  logger().debug("cloth contact: near pairs rebuilt{}", step ? " along a step" : "");
  const Timer timer;
  // The cache lives in a frame that moves with the step's mean displacement c̄ (a stack of cloths falling together
  // moves far in world space but little relative to itself), where each point moves along s_i − c̄.
  VecX rel = VecX::Zero(x.size());
  if (step) {
    const auto S = as_columns(*step);
    const Vec3 mean = S.rowwise().mean();
    as_columns(rel) = S.colwise() - mean;
  }
  // A point y within δ of its segment lies in the segment's box grown by δ, and a pair within r at y has boxes within
  // r of each other there: boxes grown by r/2 + δ catch it.
  const double grow = 0.5 * m_max_r + m_delta;
  if (step)
    m_broad->find_swept(x, rel, grow, m_candidates);
  else
    m_broad->find(x, grow, m_candidates);
  m_near.clear();
  add_near_pairs(x, rel);
  m_near_base = x;
  m_near_step = std::move(rel);
  ++m_near_generation;
  m_times.broad_phase_ms += timer.ms();
}

ClothContact::Pair ClothContact::candidate_pair(const collision::Candidates& c, Index k) const {
  Pair p;
  const Index nvt = static_cast<Index>(c.vertex_triangle.size());
  if (k < nvt) {
    const Index v = m_topology.vertices[c.vertex_triangle[k][0]];
    const Tri& t = m_topology.triangles[c.vertex_triangle[k][1]];
    p.v = {v, t[0], t[1], t[2]};
    p.edge_edge = false;
    p.weight = m_params.stiffness * m_point_area[v];
    p.r = 0.5 * (m_point_r[v] + m_point_r[t[0]]);
  } else {
    const auto& [ea, eb] = c.edge_edge[k - nvt];
    const auto& A = m_topology.edges[ea];
    const auto& B = m_topology.edges[eb];
    p.v = {A[0], A[1], B[0], B[1]};
    p.edge_edge = true;
    p.weight = m_params.stiffness * 0.5 * (m_edge_area[ea] + m_edge_area[eb]);
    p.r = 0.5 * (m_point_r[A[0]] + m_point_r[B[0]]);
  }
  p.layer = p.r;  // add_near_pairs narrows it for pairs of one piece (material_layer)
  return p;
}

void ClothContact::add_near_pairs(const VecX& x, const VecX& rel) const {
  const Index nvt = static_cast<Index>(m_candidates.vertex_triangle.size());
  const Index nee = static_cast<Index>(m_candidates.edge_edge.size());
  // A rebuild along a long step can have hundreds of millions of candidates: a byte each here, and the few kept are
  // made into pairs again below, rather than a Pair (48 bytes) for every one.
  std::vector<char> keep(static_cast<size_t>(nvt + nee), 0);
  const bool moving = rel.squaredNorm() > 0.0;
  parallel_for(nvt + nee, [&](Index k) {
    const Pair p = candidate_pair(m_candidates, k);
    if (never_paired(p)) return;
    // At a covered point, relative to the pair's first point, each point i has moved by t(s_i − s_0) + e_i, so each
    // side's distance drops by at most its largest |s_i − s_0| plus δ.
    const int split = p.edge_edge ? 2 : 1;
    double ma = 0.0, mb = 0.0;
    if (moving) {
      const Vec3 s0 = at(rel, p.v[0]);
      for (int i = 1; i < 4; ++i) {
        const double m = (at(rel, p.v[i]) - s0).norm();
        (i < split ? ma : mb) = std::max(i < split ? ma : mb, m);
      }
    }
    const double margin = 2.0 * m_delta + ma + mb;
    // The box gap against the widest reach first: most candidates fail it, and need no layer.
    const double lb = lower_bound_distance(p, x);
    if (lb >= p.r + margin) return;
    Pair q = p;
    q.layer = material_layer(p);
    const double reach = cache_layer(q) + margin;
    if (lb >= reach || distance(p, x) >= reach) return;
    keep[static_cast<size_t>(k)] = 1;
  });
  const size_t first = m_near.size();
  for (size_t k = 0; k < keep.size(); ++k)
    if (keep[k]) m_near.push_back(candidate_pair(m_candidates, static_cast<Index>(k)));
  parallel_for(static_cast<Index>(m_near.size() - first), [&](Index k) {
    Pair& p = m_near[first + static_cast<size_t>(k)];
    p.layer = material_layer(p);
  });
  m_candidates = {};  // not needed until the next search, and the largest thing contact holds
}

double ClothContact::lower_bound_distance(const Pair& p, const VecX& x) const {
  // The gap between the two sides' bounding boxes.
  const int split = p.edge_edge ? 2 : 1;
  Vec3 alo = at(x, p.v[0]), ahi = alo, blo = at(x, p.v[split]), bhi = blo;
  for (int i = 1; i < 4; ++i) {
    if (i == split) continue;
    const Vec3 y = at(x, p.v[i]);
    if (i < split) {
      alo = alo.cwiseMin(y);
      ahi = ahi.cwiseMax(y);
    } else {
      blo = blo.cwiseMin(y);
      bhi = bhi.cwiseMax(y);
    }
  }
  return (blo - ahi).cwiseMax(alo - bhi).cwiseMax(0.0).norm();
}

const std::vector<double>& ClothContact::near_distances(const VecX& x) const {
  ensure_near(x);
  if (m_eval_generation == m_near_generation && m_eval_x.size() == x.size() && m_eval_x == x) return m_eval_d;
  const Timer timer;
  m_eval_d.resize(m_near.size());
  parallel_for(static_cast<Index>(m_near.size()), [&](Index k) {
    const Pair& p = m_near[static_cast<size_t>(k)];
    // Pairs whose boxes are a layer apart need no exact distance: none of the callers looks beyond layer + δ.
    const double lb = lower_bound_distance(p, x);
    m_eval_d[static_cast<size_t>(k)] = lb >= p.layer + m_delta ? lb : distance(p, x);
  });
  m_eval_x = x;
  m_eval_generation = m_near_generation;
  m_times.distances_ms += timer.ms();
  return m_eval_d;
}

std::vector<Index> ClothContact::active(const VecX& x) const {
  const std::vector<double>& d = near_distances(x);
  std::vector<Index> out;
  for (size_t k = 0; k < m_near.size(); ++k)
    if (d[k] < m_near[k].layer) out.push_back(static_cast<Index>(k));
  return out;
}

double ClothContact::value(const VecX& x_unknown) const {
  const VecX& x = extended(x_unknown);
  const std::vector<Index> act = active(x);
  return parallel_sum(static_cast<Index>(act.size()), [&](Index k) {
    return pair_energy(m_near[static_cast<size_t>(act[static_cast<size_t>(k)])], x, nullptr, nullptr, false);
  });
}

void ClothContact::add_gradient(const VecX& x_unknown, VecX& g) const {
  const VecX& x = extended(x_unknown);
  const std::vector<Index> act = active(x);
  std::vector<Vec12> ge(act.size());
  parallel_for(static_cast<Index>(act.size()), [&](Index k) {
    pair_energy(m_near[static_cast<size_t>(act[k])], x, &ge[static_cast<size_t>(k)], nullptr, false);
  });
  for (size_t k = 0; k < act.size(); ++k) {
    const Pair& p = m_near[static_cast<size_t>(act[k])];
    for (int a = 0; a < 4; ++a)
      if (p.v[a] < m_n) g.segment<3>(3 * p.v[a]) += ge[k].segment<3>(3 * a);
  }
}

void ClothContact::add_hessian(const VecX& x_unknown, linalg::BlockMatrix3& H, bool project_psd) const {
  const VecX& x = extended(x_unknown);
  const std::vector<Index> act = active(x);
  std::vector<Mat12> He(act.size());
  parallel_for(static_cast<Index>(act.size()), [&](Index k) {
    pair_energy(m_near[static_cast<size_t>(act[k])], x, nullptr, &He[static_cast<size_t>(k)], project_psd);
  });
  for (size_t k = 0; k < act.size(); ++k) {
    const Pair& p = m_near[static_cast<size_t>(act[k])];
    const auto it = std::lower_bound(m_stencils.begin(), m_stencils.end(), p.v);
    if (it == m_stencils.end() || *it != p.v)
      throw_error("cloth contact: an active pair is missing from the Hessian's pattern (update_stencils not called)");
    const auto& slots = m_slots[static_cast<size_t>(it - m_stencils.begin())];
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        if (slots[4 * a + b] >= 0) H.block(slots[4 * a + b]) += He[k].block<3, 3>(3 * a, 3 * b);
  }
}

void collect_stencil_pattern(const std::vector<std::array<Index, 4>>& stencils,
                             std::vector<std::pair<Index, Index>>& pairs, Index unknown_points) {
  for (const auto& s : stencils)
    for (Index a : s)
      for (Index b : s)
        if (a < unknown_points && b < unknown_points) pairs.emplace_back(a, b);
}

std::vector<std::array<Index, 16>> stencil_slots(const std::vector<std::array<Index, 4>>& stencils,
                                                 const linalg::BlockMatrix3& pattern, const char* what,
                                                 Index unknown_points) {
  std::vector<std::array<Index, 16>> out(stencils.size());
  for (size_t k = 0; k < stencils.size(); ++k)
    for (size_t a = 0; a < 4; ++a)
      for (size_t b = 0; b < 4; ++b) {
        if (stencils[k][a] >= unknown_points || stencils[k][b] >= unknown_points) {
          out[k][4 * a + b] = -1;
          continue;
        }
        const Index slot = pattern.find(stencils[k][a], stencils[k][b]);
        if (slot < 0) throw_error("{}: stencil block missing from the pattern", what);
        out[k][4 * a + b] = slot;
      }
  return out;
}

void ClothContact::collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const {
  collect_stencil_pattern(m_stencils, pairs, m_n);
}

void ClothContact::bind(const linalg::BlockMatrix3& pattern) {
  m_slots = stencil_slots(m_stencils, pattern, "cloth contact", m_n);
}

std::vector<std::array<Index, 4>> ClothContact::stencils_at(const VecX& x) const {
  const std::vector<double>& d = near_distances(x);
  // Pairs a little outside the layer are kept in the pattern too, so that a pair that enters next does not change it.
  std::vector<std::array<Index, 4>> out;
  for (size_t k = 0; k < m_near.size(); ++k)
    if (d[k] < m_near[k].layer + m_delta) out.push_back(m_near[k].v);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

void ClothContact::start_step(const VecX& x) {
  auto fresh = stencils_at(extended(x));
  if (fresh == m_stencils) return;
  m_stencils = std::move(fresh);
  m_stencils_pending = true;
}

bool ClothContact::update_stencils(const VecX& x_unknown) {
  const VecX& x = extended(x_unknown);
  const std::vector<Index> act = active(x);
  bool missing = false;
  for (Index k : act)
    if (!std::binary_search(m_stencils.begin(), m_stencils.end(), m_near[static_cast<size_t>(k)].v)) {
      missing = true;
      break;
    }
  const bool changed = missing || m_stencils_pending;
  m_stencils_pending = false;
  if (!changed) return false;
  if (missing) m_stencils = stencils_at(x);
  logger().debug("cloth contact: new pattern, {} stencils", m_stencils.size());
  return true;
}

double ClothContact::max_step(const VecX& x, const VecX& d, double alpha_max) const {
  if (!(alpha_max > 0.0)) return 0.0;
  if (d.size() != 3 * m_n) throw_error("cloth contact: a step has {} entries for {} points", d.size(), m_n);
  const VecX& X = extended(x);
  if (m_m == 0) return max_extended_step(X, alpha_max * d, alpha_max);
  VecX step = VecX::Zero(3 * m_all);
  step.head(3 * m_n) = alpha_max * d;
  return max_extended_step(X, step, alpha_max);
}

double ClothContact::max_extended_step(const VecX& x, const VecX& step, double alpha_max) const {
  // A rebuild along a step holds every pair its swept boxes meet, and their number grows with the square of how far
  // the points move relative to each other in units of the mesh spacing: a Newton step of a 120K stack of landing
  // sheets had billions (24 GB). The step is therefore checked piece by piece, each moving the points at most
  // m_sweep_length relative to the mean, and the check stops at the first piece with a collision.
  double longest = 0.0;
  const auto S = as_columns(step);
  const Vec3 mean = S.rowwise().mean();
  for (Index i = 0; i < m_all; ++i) longest = std::max(longest, (S.col(i) - mean).norm());
  const int pieces = static_cast<int>(std::min(64.0, std::ceil(longest / m_sweep_length)));
  if (pieces <= 1) return alpha_max * collision_time(x, step);
  const VecX piece = step / pieces;
  for (int k = 0; k < pieces; ++k) {
    const double t = collision_time(x + (static_cast<double>(k) / pieces) * step, piece);
    if (t < 1.0) return alpha_max * (k + t) / pieces;
  }
  return alpha_max;
}

double ClothContact::collision_time(const VecX& x, const VecX& step) const {
  const double s = m_params.ccd_separation;
  // With the cache valid at x, a pair outside it is at least ρ = kCacheFloor·r_min apart (cache_layer). Distances
  // ignore the step's mean c̄, and while no point moves more than (1 − s)·ρ/2 relative to it, no such pair closes to
  // s times its distance: only the cached pairs need collision detection. The cache also covers the whole step when
  // it covers both of its ends, since the points it covers form a convex set. Otherwise, when many points move that
  // far, the cache is rebuilt along the step: its pairs are then every pair that can come within its reach anywhere
  // on it (so the line search's trial points on it need no rebuild), a superset of those that can collide. When few
  // do, only the pairs of those few are found along the step, for the collision detection alone; trial points then
  // update the cache locally.
  const double small = 0.5 * (1.0 - s) * kCacheFloor * m_min_r;
  VecX rel = step;
  as_columns(rel).colwise() -= as_columns(step).rowwise().mean();
  std::vector<char> fast(static_cast<size_t>(m_all), 0);
  Index fast_count = 0;
  for (Index i = 0; i < m_all; ++i)
    if (rel.segment<3>(3 * i).squaredNorm() > small * small) {
      fast[static_cast<size_t>(i)] = 1;
      ++fast_count;
    }
  std::vector<Pair> extra;
  const bool covered = fast_count == 0 ? (ensure_near(x), true) : near_valid(x) && near_valid(x + step);
  if (!covered) {
    if (static_cast<double>(fast_count) > kLocalUpdateFraction * static_cast<double>(m_all)) {
      rebuild_near(x, &step);
    } else {
      ensure_near(x);
      const Timer timer;
      collision::Candidates swept;
      m_broad->find_touching(x, &rel, 0.5 * s * m_max_r, fast, swept);
      const Index nvt = static_cast<Index>(swept.vertex_triangle.size());
      const Index total = nvt + static_cast<Index>(swept.edge_edge.size());
      std::vector<char> need(static_cast<size_t>(total), 0);
      std::vector<Pair> all(static_cast<size_t>(total));
      parallel_for(total, [&](Index k) {
        Pair& p = all[static_cast<size_t>(k)];
        p = candidate_pair(swept, k);
        if (never_paired(p)) return;
        // Pairs that cannot close to s times their distance need no collision detection.
        const int split = p.edge_edge ? 2 : 1;
        double ma = 0.0, mb = 0.0;
        const Vec3 s0 = at(rel, p.v[0]);
        for (int i = 1; i < 4; ++i) {
          const double m = (at(rel, p.v[i]) - s0).norm();
          (i < split ? ma : mb) = std::max(i < split ? ma : mb, m);
        }
        need[static_cast<size_t>(k)] = (1.0 - s) * distance(p, x) <= ma + mb;
      });
      for (size_t k = 0; k < all.size(); ++k)
        if (need[k]) extra.push_back(all[k]);
      m_times.broad_phase_ms += timer.ms();
    }
  }
  const Timer timer;
  const size_t nn = m_near.size();
  std::vector<double> t(nn + extra.size(), 1.0);
  // The additive CCD's first step goes to (1 − s)·d0/l_p, l_p the pair's motion relative to its own mean (the bound
  // it computes), and where that passes the step's end it returns 1 at once: a pair whose l_p is below (1 − s) times
  // a lower bound of d0 keeps its t = 1 without the CCD. In a cloth at rest or falling freely that is nearly every
  // cached pair. The bound is the cached distance at x where there is one (exact below its layer + δ, a lower bound
  // beyond), else the gap between the pair's boxes, else the exact distance; 0.99 keeps the test on the safe side of
  // rounding, so the result is the CCD's to the bit.
  const bool cached = m_eval_generation == m_near_generation && m_eval_x.size() == x.size() && m_eval_x == x;
  const double free_fraction = 0.99 * (1.0 - s);
  parallel_for(static_cast<Index>(t.size()), [&](Index k) {
    const size_t j = static_cast<size_t>(k);
    const Pair& p = j < nn ? m_near[j] : extra[j - nn];
    const auto a = [&](int i) { return at(x, p.v[i]); };
    const auto da = [&](int i) { return at(step, p.v[i]); };
    {
      const Vec3 mean = 0.25 * (da(0) + da(1) + da(2) + da(3));
      const auto rel_norm = [&](int i) { return (da(i) - mean).norm(); };
      const double l_p = p.edge_edge ? std::max(rel_norm(0), rel_norm(1)) + std::max(rel_norm(2), rel_norm(3))
                                     : rel_norm(0) + std::max({rel_norm(1), rel_norm(2), rel_norm(3)});
      const double lower = cached && j < nn ? m_eval_d[j] : lower_bound_distance(p, x);
      if (l_p < free_fraction * lower || l_p < free_fraction * distance(p, x)) return;
    }
    t[j] = p.edge_edge ? collision::edge_edge_ccd(a(0), a(1), a(2), a(3), da(0), da(1), da(2), da(3), s, 1.0)
                       : collision::point_triangle_ccd(a(0), a(1), a(2), a(3), da(0), da(1), da(2), da(3), s, 1.0);
  });
  m_times.ccd_ms += timer.ms();
  return t.empty() ? 1.0 : *std::min_element(t.begin(), t.end());
}

ContactStats ClothContact::stats(const VecX& x_unknown) const {
  // Exact distances of every near pair, not the bounded ones the evaluation keeps.
  const VecX& x = extended(x_unknown);
  ensure_near(x);
  ContactStats out;
  out.cached = static_cast<Index>(m_near.size());
  for (const Pair& p : m_near) {
    const double d = distance(p, x);
    out.min_distance = std::min(out.min_distance, d);
    if (d < p.layer) ++out.pairs;
  }
  return out;
}


namespace {

// The parameter of the point of segment (a, b) nearest to p, clamped to the segment.
double segment_parameter(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 e = b - a;
  const double ee = e.squaredNorm();
  return ee > 0.0 ? std::clamp((p - a).dot(e) / ee, 0.0, 1.0) : 0.0;
}

// The weights of the nearest points for the pair's nearest-feature type (the type the energy uses), so that the
// frozen relative position is the one whose length is the pair's distance.
std::array<double, 4> point_triangle_weights(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2) {
  using T = collision::PointTriangleType;
  double b0 = 0.0, b1 = 0.0, b2 = 0.0;
  switch (collision::point_triangle_type(p, t0, t1, t2)) {
    case T::P_T0: b0 = 1.0; break;
    case T::P_T1: b1 = 1.0; break;
    case T::P_T2: b2 = 1.0; break;
    case T::P_E0: b1 = segment_parameter(p, t0, t1), b0 = 1.0 - b1; break;
    case T::P_E1: b2 = segment_parameter(p, t1, t2), b1 = 1.0 - b2; break;
    case T::P_E2: b0 = segment_parameter(p, t2, t0), b2 = 1.0 - b0; break;
    case T::P_T: {
      // The classification only says P_T for a triangle that is not degenerate: the normal equations are regular.
      const Vec3 e1 = t1 - t0, e2 = t2 - t0, r = p - t0;
      const double a = e1.dot(e1), b = e1.dot(e2), c = e2.dot(e2), d = r.dot(e1), e = r.dot(e2);
      const double det = a * c - b * b;
      b1 = (c * d - b * e) / det;
      b2 = (a * e - b * d) / det;
      b0 = 1.0 - b1 - b2;
      break;
    }
  }
  return {1.0, -b0, -b1, -b2};
}

std::array<double, 4> edge_edge_weights(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  using T = collision::EdgeEdgeType;
  double s = 0.0, t = 0.0;
  switch (collision::edge_edge_type(a0, a1, b0, b1)) {
    case T::EA0_EB0: break;
    case T::EA0_EB1: t = 1.0; break;
    case T::EA1_EB0: s = 1.0; break;
    case T::EA1_EB1: s = t = 1.0; break;
    case T::EA_EB0: s = segment_parameter(b0, a0, a1); break;
    case T::EA_EB1: s = segment_parameter(b1, a0, a1), t = 1.0; break;
    case T::EA0_EB: t = segment_parameter(a0, b0, b1); break;
    case T::EA1_EB: s = 1.0, t = segment_parameter(a1, b0, b1); break;
    case T::EA_EB: {
      // As the classification computes them; it says EA_EB only where both lie inside (0, 1).
      const Vec3 u = a1 - a0, v = b1 - b0, w = b0 - a0, n = u.cross(v);
      const double nn = n.squaredNorm();
      s = w.cross(v).dot(n) / nn;
      t = w.cross(u).dot(n) / nn;
      break;
    }
  }
  return {1.0 - s, s, -(1.0 - t), -t};
}

// Two unit vectors completing n to an orthonormal basis; any completion gives the same tangential projector.
Eigen::Matrix<double, 3, 2> tangent_basis(const Vec3& n) {
  Index axis = 0;
  n.cwiseAbs().minCoeff(&axis);
  const Vec3 t1 = n.cross(Vec3::Unit(axis)).normalized();
  Eigen::Matrix<double, 3, 2> T;
  T << t1, n.cross(t1);
  return T;
}

}  // namespace

std::vector<ClothContact::ContactFrame> ClothContact::contact_frames(const VecX& x_unknown) const {
  const VecX& x = extended(x_unknown);
  const std::vector<Index> act = active(x);
  std::vector<ContactFrame> out(act.size());
  std::vector<char> keep(act.size(), 0);
  parallel_for(static_cast<Index>(act.size()), [&](Index k) {
    const Pair& p = m_near[static_cast<size_t>(act[static_cast<size_t>(k)])];
    ContactFrame& f = out[static_cast<size_t>(k)];
    f.v = p.v;
    f.edge_edge = p.edge_edge;
    const Vec3 a = at(x, p.v[0]), b = at(x, p.v[1]), c = at(x, p.v[2]), e = at(x, p.v[3]);
    f.c = p.edge_edge ? edge_edge_weights(a, b, c, e) : point_triangle_weights(a, b, c, e);
    const Vec3 rel = f.c[0] * a + f.c[1] * b + f.c[2] * c + f.c[3] * e;
    const double d = distance(p, x);
    if (!(rel.norm() > 0.0) || !(d > 0.0)) return;  // unreachable from an admissible point: no direction to freeze
    f.normal = rel.normalized();
    f.tangent = tangent_basis(f.normal);
    double d1 = 0.0;
    ContactLayer(p.layer, m_params.barrier_fraction, p.weight).value(d, &d1);
    f.normal_force = -d1;
    f.surface_a = m_surface_of_point[p.v[0]];
    f.surface_b = m_surface_of_point[p.v[p.edge_edge ? 2 : 1]];
    keep[static_cast<size_t>(k)] = 1;
  });
  std::vector<ContactFrame> kept;
  kept.reserve(out.size());
  for (size_t k = 0; k < out.size(); ++k)
    if (keep[k]) kept.push_back(out[k]);
  std::sort(kept.begin(), kept.end(), [](const ContactFrame& l, const ContactFrame& r) {
    return l.edge_edge != r.edge_edge ? r.edge_edge : l.v < r.v;
  });
  return kept;
}

}  // namespace mgcloth::physics
