#include <mgcloth/bodies/assembly.hpp>
#include <mgcloth/core/error.hpp>
#include <mgcloth/physics/sub_objective.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

namespace mgcloth::bodies {

/// The joint hierarchy and what it points to.
struct Assembly::Union {
  std::vector<hierarchy::Hierarchy> parts;  ///< each body's own
  hierarchy::Hierarchy joint;
  std::vector<linalg::StencilTable> prolongations;
  std::vector<std::unique_ptr<physics::Objective>> objectives;  ///< levels 1.. (rediscretized)
  std::vector<std::vector<std::vector<Index>>> patches;
};

namespace {

/// Body b's level on joint level l: its own, or its coarsest where its hierarchy is shorter.
size_t level_of(const hierarchy::Hierarchy& h, size_t l) { return std::min(l, h.num_levels() - 1); }

/// The block-diagonal union of the parts' prolongations from joint level l + 1 to l (identity for a body that
/// already is at its coarsest).
linalg::StencilTable union_prolongation(const std::vector<hierarchy::Hierarchy>& parts, size_t l) {
  linalg::StencilTable P;
  P.offsets.assign(1, 0);
  for (const auto& h : parts) {
    const Index col0 = P.num_cols;
    const auto& fine = h.levels[level_of(h, l)];
    const linalg::StencilTable* own = l + 1 < h.num_levels() ? fine.prolongation : nullptr;
    if (own) {
      for (Index i = 0; i < own->num_rows; ++i) {
        for (Index k = own->offsets[i]; k < own->offsets[i + 1]; ++k) {
          P.indices.push_back(col0 + own->indices[k]);
          P.weights.push_back(own->weights[k]);
        }
        P.offsets.push_back(static_cast<Index>(P.indices.size()));
      }
      P.num_rows += own->num_rows;
      P.num_cols += own->num_cols;
    } else {
      for (Index i = 0; i < fine.num_points; ++i) {
        P.indices.push_back(col0 + i);
        P.weights.push_back(1.0);
        P.offsets.push_back(static_cast<Index>(P.indices.size()));
      }
      P.num_rows += fine.num_points;
      P.num_cols += fine.num_points;
    }
  }
  P.build_transpose();
  return P;
}

}  // namespace

Assembly::Assembly(std::vector<Body*> bodies) : m_bodies(std::move(bodies)) {
  if (m_bodies.empty()) throw_error("Assembly: no bodies");
  m_offsets.push_back(0);
  for (const Body* b : m_bodies) m_offsets.push_back(m_offsets.back() + b->num_points());
}

Assembly::~Assembly() = default;

VecX Assembly::x() const {
  VecX out(3 * num_points());
  for (size_t b = 0; b < m_bodies.size(); ++b) out.segment(3 * m_offsets[b], m_bodies[b]->x().size()) = m_bodies[b]->x();
  return out;
}

VecX Assembly::v() const {
  VecX out(3 * num_points());
  for (size_t b = 0; b < m_bodies.size(); ++b) out.segment(3 * m_offsets[b], m_bodies[b]->v().size()) = m_bodies[b]->v();
  return out;
}

VecX Assembly::prepare_step(const StepTime& step) {
  const VecX from = m_contact ? x() : VecX();
  VecX out;
  if (m_bodies.size() == 1) {
    out = m_bodies[0]->prepare_step(step);
  } else {
    out.resize(3 * num_points());
    for (size_t b = 0; b < m_bodies.size(); ++b) {
      const VecX y = m_bodies[b]->prepare_step(step);
      out.segment(3 * m_offsets[b], y.size()) = y;
    }
  }
  if (m_contact) {
    // The prediction x + h v may pass through cloth; the solve starts where the motion towards it stops.
    m_contact->close_seams(from);  // also drops the near-pair cache: every step starts from a fresh one
    if (m_meshes.empty()) {
      const VecX d = out - from;
      out = from + objective().max_step(from, d, 1.0) * d;
      m_contact->start_step(out);
      // Friction is lagged at the state the step starts from, so that u/h is the relative tangential velocity.
      if (m_friction) m_friction->start_step(from, m_contact->contact_frames(from), step.h);
    } else {
      // Friction's frames at the start, where the obstacles still are.
      std::vector<physics::ClothContact::ContactFrame> frames;
      if (m_friction) frames = m_contact->contact_frames(from);
      // The obstacles move with the cloths' prediction (which, for cloth resting on a moving body, carries it
      // along); where the joint motion would collide, both stop there, and advance_obstacles goes on after a solve.
      const VecX y0 = m_contact->kinematic_positions();
      m_mesh_target = obstacle_positions(step.t + step.h);
      // Cloth in the obstacles' way starts moving with them rather than by its inertia: otherwise each solve lets
      // the obstacles reach the next piece of cloth in their way only (advance_obstacles).
      VecX d = out - from;
      carry_swept(from, y0, m_mesh_target - y0, std::vector<char>(static_cast<size_t>(num_points()), 0), d);
      const double a = m_contact->max_joint_step(from, d, m_mesh_target);
      m_contact->set_kinematic_positions(a < 1.0 ? VecX(y0 + a * (m_mesh_target - y0)) : m_mesh_target);
      // Short of the target only where they had a way to go: a still obstacle is never behind, however short the
      // cloth's own motion fell.
      m_behind = a < 1.0 && m_mesh_target != y0;
      out = from + a * d;
      m_contact->start_step(out);
      if (m_friction) {
        const VecX motion = m_mesh_target - y0;
        m_friction->start_step(from, frames, step.h, &motion);
      }
    }
  }
  return out;
}

VecX Assembly::obstacle_positions(double t) const {
  Index size = 0;
  for (const geometry::Obstacle& o : m_meshes) size += 3 * o.mesh->vertices.cols();
  VecX out(size);
  Index k = 0;
  for (const geometry::Obstacle& o : m_meshes) {
    const VecX y = o.mesh_positions(t);
    out.segment(k, y.size()) = y;
    k += y.size();
  }
  return out;
}

void Assembly::place_obstacles(double t) {
  if (m_meshes.empty()) return;
  m_contact->set_kinematic_positions(obstacle_positions(t));
  m_behind = false;
}

double Assembly::advance_obstacles(VecX& x) {
  if (!m_behind) return 1.0;
  // Cloth in the layer of an obstacle is carried along with the obstacle's nearest point, so that the obstacle
  // pushes it rather than closing in on it a fraction of the gap per solve; the rest of the cloth stays. The joint
  // motion is checked as a whole, and the solve that follows settles the cloth.
  const Index n = num_points();
  const VecX& y = m_contact->kinematic_positions();
  VecX dx = VecX::Zero(x.size());
  VecX count = VecX::Zero(n);
  for (const auto& f : m_contact->contact_frames(x)) {
    Vec3 moved = Vec3::Zero();
    double weight = 0.0;
    for (size_t i = 0; i < 4; ++i)
      if (f.v[i] >= n) {
        const Index k = f.v[i] - n;
        moved += std::abs(f.c[i]) * (m_mesh_target.segment<3>(3 * k) - y.segment<3>(3 * k));
        weight += std::abs(f.c[i]);
      }
    if (!(weight > 0.0)) continue;  // a pair between cloths
    for (size_t i = 0; i < 4; ++i)
      if (f.v[i] < n) {
        dx.segment<3>(3 * f.v[i]) += moved / weight;
        count[f.v[i]] += 1.0;
      }
  }
  for (Index i = 0; i < n; ++i)
    if (count[i] > 0.0) dx.segment<3>(3 * i) /= count[i];
  std::vector<char> carried(static_cast<size_t>(n));
  for (Index i = 0; i < n; ++i) carried[static_cast<size_t>(i)] = count[i] > 0.0;
  carry_swept(x, y, m_mesh_target - y, carried, dx);
  const double a = m_contact->max_joint_step(x, dx, m_mesh_target);
  x += a * dx;
  const bool short_of = a < 1.0 && m_mesh_target != y;
  m_contact->set_kinematic_positions(a < 1.0 ? VecX(y + a * (m_mesh_target - y)) : m_mesh_target);
  m_behind = short_of;
  return a;
}

void Assembly::carry_swept(const VecX& x, const VecX& y_from, const VecX& motion, const std::vector<char>& skip,
                           VecX& dx) const {
  const Index n = num_points(), m = static_cast<Index>(y_from.size() / 3);
  double longest = 0.0;
  for (Index o = 0; o < m; ++o) longest = std::max(longest, motion.segment<3>(3 * o).norm());
  if (!(longest > 0.0)) return;
  // Cloth points hashed in cells as large as the longest sweep plus the pad: a sweep meets the cells its box does.
  const double cell = longest + m_sweep_pad;
  const auto key = [&](const Vec3& p) -> Eigen::Vector3i { return (p / cell).array().floor().cast<int>(); };
  const auto hash = [](const Eigen::Vector3i& k) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.x())) * 73856093u) ^
           (static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.y())) * 19349663u) ^
           (static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.z())) * 83492791u);
  };
  std::unordered_map<std::uint64_t, std::vector<Index>> grid;
  for (Index i = 0; i < n; ++i)
    if (!skip[static_cast<size_t>(i)]) grid[hash(key(x.segment<3>(3 * i)))].push_back(i);
  std::vector<double> best(static_cast<size_t>(n), m_sweep_pad);
  std::vector<Index> from(static_cast<size_t>(n), -1);
  for (Index o = 0; o < m; ++o) {
    const Vec3 a = y_from.segment<3>(3 * o), d = motion.segment<3>(3 * o);
    const double len2 = d.squaredNorm();
    if (!(len2 > 0.0)) continue;
    const Eigen::Vector3i lo = key(a.cwiseMin(a + d) - Vec3::Constant(m_sweep_pad));
    const Eigen::Vector3i hi = key(a.cwiseMax(a + d) + Vec3::Constant(m_sweep_pad));
    for (int i = lo.x(); i <= hi.x(); ++i)
      for (int j = lo.y(); j <= hi.y(); ++j)
        for (int k = lo.z(); k <= hi.z(); ++k) {
          const auto it = grid.find(hash({i, j, k}));
          if (it == grid.end()) continue;
          for (Index c : it->second) {
            const Vec3 p = x.segment<3>(3 * c);
            const double s = std::clamp((p - a).dot(d) / len2, 0.0, 1.0);
            const double dist = (a + s * d - p).norm();
            if (dist < best[static_cast<size_t>(c)]) {
              best[static_cast<size_t>(c)] = dist;
              from[static_cast<size_t>(c)] = o;
            }
          }
        }
  }
  for (Index c = 0; c < n; ++c)
    if (from[static_cast<size_t>(c)] >= 0) dx.segment<3>(3 * c) = motion.segment<3>(3 * from[static_cast<size_t>(c)]);
}

