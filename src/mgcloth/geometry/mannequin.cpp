#include <mgcloth/core/error.hpp>
#include <mgcloth/geometry/mannequin.hpp>

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <optional>
#include <unordered_map>

namespace mgcloth::geometry {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

enum Joint : int {
  kPelvis,
  kAbdomen,
  kChest,
  kHead,
  kUpperArmL,
  kUpperArmR,
  kForearmL,
  kForearmR,
  kHandL,
  kHandR,
  kThighL,
  kThighR,
  kShankL,
  kShankR,
  kFootL,
  kFootR,
  kNumJoints
};

const std::array<const char*, kNumJoints> kJointNames = {
    "pelvis",     "abdomen",    "chest",     "head",     "upper_arm_l", "upper_arm_r", "forearm_l", "forearm_r",
    "hand_l",     "hand_r",     "thigh_l",   "thigh_r",  "shank_l",     "shank_r",     "foot_l",    "foot_r"};
const std::array<int, kNumJoints> kParent = {-1,      kPelvis,   kAbdomen,  kChest,    kChest,    kChest,
                                             kUpperArmL, kUpperArmR, kForearmL, kForearmR, kPelvis,   kPelvis,
                                             kThighL,   kThighR,   kShankL,   kShankR};

/// A round cone: the union of spheres whose centres run from a to b and radii from ra to rb, measured in a
/// metric stretched by `scale` (a flattened torso, hand or head).
struct Segment {
  Vec3 a, b;
  double ra, rb;
  Vec3 scale = Vec3::Ones();
  int joint;
  /// The part of the axis (fractions of a→b) whose nearest vertices follow `joint` alone in the skin weights.
  std::array<double, 2> core = {-1e9, 1e9};
  bool shape = true;  ///< false: it only steers the skin weights
};

/// Distance to a round cone in its 2D half-plane (axial y from a, radial q ≥ 0). The side line touches both end
/// circles; with sin α = (ra − rb) / L its outward normal is n = (sin α, cos α) and n·p = ra on it. A point whose
/// foot on that line lies before the first tangent point is nearest the first sphere, past the second the second.
double round_cone_distance(const Segment& s, const Vec3& p_world) {
  const Vec3 inv = s.scale.cwiseInverse();
  const Vec3 a = s.a.cwiseProduct(inv), b = s.b.cwiseProduct(inv), p = p_world.cwiseProduct(inv);
  const Vec3 ab = b - a;
  const double len = ab.norm();
  const double stretch = s.scale.minCoeff();  // distances in the stretched metric are at most this much shorter
  if (len <= std::abs(s.ra - s.rb) + 1e-12) {
    // One sphere contains the other: the larger one is the shape.
    const bool first = s.ra >= s.rb;
    return stretch * ((p - (first ? a : b)).norm() - (first ? s.ra : s.rb));
  }
  const Vec3 axis = ab / len;
  const double y = (p - a).dot(axis);
  const double q = (p - a - y * axis).norm();
  const double sin_a = (s.ra - s.rb) / len;
  const double cos_a = std::sqrt(1.0 - sin_a * sin_a);
  // Position along the side line (direction (cos α, −sin α)) measured from the first tangent point ra·n.
  const double along = (y - s.ra * sin_a) * cos_a - (q - s.ra * cos_a) * sin_a;
  double d;
  if (along < 0.0) d = std::hypot(y, q) - s.ra;
  else if (along > len * cos_a) d = std::hypot(y - len, q) - s.rb;
  else d = y * sin_a + q * cos_a - s.ra;
  return stretch * d;
}

/// Polynomial smooth minimum: equals min(a, b) when they differ by more than k, rounds the crease within k.
double smooth_min(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}

struct Body {
  std::vector<Segment> segments;
  std::array<Vec3, kNumJoints> joint_pos;  ///< bind pose, world
  std::array<Vec3, 4> soles;  ///< heel and ball of the left foot, then of the right (bind pose, on z = 0)
  double blend = 0.0;         ///< smooth-union width

