#include <mgcloth/collision/distance.hpp>

#include "collision/distance_reference.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <unsupported/Eigen/AutoDiff>

#include <array>
#include <cmath>
#include <map>
#include <random>
#include <set>

namespace mgcloth::collision {
namespace {

using testing::random_vec;
using testing::reference_edge_edge_sq;
using testing::reference_point_triangle_sq;

using Points = std::array<Vec3, 4>;  // (p, t0, t1, t2) or (a0, a1, b0, b1)

constexpr int kPointTriangleTypes = 7;
constexpr int kEdgeEdgeTypes = 9;

double pt_exact(const Points& x) { return point_triangle_distance_sq(x[0], x[1], x[2], x[3]); }
double ee_exact(const Points& x) { return edge_edge_distance_sq(x[0], x[1], x[2], x[3]); }
PointTriangleType pt_type(const Points& x) { return point_triangle_type(x[0], x[1], x[2], x[3]); }
EdgeEdgeType ee_type(const Points& x) { return edge_edge_type(x[0], x[1], x[2], x[3]); }
double pt_typed(const Points& x, int type, Vec12* g = nullptr, Mat12* H = nullptr) {
  return point_triangle_distance_sq(x[0], x[1], x[2], x[3], PointTriangleType(type), g, H);
}
double ee_typed(const Points& x, int type, Vec12* g = nullptr, Mat12* H = nullptr) {
  return edge_edge_distance_sq(x[0], x[1], x[2], x[3], EdgeEdgeType(type), g, H);
}

Vec12 stack(const Points& x) {
  Vec12 v;
  for (int i = 0; i < 4; ++i) v.segment<3>(3 * i) = x[i];
  return v;
}
Points unstack(const Vec12& v) { return {v.segment<3>(0), v.segment<3>(3), v.segment<3>(6), v.segment<3>(9)}; }

// Largest squared extent of the configuration: the scale of the tolerances.
double extent_sq(const Points& x) {
  double m = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) m = std::max(m, (x[i] - x[j]).squaredNorm());
  return m;
}

// Random point–triangle configurations, each kind a family the classification must survive.
Points random_point_triangle(std::mt19937_64& rng, int kind) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  Points x{random_vec(rng), random_vec(rng), random_vec(rng), random_vec(rng)};
  const Vec3 e1 = x[2] - x[1], e2 = x[3] - x[1];
  switch (kind) {
    case 0: break;
    case 1:  // p near the plane, inside or outside
      x[0] = x[1] + (3 * u01(rng) - 1) * e1 + (3 * u01(rng) - 1) * e2 + 1e-3 * u01(rng) * e1.cross(e2).normalized();
      break;
    case 2: x[2] = x[1]; break;          // two vertices coincide
    case 3: x[2] = x[3] = x[1]; break;   // all three coincide
    case 4: x[3] = x[1] + (3 * u01(rng) - 1) * e1; break;  // collinear
    case 5: {                                                // nearly collinear, across the threshold
      const double eps = std::pow(10.0, -3 - 6 * u01(rng));
      x[3] = x[1] + (3 * u01(rng) - 1) * e1 + random_vec(rng, eps);
      break;
    }
    case 6: {  // p on the triangle: a vertex, an edge or the interior
      const double a = u01(rng), b = u01(rng) * (1 - a);
      const int which = int(4 * u01(rng));
      x[0] = which == 0 ? x[1] : which == 1 ? Vec3(x[1] + a * e1) : x[1] + a * e1 + b * e2;
      break;
    }
    case 7: {  // far from unit scale
      const double scale = u01(rng) < 0.5 ? 1e-3 : 1e3;
      for (auto& v : x) v *= scale;
      break;
    }
    default: break;
  }
  return x;
}