void Assembly::add_cloth_contact(const physics::ClothContactParams& params, const std::vector<double>& thickness,
                                 std::vector<geometry::Obstacle> meshes, double t0) {
  if (m_contact) throw_error("Assembly: cloth contact added twice");
  if (thickness.size() != m_bodies.size()) throw_error("Assembly: {} thicknesses for {} bodies", thickness.size(), m_bodies.size());
  std::vector<physics::ContactSurface> surfaces;
  for (size_t b = 0; b < m_bodies.size(); ++b) {
    auto s = m_bodies[b]->contact_surface(thickness[b]);
    if (!s) continue;
    s->offset = m_offsets[b];
    surfaces.push_back(std::move(*s));
    m_bodies[b]->set_obstacle_projection(false);
  }
  if (surfaces.empty()) return;
  VecX kinematic;
  Index points = 0;
  for (const geometry::Obstacle& o : meshes) {
    if (!o.mesh) throw_error("Assembly: obstacle \"{}\" has no mesh", o.name);
    physics::ContactSurface s;
    s.name = o.name;
    s.offset = points;
    s.tris = o.mesh->tris;
    s.kinematic = true;
    s.thickness = o.contact_thickness;
    // Rigid motions keep areas: the lumped areas in the obstacle's frame are those in the world.
    const Mat3X& v = o.mesh->vertices;
    s.area = VecX::Zero(v.cols());
    for (const Tri& t : s.tris) {
      const double a = 0.5 * (v.col(t[1]) - v.col(t[0])).cross(v.col(t[2]) - v.col(t[0])).norm() / 3.0;
      for (Index i : t) s.area[i] += a;
    }
    points += v.cols();
    surfaces.push_back(std::move(s));
  }
  m_meshes = std::move(meshes);
  if (!m_meshes.empty()) kinematic = obstacle_positions(t0);
  double thickest = 0.0, edge = 0.0;
  for (const auto& s : surfaces) thickest = std::max(thickest, s.thickness);
  for (const geometry::Obstacle& o : m_meshes) {
    const Mat3X& v = o.mesh->vertices;
    for (const Tri& t : o.mesh->tris)
      for (int c = 0; c < 3; ++c) edge = std::max(edge, (v.col(t[c]) - v.col(t[(c + 1) % 3])).norm());
  }
  // Vertices stand for their triangles within half an edge; a coarse mesh's large faces are left to the re-solves
  // rather than carrying cloth from far around them.
  m_sweep_pad = std::min(0.5 * edge, 0.05) + thickest;
  auto term = std::make_unique<physics::ClothContact>(std::move(surfaces), num_points(), params, std::move(kinematic));
  m_contact = term.get();
  m_contact->close_seams(x());  // seams sewn already (a garment read closed) are joined from the start
  add_coupling(std::move(term));
}