  double field(const Vec3& p) const {
    double f = 1e300;
    for (const auto& s : segments) {
      if (s.shape) f = f == 1e300 ? round_cone_distance(s, p) : smooth_min(f, round_cone_distance(s, p), blend);
    }
    return f;
  }
  Vec3 gradient(const Vec3& p) const {
    const double e = 1e-6;
    Vec3 g;
    for (int k = 0; k < 3; ++k) {
      Vec3 d = Vec3::Zero();
      d[k] = e;
      g[k] = (field(p + d) - field(p - d)) / (2 * e);
    }
    return g;
  }
};

/// The segments in units of the height, from the Drillis–Contini proportions (shoulder 0.818 H, elbow 0.630 H,
/// wrist 0.485 H, hip 0.530 H, knee 0.285 H, ankle 0.039 H, chin 0.870 H, foot length 0.152 H, shoulder width
/// 0.259 H, hip width 0.191 H); the radii are chosen for those widths and common girths.
Body make_body(const MannequinParams& m) {
  Body body;
  const double H = m.height, g = m.build;
  const double abd = m.arm_abduction * kDeg;
  auto P = [&](double x, double y, double z) { return Vec3(x * H, y * H, z * H); };
  auto add = [&](Vec3 a, Vec3 b, double ra, double rb, int joint, Vec3 scale = Vec3::Ones(),
                 std::array<double, 2> core = {-1e9, 1e9}) {
    body.segments.push_back({a, b, ra * H * g, rb * H * g, scale, joint, core});
  };
  auto& J = body.joint_pos;
  J[kPelvis] = P(0, 0, 0.53);
  J[kAbdomen] = P(0, 0, 0.60);
  J[kChest] = P(0, 0, 0.68);
  J[kHead] = P(0, 0, 0.83);
  const Vec3 torso(0.75, 1.0, 1.0);  // front to back thinner than across
  add(P(0, -0.05, 0.55), P(0, 0.05, 0.55), 0.062, 0.062, kPelvis, Vec3(0.85, 1, 1));
  add(P(0, 0, 0.56), P(0, 0, 0.66), 0.088, 0.078, kAbdomen, torso);
  // The crotch follows the pelvis, not either thigh: between the thighs' surfaces that scissor apart.
  add(P(0, 0, 0.455), P(0, 0, 0.455), 0.02, 0.02, kPelvis);
  body.segments.back().shape = false;
  add(P(0, 0, 0.66), P(0, 0, 0.74), 0.078, 0.088, kChest, torso);
  add(P(0, 0, 0.80), P(0, 0, 0.87), 0.034, 0.030, kHead, Vec3::Ones(), {0.6, 1e9});
  add(P(0.008, 0, 0.935), P(0.008, 0, 0.935), 0.062, 0.062, kHead, Vec3(1.0, 0.78, 1.05));
  for (int side = 0; side < 2; ++side) {
    const double s = side == 0 ? 1.0 : -1.0;  // left is +y
    const int arm = side == 0 ? kUpperArmL : kUpperArmR;
    const Vec3 shoulder = P(0, s * 0.112, 0.80);
    const Vec3 down(0, s * std::sin(abd), -std::cos(abd));
    const Vec3 elbow = shoulder + 0.186 * H * down, wrist = elbow + 0.146 * H * down;
    J[arm] = shoulder;
    J[arm + 2] = elbow;
    J[arm + 4] = wrist;
    add(P(0, s * 0.03, 0.79), shoulder, 0.048, 0.036, kChest, Vec3(0.8, 1, 1), {-1e9, 0.3});  // shoulder girdle
    add(shoulder, elbow, 0.031, 0.023, arm, Vec3::Ones(), {0.5, 0.85});
    add(elbow, wrist, 0.022, 0.016, arm + 2, Vec3::Ones(), {0.25, 0.8});
    add(wrist + 0.01 * H * down, wrist + 0.075 * H * down, 0.018, 0.013, arm + 4, Vec3(1.0, 0.75, 1.0), {0.2, 1e9});
    const int leg = side == 0 ? kThighL : kThighR;
    const Vec3 hip = P(0, s * 0.052, 0.53), knee = P(0, s * 0.05, 0.285), ankle = P(0, s * 0.05, 0.045);
    J[leg] = hip;
    J[leg + 2] = knee;
    J[leg + 4] = ankle;
    add(hip + P(0, s * 0.004, 0), knee, 0.055, 0.034, leg, Vec3::Ones(), {0.6, 0.85});
    add(knee, ankle, 0.033, 0.020, leg + 2, Vec3::Ones(), {0.25, 0.8});
    add(knee + P(-0.008, 0, -0.03), P(-0.004, s * 0.05, 0.15), 0.036, 0.024, leg + 2, Vec3::Ones(), {0.0, 1e9});  // calf
    const Vec3 heel = P(-0.02, s * 0.05, 0.024), ball = P(0.09, s * 0.055, 0.014);
    add(heel, ball, 0.024, 0.014, leg + 4);
    body.soles[2 * side] = P(-0.02, s * 0.05, 0.0);
    body.soles[2 * side + 1] = P(0.09, s * 0.055, 0.0);
  }
  body.blend = 0.016 * H;
  return body;
}

/// Surface nets: one vertex per grid cell the zero set crosses (the mean of its edges' crossings), one quad per
/// crossed grid edge joining the four cells around it, split along its shorter diagonal and oriented outward.
void surface_nets(const Body& body, double h, double shift, Mat3X& x, std::vector<Tri>& tris) {
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (const auto& s : body.segments) {
    if (!s.shape) continue;
    const double r = std::max(s.ra, s.rb) * s.scale.maxCoeff();
    lo = lo.cwiseMin(s.a - Vec3::Constant(r)).cwiseMin(s.b - Vec3::Constant(r));
    hi = hi.cwiseMax(s.a + Vec3::Constant(r)).cwiseMax(s.b + Vec3::Constant(r));
  }
  lo -= Vec3::Constant((2 + shift) * h);
  hi += Vec3::Constant(2 * h);
  const Eigen::Vector3i n = ((hi - lo) / h).array().ceil().cast<int>() + 1;
  const auto idx = [&](int i, int j, int k) { return (static_cast<long>(k) * n[1] + j) * n[0] + i; };
  std::vector<double> f(static_cast<size_t>(n.prod()));
#pragma omp parallel for schedule(dynamic, 4)
  for (int k = 0; k < n[2]; ++k) {
    for (int j = 0; j < n[1]; ++j) {
      for (int i = 0; i < n[0]; ++i) f[static_cast<size_t>(idx(i, j, k))] = body.field(lo + h * Vec3(i, j, k));
    }
  }
  const auto value = [&](int i, int j, int k) { return f[static_cast<size_t>(idx(i, j, k))]; };
  std::unordered_map<long, Index> cell_vertex;
  std::vector<Vec3> verts;
  static const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {1, 1, 1}};
  static const int edge[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3}, {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  const auto cell = [&](int i, int j, int k) -> Index {
    const long key = idx(i, j, k);
    if (auto it = cell_vertex.find(key); it != cell_vertex.end()) return it->second;
    double v[8];
    for (int c = 0; c < 8; ++c) v[c] = value(i + corner[c][0], j + corner[c][1], k + corner[c][2]);
    Vec3 sum = Vec3::Zero();
    int count = 0;
    for (const auto& e : edge) {
      const double a = v[e[0]], b = v[e[1]];
      if ((a < 0) == (b < 0)) continue;
      const double t = a / (a - b);
      const Vec3 pa(corner[e[0]][0], corner[e[0]][1], corner[e[0]][2]), pb(corner[e[1]][0], corner[e[1]][1], corner[e[1]][2]);
      sum += pa + t * (pb - pa);
      ++count;
    }
    const Index id = static_cast<Index>(verts.size());
    verts.push_back(lo + h * (Vec3(i, j, k) + sum / std::max(count, 1)));
    cell_vertex.emplace(key, id);
    return id;
  };
  for (int k = 1; k < n[2] - 1; ++k) {
    for (int j = 1; j < n[1] - 1; ++j) {
      for (int i = 1; i < n[0] - 1; ++i) {
        const bool inside = value(i, j, k) < 0;
        for (int axis = 0; axis < 3; ++axis) {
          const int ni = i + (axis == 0), nj = j + (axis == 1), nk = k + (axis == 2);
          if ((value(ni, nj, nk) < 0) == inside) continue;
          // The four cells around edge (i,j,k)–(ni,nj,nk), in a cycle about the axis.
          std::array<Index, 4> q;
          if (axis == 0) q = {cell(i, j - 1, k - 1), cell(i, j, k - 1), cell(i, j, k), cell(i, j - 1, k)};
          else if (axis == 1) q = {cell(i - 1, j, k - 1), cell(i - 1, j, k), cell(i, j, k), cell(i, j, k - 1)};
          else q = {cell(i - 1, j - 1, k), cell(i, j - 1, k), cell(i, j, k), cell(i - 1, j, k)};
          // The cycle's normal is +axis; the surface's outward normal points from inside to outside.
          if (!inside) std::swap(q[1], q[3]);
          const double d02 = (verts[q[0]] - verts[q[2]]).squaredNorm(), d13 = (verts[q[1]] - verts[q[3]]).squaredNorm();
          if (d02 <= d13) {
            tris.push_back({q[0], q[1], q[2]});
            tris.push_back({q[0], q[2], q[3]});
          } else {
            tris.push_back({q[0], q[1], q[3]});
            tris.push_back({q[1], q[2], q[3]});
          }
        }
      }
    }
  }
  x.resize(3, static_cast<Index>(verts.size()));
  for (size_t v = 0; v < verts.size(); ++v) x.col(static_cast<Index>(v)) = verts[v];
}

Vec3 project_to_surface(const Body& body, Vec3 p) {
  for (int it = 0; it < 4; ++it) {
    const double f = body.field(p);
    const Vec3 g = body.gradient(p);
    const double g2 = g.squaredNorm();
    if (g2 < 1e-12) break;
    p -= f * g / g2;
    if (std::abs(f) < 1e-9) break;
  }
  return p;
}

/// Tangential Laplacian smoothing with reprojection onto the zero set: evens out the surface nets' triangles
/// without moving the surface.
void relax(const Body& body, Mat3X& x, const std::vector<Tri>& tris, int iterations) {
  std::vector<std::vector<Index>> nbr(static_cast<size_t>(x.cols()));
  for (const auto& t : tris) {
    for (int c = 0; c < 3; ++c) {
      nbr[static_cast<size_t>(t[c])].push_back(t[(c + 1) % 3]);
      nbr[static_cast<size_t>(t[c])].push_back(t[(c + 2) % 3]);
    }
  }
  for (auto& l : nbr) {
    std::sort(l.begin(), l.end());
    l.erase(std::unique(l.begin(), l.end()), l.end());
  }
  for (int it = 0; it < iterations; ++it) {
    Mat3X next = x;
#pragma omp parallel for schedule(static)
    for (Index v = 0; v < x.cols(); ++v) {
      Vec3 mean = Vec3::Zero();
      for (Index u : nbr[static_cast<size_t>(v)]) mean += x.col(u);
      mean /= static_cast<double>(nbr[static_cast<size_t>(v)].size());
      const Vec3 p = x.col(v);
      const Vec3 nrm = body.gradient(p).normalized();
      Vec3 d = mean - p;
      d -= d.dot(nrm) * nrm;
      next.col(v) = project_to_surface(body, p + 0.6 * d);
    }
    x = next;
  }
}

/// Every edge in exactly two triangles, in opposite directions (a closed, consistently oriented surface); else
/// the position of a vertex of an offending edge.
std::optional<Vec3> open_edge(const Mat3X& x, const std::vector<Tri>& tris) {
  std::map<std::pair<Index, Index>, int> directed;
  for (const auto& t : tris) {
    for (int c = 0; c < 3; ++c) ++directed[{t[c], t[(c + 1) % 3]}];
  }
  for (const auto& [e, count] : directed) {
    const auto back = directed.find({e.second, e.first});
    if (count != 1 || back == directed.end() || back->second != 1) return Vec3(x.col(e.first));
  }
  return std::nullopt;
}

/// Linear blend weights as harmonic functions on the surface (Laplace's equation on its edge graph): vertices
/// along the middle of a segment (its `core`, as fractions of its axis) follow that segment's joint alone, the
/// rest interpolate. Weights that fall off with the distance to each segment tear the crotch, where the two thighs'
/// surfaces meet and scissor apart; harmonic weights spread every joint's change over the free band around it.
void skin_weights(const Body& body, const Mat3X& x, const std::vector<Tri>& tris, Eigen::Matrix4Xi& joints,
                  Eigen::Matrix4Xd& weights) {
  const Index nv = x.cols();
  std::vector<int> fixed(static_cast<size_t>(nv), -1);
#pragma omp parallel for schedule(static)
  for (Index v = 0; v < nv; ++v) {
    double best = 1e300;
    const Segment* near = nullptr;
    for (const auto& s : body.segments) {
      const double d = round_cone_distance(s, x.col(v));
      if (d < best) {
        best = d;
        near = &s;
      }
    }
    const Vec3 ab = near->b - near->a;
    const double len2 = ab.squaredNorm();
    const double axial = len2 > 0.0 ? (x.col(v) - near->a).dot(ab) / len2 : 0.5;
    if (axial >= near->core[0] && axial <= near->core[1]) fixed[static_cast<size_t>(v)] = near->joint;
  }
  // Unknowns are the free vertices; L_ff W_f = −L_fs W_s with the graph Laplacian's unit edge weights.
  std::vector<Index> unknown(static_cast<size_t>(nv), -1);
  Index nf = 0;
  for (Index v = 0; v < nv; ++v) {
    if (fixed[static_cast<size_t>(v)] < 0) unknown[static_cast<size_t>(v)] = nf++;
  }
  std::vector<std::vector<Index>> nbr(static_cast<size_t>(nv));
  for (const auto& t : tris) {
    for (int c = 0; c < 3; ++c) nbr[static_cast<size_t>(t[c])].push_back(t[(c + 1) % 3]);
  }
  MatX w = MatX::Zero(nv, kNumJoints);
  for (Index v = 0; v < nv; ++v) {
    if (fixed[static_cast<size_t>(v)] >= 0) w(v, fixed[static_cast<size_t>(v)]) = 1.0;
  }
  if (nf > 0) {
    std::vector<Eigen::Triplet<double>> entries;
    MatX rhs = MatX::Zero(nf, kNumJoints);
    for (Index v = 0; v < nv; ++v) {
      const Index r = unknown[static_cast<size_t>(v)];
      if (r < 0) continue;
      // Closed surface: each vertex's outgoing directed edges are all of its edges.
      entries.emplace_back(r, r, static_cast<double>(nbr[static_cast<size_t>(v)].size()));
      for (Index u : nbr[static_cast<size_t>(v)]) {
        if (unknown[static_cast<size_t>(u)] >= 0) entries.emplace_back(r, unknown[static_cast<size_t>(u)], -1.0);
        else rhs.row(r) += w.row(u);
      }
    }
    Eigen::SparseMatrix<double> L(nf, nf);
    L.setFromTriplets(entries.begin(), entries.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(L);
    if (solver.info() != Eigen::Success) throw_error("mannequin: the skin weights' system is singular (a limb without a core)");
    const MatX wf = solver.solve(rhs);
    for (Index v = 0; v < nv; ++v) {
      if (unknown[static_cast<size_t>(v)] >= 0) w.row(v) = wf.row(unknown[static_cast<size_t>(v)]);
    }
  }
  joints.setZero(4, nv);
  weights.setZero(4, nv);
  for (Index v = 0; v < nv; ++v) {
    std::array<std::pair<double, int>, kNumJoints> order;
    for (int j = 0; j < kNumJoints; ++j) order[static_cast<size_t>(j)] = {std::max(w(v, j), 0.0), j};
    std::partial_sort(order.begin(), order.begin() + 4, order.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    double sum = 0.0;
    for (int k = 0; k < 4; ++k) sum += order[static_cast<size_t>(k)].first;
    for (int k = 0; k < 4; ++k) {
      const auto [wk, j] = order[static_cast<size_t>(k)];
      joints(k, v) = wk > 0.0 ? j : 0;
      weights(k, v) = wk / sum;
    }
  }
}

/// Periodic Catmull–Rom through samples at 0, 5, …, 95 % of the cycle (the 100 % sample equals the 0 % one).
double periodic_curve(const std::array<double, 20>& y, double phase) {
  const double s = (phase - std::floor(phase)) * 20.0;
  const int k = static_cast<int>(s);
  const double t = s - k;
  const auto at = [&](int i) { return y[static_cast<size_t>(((i % 20) + 20) % 20)]; };
  const double p0 = at(k - 1), p1 = at(k), p2 = at(k + 1), p3 = at(k + 2);
  return 0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t * t + (-p0 + 3 * p1 - 3 * p2 + p3) * t * t * t);
}

Eigen::Quaterniond about(const Vec3& axis, double degrees) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(degrees * kDeg, axis.normalized()));
}