Points random_edge_edge(std::mt19937_64& rng, int kind) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  Points x{random_vec(rng), random_vec(rng), random_vec(rng), random_vec(rng)};
  const Vec3 u = x[1] - x[0];
  switch (kind) {
    case 0: break;
    case 1: x[3] = x[2] + (4 * u01(rng) - 2) * u; break;  // parallel
    case 2:                                                // collinear, overlapping or not
      x[2] = x[0] + (4 * u01(rng) - 2) * u;
      x[3] = x[0] + (4 * u01(rng) - 2) * u;
      break;
    case 3: x[1] = x[0]; break;              // one degenerate
    case 4: x[1] = x[0], x[3] = x[2]; break;  // both degenerate
    case 5: {                                 // nearly parallel, across the threshold
      const double eps = std::pow(10.0, -2 - 8 * u01(rng));
      x[2] = x[0] + (2 * u01(rng) - 0.5) * u + random_vec(rng, 0.1);
      x[3] = x[2] + (4 * u01(rng) - 2) * u + random_vec(rng, eps);
      break;
    }
    case 6: {  // crossing: b passes through a point of a
      const Vec3 m = x[0] + u01(rng) * u, w = random_vec(rng);
      x[2] = m - u01(rng) * w;
      x[3] = m + u01(rng) * w;
      break;
    }
    case 7: x[2] = x[0]; break;  // shared endpoint
    case 8: {
      const double scale = u01(rng) < 0.5 ? 1e-3 : 1e3;
      for (auto& v : x) v *= scale;
      break;
    }
    default: break;
  }
  return x;
}

constexpr int kPointTriangleKinds = 8;
constexpr int kEdgeEdgeKinds = 9;

// Exact distance against brute force, within the threshold's documented error (kDegenerateSin2 = 1e-12 of the
// squared extent) and a relative 1e-10.
TEST(Distance, PointTriangleMatchesBruteForce) {
  std::mt19937_64 rng(1);
  std::set<int> types;
  for (int kind = 0; kind < kPointTriangleKinds; ++kind)
    for (int trial = 0; trial < 250; ++trial) {
      const Points x = random_point_triangle(rng, kind);
      const double d2 = pt_exact(x);
      const double ref = reference_point_triangle_sq(x[0], x[1], x[2], x[3]);
      const double tol = 1e-12 * extent_sq(x) + 1e-10 * ref;
      ASSERT_TRUE(std::isfinite(d2));
      EXPECT_NEAR(d2, ref, tol) << "kind " << kind << " trial " << trial << " type " << int(pt_type(x));
      types.insert(int(pt_type(x)));
    }
  EXPECT_EQ(types.size(), size_t(kPointTriangleTypes));
}

TEST(Distance, EdgeEdgeMatchesBruteForce) {
  std::mt19937_64 rng(2);
  std::set<int> types;
  for (int kind = 0; kind < kEdgeEdgeKinds; ++kind)
    for (int trial = 0; trial < 250; ++trial) {
      const Points x = random_edge_edge(rng, kind);
      const double d2 = ee_exact(x);
      const double ref = reference_edge_edge_sq(x[0], x[1], x[2], x[3]);
      const double tol = 1e-12 * extent_sq(x) + 1e-10 * ref;
      ASSERT_TRUE(std::isfinite(d2));
      EXPECT_NEAR(d2, ref, tol) << "kind " << kind << " trial " << trial << " type " << int(ee_type(x));
      types.insert(int(ee_type(x)));
    }
  EXPECT_EQ(types.size(), size_t(kEdgeEdgeTypes));
}

// The chosen type's formula gives the exact distance, and degenerate pairs never get the plane / line–line type.
TEST(Distance, TypeValueIsTheExactDistance) {
  std::mt19937_64 rng(3);
  for (int kind = 0; kind < kPointTriangleKinds; ++kind)
    for (int trial = 0; trial < 200; ++trial) {
      const Points x = random_point_triangle(rng, kind);
      const int type = int(pt_type(x));
      EXPECT_NEAR(pt_typed(x, type), pt_exact(x), 1e-14 * pt_exact(x)) << "kind " << kind;
      if (kind == 2 || kind == 3 || kind == 4) {
        EXPECT_NE(type, int(PointTriangleType::P_T));
      }
    }
  for (int kind = 0; kind < kEdgeEdgeKinds; ++kind)
    for (int trial = 0; trial < 200; ++trial) {
      const Points x = random_edge_edge(rng, kind);
      const int type = int(ee_type(x));
      EXPECT_NEAR(ee_typed(x, type), ee_exact(x), 1e-14 * ee_exact(x)) << "kind " << kind;
      if (kind >= 1 && kind <= 4) {
        EXPECT_NE(type, int(EdgeEdgeType::EA_EB)) << "kind " << kind;
      }
    }
}