void Assembly::add_coupling(std::unique_ptr<physics::Term> term) {
  if (m_bodies.size() == 1) {
    physics::Objective& own = m_bodies[0]->objective();
    own.add(std::move(term));
    own.finalize();
  } else if (m_objective) {
    m_objective->add(std::move(term));
    m_objective->finalize();
  } else {
    m_pending.push_back(std::move(term));
  }
}

void Assembly::add_cloth_friction(const physics::ClothFrictionParams& params) {
  if (m_friction) throw_error("Assembly: cloth friction added twice");
  if (!m_contact) return;
  std::vector<std::string> names;
  for (const auto& s : m_contact->surfaces()) names.push_back(s.name);
  auto term = std::make_unique<physics::ClothFriction>(num_points(), names, params);
  bool any = false;
  for (Index a = 0; a < static_cast<Index>(names.size()); ++a)
    for (Index b = 0; b < static_cast<Index>(names.size()); ++b) any = any || term->friction(a, b) > 0.0;
  if (!any) return;
  m_friction = term.get();
  add_coupling(std::move(term));
}

std::unique_ptr<physics::Objective> Assembly::joint_objective(const std::vector<const physics::Objective*>& parts) const {
  Index n = 0;
  for (const auto* p : parts) n += p->num_vertices();
  auto joint = std::make_unique<physics::Objective>(n);
  Index offset = 0;
  for (size_t b = 0; b < parts.size(); ++b) {
    joint->add(std::make_unique<physics::SubObjectiveTerm>(m_bodies[b]->name(), *parts[b], offset));
    offset += parts[b]->num_vertices();
  }
  joint->finalize();
  return joint;
}