double smoothstep(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

/// The joints' local rotations at gait phase `phase` with the gait's amplitude scaled by `amp` (0: bind pose).
std::array<Eigen::Quaterniond, kNumJoints> pose_rotations(double phase, double amp, double arm_swing) {
  std::array<Eigen::Quaterniond, kNumJoints> r;
  r.fill(Eigen::Quaterniond::Identity());
  const Vec3 lateral(0, 1, 0);  // flexion swings a limb forward: a rotation about −y
  for (int side = 0; side < 2; ++side) {
    const GaitAngles a = gait_angles(phase + (side == 0 ? 0.5 : 0.0));  // the right leg strikes at phase 0
    const int o = side == 0 ? 0 : 1;
    r[static_cast<size_t>(kThighL + o)] = about(-lateral, amp * a.hip);
    r[static_cast<size_t>(kShankL + o)] = about(lateral, amp * a.knee);
    r[static_cast<size_t>(kFootL + o)] = about(-lateral, amp * a.ankle);
    r[static_cast<size_t>(kUpperArmL + o)] = about(-lateral, amp * arm_swing * a.shoulder);
    r[static_cast<size_t>(kForearmL + o)] = about(-lateral, amp * arm_swing * a.elbow);
  }
  // Pelvis: transverse rotation ±4° (the swinging leg's side forward) and obliquity ±3° (the swing side drops);
  // the trunk turns against the pelvis.
  const double w = 2 * std::numbers::pi * phase;
  r[kPelvis] = about(Vec3::UnitZ(), amp * 4.0 * std::cos(w)) * about(Vec3::UnitX(), amp * 3.0 * std::sin(2 * w));
  r[kChest] = about(Vec3::UnitZ(), -amp * 3.0 * std::cos(w));
  return r;
}

/// World transforms of the joints for given local rotations, the pelvis at `root`.
std::array<Eigen::Affine3d, kNumJoints> forward_kinematics(const Body& body,
                                                            const std::array<Eigen::Quaterniond, kNumJoints>& rot,
                                                            const Vec3& root) {
  std::array<Eigen::Affine3d, kNumJoints> world;
  for (int j = 0; j < kNumJoints; ++j) {
    const int p = kParent[static_cast<size_t>(j)];
    Eigen::Affine3d local = Eigen::Affine3d::Identity();
    local.translate(p < 0 ? root : Vec3(body.joint_pos[static_cast<size_t>(j)] - body.joint_pos[static_cast<size_t>(p)]));
    local.rotate(rot[static_cast<size_t>(j)]);
    world[static_cast<size_t>(j)] = p < 0 ? local : world[static_cast<size_t>(p)] * local;
  }
  return world;
}

/// The pelvis height that puts the lowest sole point on the ground, and that point's x relative to the pelvis.
std::pair<double, double> ground(const Body& body, const std::array<Eigen::Quaterniond, kNumJoints>& rot,
                                 int* lowest = nullptr) {
  const Vec3 rest_root = body.joint_pos[kPelvis];
  const auto world = forward_kinematics(body, rot, rest_root);
  double zmin = 1e300, xrel = 0.0;
  for (int i = 0; i < 4; ++i) {
    const int foot = i < 2 ? kFootL : kFootR;
    const Vec3 p = world[static_cast<size_t>(foot)] * (body.soles[static_cast<size_t>(i)] - body.joint_pos[static_cast<size_t>(foot)]);
    if (p.z() < zmin) {
      zmin = p.z();
      xrel = p.x() - rest_root.x();
      if (lowest) *lowest = i;
    }
  }
  return {rest_root.z() - zmin, xrel};
}

}  // namespace