// Lines crossing (in projection) inside both segments at height h, at angles through parallel: the line–line formula
// holds the distance to h above the threshold; below it an endpoint type is chosen, off by at most the threshold's
// sin²·ℓ², so the distance stays continuous through the switch.
TEST(Distance, NearParallelSegmentsPickAnEndpointType) {
  for (const double h : {0.0, 1e-6, 1e-2}) {
    const Vec3 a0(-1, 0, 0), a1(1, 0, 0), c(0.1, 0, h);
    for (const double theta : {1e-1, 1e-3, 1e-5, 2e-6, 5e-7, 1e-7, 1e-9, 0.0, -1e-9, -1e-7, -1e-3}) {
      const Vec3 dir(std::cos(theta), std::sin(theta), 0);
      const Points x{a0, a1, c - dir, c + dir};
      const EdgeEdgeType type = ee_type(x);
      const double sin2 = std::sin(theta) * std::sin(theta);
      if (sin2 > 1.1e-12) {
        EXPECT_EQ(type, EdgeEdgeType::EA_EB) << theta;
      } else if (sin2 < 0.9e-12) {
        EXPECT_NE(type, EdgeEdgeType::EA_EB) << theta;
      }
      EXPECT_NEAR(ee_exact(x), h * h, 1e-12 * 4 + 1e-15) << "h " << h << " theta " << theta;
      Vec12 g;
      Mat12 H;
      ee_typed(x, int(type), &g, &H);
      EXPECT_TRUE(g.allFinite() && H.allFinite());
    }
  }
}

// Every type's formula, asked for on degenerate input (a stale type), returns finite values and derivatives.
TEST(Distance, DegenerateInputNeverGivesNaN) {
  std::mt19937_64 rng(4);
  const Vec3 o(0.3, -0.2, 0.1);
  std::vector<Points> cases{{o, o, o, o}, {Vec3(1, 2, 3), o, o, o}};
  for (int trial = 0; trial < 50; ++trial) {
    for (int kind : {2, 3, 4, 5, 6}) cases.push_back(random_point_triangle(rng, kind));
    for (int kind : {1, 2, 3, 4, 5, 6, 7}) cases.push_back(random_edge_edge(rng, kind));
  }
  for (const Points& x : cases) {
    ASSERT_TRUE(std::isfinite(pt_exact(x)) && std::isfinite(ee_exact(x)));
    Vec12 g;
    Mat12 H;
    for (int type = 0; type < kPointTriangleTypes; ++type) {
      ASSERT_TRUE(std::isfinite(pt_typed(x, type, &g, &H))) << type;
      ASSERT_TRUE(g.allFinite() && H.allFinite()) << type;
    }
    for (int type = 0; type < kEdgeEdgeTypes; ++type) {
      ASSERT_TRUE(std::isfinite(ee_typed(x, type, &g, &H))) << type;
      ASSERT_TRUE(g.allFinite() && H.allFinite()) << type;
    }
  }
}

// --- Derivatives. ---

// The type must not change within ±h of any coordinate, so that the exact distance is the typed formula there.
template <class TypeOf>
bool type_stable(const Points& x, TypeOf type_of, double h) {
  const auto type = type_of(x);
  const Vec12 v = stack(x);
  for (int k = 0; k < 12; ++k)
    for (const double s : {-h, h}) {
      Vec12 w = v;
      w[k] += s;
      if (type_of(unstack(w)) != type) return false;
    }
  return true;
}