physics::Objective& Assembly::objective() {
  if (m_bodies.size() == 1) return m_bodies[0]->objective();
  if (!m_objective) {
    std::vector<const physics::Objective*> parts;
    for (Body* b : m_bodies) parts.push_back(&b->objective());
    m_objective = joint_objective(parts);
    if (!m_pending.empty()) {
      for (auto& term : m_pending) m_objective->add(std::move(term));
      m_pending.clear();
      m_objective->finalize();
    }
  }
  return *m_objective;
}

hierarchy::Hierarchy Assembly::solver_hierarchy(bool rediscretized) {
  if (m_bodies.size() == 1) return m_bodies[0]->solver_hierarchy(rediscretized);
  auto& u = rediscretized ? m_rediscretized : m_galerkin;
  if (!u) {
    u = std::make_unique<Union>();
    size_t L = 1;
    for (Body* b : m_bodies) {
      u->parts.push_back(b->solver_hierarchy(rediscretized));
      L = std::max(L, u->parts.back().num_levels());
    }
    u->prolongations.reserve(L);
    for (size_t l = 0; l + 1 < L; ++l) u->prolongations.push_back(union_prolongation(u->parts, l));
    u->joint.levels.resize(L);
    for (size_t l = 0; l < L; ++l) {
      auto& level = u->joint.levels[l];
      for (const auto& h : u->parts) level.num_points += h.levels[level_of(h, l)].num_points;
      if (l + 1 < L) level.prolongation = &u->prolongations[l];
    }
    if (rediscretized) {
      u->patches.resize(L);
      for (size_t l = 1; l < L; ++l) {
        std::vector<const physics::Objective*> parts;
        for (const auto& h : u->parts) parts.push_back(h.levels[level_of(h, l)].objective);
        u->objectives.push_back(joint_objective(parts));
        u->joint.levels[l].objective = u->objectives.back().get();
      }
      for (size_t l = 0; l < L; ++l) {
        Index offset = 0;
        bool all = true;
        for (const auto& h : u->parts) {
          const auto* own = h.levels[level_of(h, l)].patches;
          all = all && own;
          if (own)
            for (const auto& patch : *own) {
              u->patches[l].push_back(patch);
              for (Index& i : u->patches[l].back()) i += offset;
            }
          offset += h.levels[level_of(h, l)].num_points;
        }
        if (all) u->joint.levels[l].patches = &u->patches[l];
      }
      // Projections of iterates: each body's on its part, the identity for a body already at its coarsest.
      for (size_t l = 0; l + 1 < L; ++l)
        for (bool lsq : {false, true}) {
          bool all = true;
          for (const auto& h : u->parts)
            if (l + 1 < h.num_levels()) all = all && static_cast<bool>(lsq ? h.levels[l].project_lsq : h.levels[l].project);
          if (!all) continue;
          const Union* un = u.get();
          (lsq ? u->joint.levels[l].project_lsq : u->joint.levels[l].project) = [un, l, lsq](const VecX& fine, VecX& coarse) {
            coarse.resize(3 * un->joint.levels[l + 1].num_points);
            Index from = 0, to = 0;
            VecX part;
            for (const auto& h : un->parts) {
              const Index nf = h.levels[level_of(h, l)].num_points, nc = h.levels[level_of(h, l + 1)].num_points;
              if (l + 1 < h.num_levels())
                (lsq ? h.levels[l].project_lsq : h.levels[l].project)(fine.segment(3 * from, 3 * nf), part);
              else
                part = fine.segment(3 * from, 3 * nf);
              coarse.segment(3 * to, 3 * nc) = part;
              from += nf;
              to += nc;
            }
          };
        }
    }
  }
  hierarchy::Hierarchy h = u->joint;
  h.levels[0].objective = &objective();
  return h;
}