GaitAngles gait_angles(double phase) {
  // Approximate normative sagittal angles of level walking at natural cadence, every 5 % of the cycle from right
  // heel strike (after Winter 2009, "Biomechanics and Motor Control of Human Movement", Ch. 5, and Perry &
  // Burnfield 2010, "Gait Analysis"). The hip is the thigh's angle from the vertical (the hip angle plus the
  // pelvis' forward tilt, which this mannequin does not model): +25° at heel strike, −19° at toe-off, +29° in late
  // swing; knee 18° in loading response, 62° peak in swing; ankle −4° after heel strike, +10° in terminal stance,
  // −16° after toe-off.
  static const std::array<double, 20> hip = {25, 24, 22, 18, 13, 8, 3, -2, -7, -12, -17, -19, -14, -4, 8, 18, 25, 29, 29, 27};
  static const std::array<double, 20> knee = {3, 10, 16, 18, 16, 12, 8, 5, 4, 5, 9, 17, 30, 46, 58, 62, 56, 42, 24, 8};
  static const std::array<double, 20> ankle = {0, -4, -3, 1, 4, 6, 7, 8, 9, 10, 8, 2, -10, -16, -10, -3, 0, 1, 1, 0};
  GaitAngles a;
  a.hip = periodic_curve(hip, phase);
  a.knee = periodic_curve(knee, phase);
  a.ankle = periodic_curve(ankle, phase);
  // The arm swings against the leg of its side (forward while that leg extends): shoulder ≈ +8° ± 16°, elbow
  // 15° – 35° flexed, most when the arm is forward (Murray et al. 1967 range).
  const double hip_mid = 5.0, hip_amp = 24.0;
  a.shoulder = 4.0 - 16.0 * (a.hip - hip_mid) / hip_amp;
  a.elbow = 25.0 + 10.0 * (a.shoulder - 4.0) / 16.0;
  return a;
}