// Central differences of the exact (untyped) distance against the typed gradient, and of the typed gradient against
// the typed Hessian.
template <class Exact, class Typed>
void check_derivatives(const Points& x, int type, Exact exact, Typed typed, const char* what) {
  const double h = 1e-5;
  Vec12 g;
  Mat12 H;
  typed(x, type, &g, &H);
  Vec12 g_fd;
  Mat12 H_fd;
  const Vec12 v = stack(x);
  for (int k = 0; k < 12; ++k) {
    Vec12 vp = v, vm = v;
    vp[k] += h;
    vm[k] -= h;
    g_fd[k] = (exact(unstack(vp)) - exact(unstack(vm))) / (2 * h);
    Vec12 gp, gm;
    typed(unstack(vp), type, &gp, nullptr);
    typed(unstack(vm), type, &gm, nullptr);
    H_fd.col(k) = (gp - gm) / (2 * h);
  }
  EXPECT_LE((g_fd - g).norm(), 1e-6 * g.norm() + 1e-10) << what << " type " << type << " gradient";
  EXPECT_LE((H_fd - H).norm(), 1e-5 * H.norm() + 1e-8) << what << " type " << type << " Hessian";
  EXPECT_LE((H - H.transpose()).norm(), 1e-12 * H.norm()) << what << " type " << type << " symmetry";
}

// Well inside a region: no coincident or nearly parallel features, not touching.
bool well_conditioned(const Points& x, double d2) {
  if (d2 < 1e-2) return false;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j)
      if ((x[i] - x[j]).squaredNorm() < 1e-2) return false;
  return true;
}

bool all_reached(std::map<int, int>& count, int num_types, int target) {
  for (int t = 0; t < num_types; ++t)
    if (count[t] < target) return false;
  return true;
}

TEST(Distance, PointTriangleDerivativesMatchFiniteDifferences) {
  std::mt19937_64 rng(5);
  std::map<int, int> checked;
  for (int trial = 0; trial < 20000 && !all_reached(checked, kPointTriangleTypes, 20); ++trial) {
    Points x = random_point_triangle(rng, 0);
    x[0] *= 2;  // reach the vertex regions more often
    const int type = int(pt_type(x));
    const Vec3 n = (x[2] - x[1]).cross(x[3] - x[1]);
    if (n.squaredNorm() < 1e-2 * (x[2] - x[1]).squaredNorm() * (x[3] - x[1]).squaredNorm()) continue;
    if (checked[type] >= 20 || !well_conditioned(x, pt_exact(x)) || !type_stable(x, pt_type, 1e-4)) continue;
    check_derivatives(x, type, pt_exact, [](const Points& y, int t, Vec12* g, Mat12* H) { return pt_typed(y, t, g, H); },
                      "point-triangle");
    ++checked[type];
  }
  for (int type = 0; type < kPointTriangleTypes; ++type) EXPECT_EQ(checked[type], 20) << "type " << type;
}

TEST(Distance, EdgeEdgeDerivativesMatchFiniteDifferences) {
  std::mt19937_64 rng(6);
  std::map<int, int> checked;
  for (int trial = 0; trial < 50000 && !all_reached(checked, kEdgeEdgeTypes, 20); ++trial) {
    Points x = random_edge_edge(rng, 0);
    x[2] += random_vec(rng);  // spread the pairs so that endpoint–endpoint types occur
    x[3] += random_vec(rng);
    const int type = int(ee_type(x));
    const Vec3 u = x[1] - x[0], v = x[3] - x[2];
    if (u.cross(v).squaredNorm() < 1e-2 * u.squaredNorm() * v.squaredNorm()) continue;
    if (checked[type] >= 20 || !well_conditioned(x, ee_exact(x)) || !type_stable(x, ee_type, 1e-4)) continue;
    check_derivatives(x, type, ee_exact, [](const Points& y, int t, Vec12* g, Mat12* H) { return ee_typed(y, t, g, H); },
                      "edge-edge");
    ++checked[type];
  }
  for (int type = 0; type < kEdgeEdgeTypes; ++type) EXPECT_EQ(checked[type], 20) << "type " << type;
}