std::function<Index(VecX&)> Assembly::feasibility_projection() const {
  if (m_bodies.size() == 1) return m_bodies[0]->feasibility_projection();
  std::vector<std::pair<Index, std::function<Index(VecX&)>>> parts;
  for (size_t b = 0; b < m_bodies.size(); ++b)
    if (auto p = m_bodies[b]->feasibility_projection()) parts.emplace_back(b, std::move(p));
  if (parts.empty()) return {};
  return [this, parts](VecX& x) {
    Index moved = 0;
    for (const auto& [b, project] : parts) {
      VecX part = x.segment(3 * m_offsets[b], 3 * (m_offsets[b + 1] - m_offsets[b]));
      if (const Index k = project(part); k > 0) {
        moved += k;
        x.segment(3 * m_offsets[b], part.size()) = part;
      }
    }
    return moved;
  };
}

void Assembly::finish_step(VecX& x, double h) {
  if (m_bodies.size() == 1) return m_bodies[0]->finish_step(x, h);
  for (size_t b = 0; b < m_bodies.size(); ++b) {
    VecX part = x.segment(3 * m_offsets[b], 3 * (m_offsets[b + 1] - m_offsets[b]));
    m_bodies[b]->finish_step(part, h);
    x.segment(3 * m_offsets[b], part.size()) = part;
  }
}

void Assembly::accept_step(const VecX& x, const VecX& v) {
  if (m_bodies.size() == 1) return m_bodies[0]->accept_step(x, v);
  for (size_t b = 0; b < m_bodies.size(); ++b) {
    const Index from = 3 * m_offsets[b], n = 3 * (m_offsets[b + 1] - m_offsets[b]);
    m_bodies[b]->accept_step(x.segment(from, n), v.segment(from, n));
  }
}

}  // namespace mgcloth::bodies