SkinnedMesh make_mannequin(const MannequinParams& m, const WalkParams& walk, MannequinInfo* info) {
  auto range = [](const char* name, double v, double lo, double hi) {
    if (!std::isfinite(v) || v < lo || v > hi) throw_error<InputError>("mannequin: {} = {} is outside [{}, {}]", name, v, lo, hi);
  };
  range("height", m.height, 1.2, 2.2);
  range("build", m.build, 0.7, 1.5);
  range("resolution", m.resolution, 0.003, 0.05);
  range("arm_abduction", m.arm_abduction, 5.0, 60.0);
  range("walk.period", walk.period, 0.5, 3.0);
  range("walk.stand", walk.stand, 0.0, 1e4);
  range("walk.ramp", walk.ramp, 0.0, 1e4);
  range("walk.duration", walk.duration, 0.0, 1e4);
  range("walk.key_rate", walk.key_rate, 1.0, 1000.0);
  range("walk.arm_swing", walk.arm_swing, 0.0, 3.0);

  const Body body = make_body(m);
  SkinnedMesh skin;
  // Where a limb is barely thicker than the grid, one alignment can put two sheets through one cell (a
  // non-manifold edge); another alignment of the grid usually does not.
  for (const double shift : {0.0, 0.37, 0.71, 0.19, 0.53}) {
    skin.tris.clear();
    surface_nets(body, m.resolution, shift, skin.rest, skin.tris);
    const auto bad = open_edge(skin.rest, skin.tris);
    if (!bad) break;
    if (shift == 0.53) {
      throw_error("mannequin: the surface is not a closed manifold near ({:.3f}, {:.3f}, {:.3f}) m at resolution {} "
                  "m; a finer resolution resolves it",
                  bad->x(), bad->y(), bad->z(), m.resolution);
    }
  }
  for (Index v = 0; v < skin.rest.cols(); ++v) skin.rest.col(v) = project_to_surface(body, skin.rest.col(v));
  relax(body, skin.rest, skin.tris, 8);
  skin_weights(body, skin.rest, skin.tris, skin.joints, skin.weights);

  skin.joint_names.assign(kJointNames.begin(), kJointNames.end());
  skin.parent.assign(kParent.begin(), kParent.end());
  skin.rest_local.resize(kNumJoints);
  skin.inverse_bind.resize(kNumJoints);
  skin.tracks.resize(kNumJoints);
  for (int j = 0; j < kNumJoints; ++j) {
    const int p = kParent[static_cast<size_t>(j)];
    skin.rest_local[static_cast<size_t>(j)].translation =
        p < 0 ? body.joint_pos[static_cast<size_t>(j)] : Vec3(body.joint_pos[static_cast<size_t>(j)] - body.joint_pos[static_cast<size_t>(p)]);
    skin.inverse_bind[static_cast<size_t>(j)] = Eigen::Translation3d(-body.joint_pos[static_cast<size_t>(j)]);
  }

  // Forward speed: the lowest sole point is the one carrying the body, so the pelvis moves at the speed that
  // point moves backward relative to it; its mean over a cycle makes the stance foot stand still on average.
  double speed = 0.0;
  if (walk.forward) {
    const int samples = 400;
    for (int i = 0; i < samples; ++i) {
      const double ph = static_cast<double>(i) / samples, dph = 1e-4;
      int lowest = 0;
      ground(body, pose_rotations(ph, 1.0, walk.arm_swing), &lowest);
      const auto world0 = forward_kinematics(body, pose_rotations(ph, 1.0, walk.arm_swing), Vec3::Zero());
      const auto world1 = forward_kinematics(body, pose_rotations(ph + dph, 1.0, walk.arm_swing), Vec3::Zero());
      const int foot = lowest < 2 ? kFootL : kFootR;
      const Vec3 sole = body.soles[static_cast<size_t>(lowest)] - body.joint_pos[static_cast<size_t>(foot)];
      const double dx = (world1[static_cast<size_t>(foot)] * sole).x() - (world0[static_cast<size_t>(foot)] * sole).x();
      speed += -dx / (dph * walk.period);
    }
    speed = std::max(speed / samples, 0.0);
  }

  const auto keys = static_cast<size_t>(std::ceil(walk.duration * walk.key_rate)) + 1;
  double x = 0.0, last_t = 0.0;
  for (size_t k = 0; k < keys; ++k) {
    const double t = std::min(static_cast<double>(k) / walk.key_rate, walk.duration);
    const double amp = walk.ramp > 0.0 ? smoothstep((t - walk.stand) / walk.ramp) : (t >= walk.stand ? 1.0 : 0.0);
    const double phase = std::max(t - walk.stand, 0.0) / walk.period;
    const auto rot = pose_rotations(phase, amp, walk.arm_swing);
    // The speed follows the amplitude (trapezoidal integration of amp · speed).
    if (k > 0) {
      const double amp0 = walk.ramp > 0.0 ? smoothstep((last_t - walk.stand) / walk.ramp) : (last_t >= walk.stand ? 1.0 : 0.0);
      x += 0.5 * (amp0 + amp) * speed * (t - last_t);
    }
    last_t = t;
    const double z = ground(body, rot).first;
    for (int j = 0; j < kNumJoints; ++j) {
      auto& tr = skin.tracks[static_cast<size_t>(j)];
      const auto& q = rot[static_cast<size_t>(j)];
      tr.rotation.times.push_back(t);
      tr.rotation.values.emplace_back(q.x(), q.y(), q.z(), q.w());
    }
    auto& root = skin.tracks[kPelvis].translation;
    root.times.push_back(t);
    root.values.emplace_back(body.joint_pos[kPelvis].x() + x, body.joint_pos[kPelvis].y(), z);
    if (t >= walk.duration) break;
  }

  if (info) {
    info->speed = speed;
    info->stride = speed * walk.period;
    double vol = 0.0, min_angle = 180.0;
    for (const auto& t : skin.tris) {
      const Vec3 a = skin.rest.col(t[0]), b = skin.rest.col(t[1]), c = skin.rest.col(t[2]);
      vol += a.dot(b.cross(c)) / 6.0;
      const std::array<Vec3, 3> p = {a, b, c};
      for (int i = 0; i < 3; ++i) {
        const Vec3 u = p[static_cast<size_t>((i + 1) % 3)] - p[static_cast<size_t>(i)];
        const Vec3 w = p[static_cast<size_t>((i + 2) % 3)] - p[static_cast<size_t>(i)];
        min_angle = std::min(min_angle, std::atan2(u.cross(w).norm(), u.dot(w)) / kDeg);
      }
    }
    info->volume = vol;
    info->min_angle = min_angle;
  }
  skin.validate("mannequin");
  return skin;
}

}  // namespace mgcloth::geometry