// The same derivatives against forward-mode automatic differentiation of the defining formulas (nested for the
// Hessian), to round-off rather than to the finite differences' truncation.
using AD1 = Eigen::AutoDiffScalar<Vec12>;
using AD2 = Eigen::AutoDiffScalar<Eigen::Matrix<AD1, 12, 1>>;
using Vec3AD = Eigen::Matrix<AD2, 3, 1>;

template <class S>
S point_line_formula(const Eigen::Matrix<S, 3, 1>& p, const Eigen::Matrix<S, 3, 1>& a, const Eigen::Matrix<S, 3, 1>& b) {
  const Eigen::Matrix<S, 3, 1> e = b - a;
  return (p - a).cross(e).squaredNorm() / e.squaredNorm();
}
template <class S>
S plane_formula(const Eigen::Matrix<S, 3, 1>& r, const Eigen::Matrix<S, 3, 1>& e1, const Eigen::Matrix<S, 3, 1>& e2) {
  const Eigen::Matrix<S, 3, 1> n = e1.cross(e2);
  const S g = n.dot(r);
  return g * g / n.squaredNorm();
}

// Value, gradient and Hessian of f(x) by nested forward AD.
template <class F>
void autodiff(const Vec12& v, F f, Vec12& g, Mat12& H) {
  std::array<Vec3AD, 4> x;
  for (int k = 0; k < 12; ++k) {
    AD1 inner(v[k], 12, k);
    Eigen::Matrix<AD1, 12, 1> outer_d = Eigen::Matrix<AD1, 12, 1>::Constant(AD1(0.0, Vec12::Zero()));
    outer_d[k] = AD1(1.0, Vec12::Zero());
    x[k / 3][k % 3] = AD2(inner, outer_d);
  }
  const AD2 r = f(x);
  for (int i = 0; i < 12; ++i) {
    g[i] = r.derivatives()[i].value();
    H.row(i) = r.derivatives()[i].derivatives().transpose();
  }
}

TEST(Distance, DerivativesMatchAutoDiff) {
  using T = PointTriangleType;
  using E = EdgeEdgeType;
  std::mt19937_64 rng(7);
  const auto pt_formula = [](int type) {
    return [type](const std::array<Vec3AD, 4>& x) -> AD2 {
      switch (T(type)) {
        case T::P_T0: return (x[0] - x[1]).squaredNorm();
        case T::P_T1: return (x[0] - x[2]).squaredNorm();
        case T::P_T2: return (x[0] - x[3]).squaredNorm();
        case T::P_E0: return point_line_formula(x[0], x[1], x[2]);
        case T::P_E1: return point_line_formula(x[0], x[2], x[3]);
        case T::P_E2: return point_line_formula(x[0], x[3], x[1]);
        case T::P_T: return plane_formula<AD2>(x[0] - x[1], x[2] - x[1], x[3] - x[1]);
      }
      return AD2(0.0);
    };
  };
  const auto ee_formula = [](int type) {
    return [type](const std::array<Vec3AD, 4>& x) -> AD2 {
      switch (E(type)) {
        case E::EA0_EB0: return (x[0] - x[2]).squaredNorm();
        case E::EA0_EB1: return (x[0] - x[3]).squaredNorm();
        case E::EA1_EB0: return (x[1] - x[2]).squaredNorm();
        case E::EA1_EB1: return (x[1] - x[3]).squaredNorm();
        case E::EA_EB0: return point_line_formula(x[2], x[0], x[1]);
        case E::EA_EB1: return point_line_formula(x[3], x[0], x[1]);
        case E::EA0_EB: return point_line_formula(x[0], x[2], x[3]);
        case E::EA1_EB: return point_line_formula(x[1], x[2], x[3]);
        case E::EA_EB: return plane_formula<AD2>(x[2] - x[0], x[1] - x[0], x[3] - x[2]);
      }
      return AD2(0.0);
    };
  };
  for (int trial = 0; trial < 20; ++trial) {
    const Points x = random_point_triangle(rng, 0);
    Vec12 g, g_ad;
    Mat12 H, H_ad;
    for (int type = 0; type < kPointTriangleTypes; ++type) {
      const double f = pt_typed(x, type, &g, &H);
      autodiff(stack(x), pt_formula(type), g_ad, H_ad);
      EXPECT_LE((g - g_ad).norm(), 1e-10 * g_ad.norm() + 1e-12) << "point-triangle type " << type;
      EXPECT_LE((H - H_ad).norm(), 1e-9 * H_ad.norm() + 1e-12) << "point-triangle type " << type;
      EXPECT_NEAR(f, pt_typed(x, type), 0.0);  // derivatives do not change the value
    }
    const Points y = random_edge_edge(rng, 0);
    for (int type = 0; type < kEdgeEdgeTypes; ++type) {
      ee_typed(y, type, &g, &H);
      autodiff(stack(y), ee_formula(type), g_ad, H_ad);
      EXPECT_LE((g - g_ad).norm(), 1e-10 * g_ad.norm() + 1e-12) << "edge-edge type " << type;
      EXPECT_LE((H - H_ad).norm(), 1e-9 * H_ad.norm() + 1e-12) << "edge-edge type " << type;
    }
  }
}

// --- Continuity across type boundaries. ---

// Moving every point by at most δ changes the distance between the primitives by at most 2δ (each point of either
// primitive moves by at most δ). Along random straight paths through the regions the exact distance must obey that
// at every step, and where the type changes the two types' formulas must agree at the crossing to within a few steps
// (both equal the exact distance on their common boundary; a step may skip a thin region in between).
template <class Exact, class TypeOf, class Typed>
void check_continuity(std::mt19937_64& rng, Points (*make)(std::mt19937_64&, int), Exact exact, TypeOf type_of,
                      Typed typed, int num_types, const char* what) {
  std::set<std::pair<int, int>> transitions;
  std::set<int> seen;
  const int steps = 2000;
  for (int path = 0; path < 60; ++path) {
    const Points start = make(rng, 0);
    Points vel;
    for (auto& v : vel) v = random_vec(rng, 0.3);
    vel[0] = random_vec(rng, 3.0);  // the first point sweeps across the others' regions
    const double dt = 1.0 / steps;
    double max_step = 0;
    for (const auto& v : vel) max_step = std::max(max_step, v.norm() * dt);
    Points x = start;
    double d = std::sqrt(exact(x));
    int type = int(type_of(x));
    for (int k = 1; k <= steps; ++k) {
      Points y;
      for (int i = 0; i < 4; ++i) y[i] = start[i] + (k * dt - 0.5) * vel[i];
      const double dy = std::sqrt(exact(y));
      const int ty = int(type_of(y));
      if (k > 1) {
        ASSERT_LE(std::abs(dy - d), 2 * max_step * (1 + 1e-9) + 1e-12) << what << " path " << path << " step " << k;
        if (ty != type) {
          transitions.insert({type, ty});
          EXPECT_NEAR(std::sqrt(typed(y, type)), std::sqrt(typed(y, ty)), 10 * max_step)
              << what << " types " << type << " -> " << ty;
        }
      }
      x = y, d = dy, type = ty;
      seen.insert(ty);
    }
  }
  EXPECT_EQ(seen.size(), size_t(num_types)) << what;
  EXPECT_GE(transitions.size(), size_t(num_types)) << what;
}

TEST(Distance, PointTriangleContinuousAcrossTypes) {
  std::mt19937_64 rng(8);
  check_continuity(rng, random_point_triangle, pt_exact, pt_type, [](const Points& y, int t) { return pt_typed(y, t); },
                   kPointTriangleTypes, "point-triangle");
}

TEST(Distance, EdgeEdgeContinuousAcrossTypes) {
  std::mt19937_64 rng(9);
  check_continuity(rng, random_edge_edge, ee_exact, ee_type, [](const Points& y, int t) { return ee_typed(y, t); },
                   kEdgeEdgeTypes, "edge-edge");
}

}  // namespace
}  // namespace mgcloth::collision
