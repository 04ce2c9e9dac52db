// Lagged cloth–cloth friction: the frozen contact frames, the smoothed Coulomb energy's derivatives and its
// coefficients per pair of cloths.
#include <mgcloth/collision/distance.hpp>
#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/physics/cloth_contact.hpp>
#include <mgcloth/physics/cloth_friction.hpp>

#include "contact_fixtures.hpp"
#include "term_checks.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <random>
#include <set>

namespace mgcloth::physics {
namespace {

using fixtures::sheet;

/// Two small sheets half a layer apart, jittered and shifted so that every pair type is inside the layer.
struct TwoSheets {
  VecX x;
  std::vector<ContactSurface> surfaces;
  std::unique_ptr<ClothContact> contact;
  explicit TwoSheets(unsigned seed) {
    surfaces.push_back(sheet("a", 0.02, 16, 0.0, 0, x));
    surfaces.push_back(sheet("b", 0.02, 16, 0.5e-3, static_cast<Index>(x.size() / 3), x));
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-0.15e-3, 0.15e-3);
    for (Index i = 0; i < x.size(); ++i) x[i] += u(rng);
    for (Index i = surfaces[1].offset; i < x.size() / 3; ++i) x.segment<2>(3 * i) += Vec2(0.0031, 0.0017);
    contact = std::make_unique<ClothContact>(surfaces, num_points(), ClothContactParams{});
  }
  Index num_points() const { return static_cast<Index>(x.size() / 3); }
  std::vector<std::string> names() const { return {"a", "b"}; }
};

Vec3 at(const VecX& x, Index i) { return x.segment<3>(3 * i); }

TEST(ClothFriction, MollifiedEnergyMatchesFiniteDifferencesAndIsConvex) {
  const double eps = 1e-5, ml = 2.0;
  // u = 0, sticking (well inside and just below ε), just above ε and far into sliding.
  for (const Vec2& u : {Vec2(0.0, 0.0), Vec2(2e-6, -1e-6), Vec2(0.6e-5, 0.79e-5), Vec2(0.6e-5, 0.81e-5),
                        Vec2(-3e-4, 1e-4)}) {
    Vec2 g;
    Mat2 H;
    const double e = ClothFriction::element_energy(ml, eps, u, &g, &H);
    EXPECT_GE(e, 0.0);
    // A step far below ε: at u = 0 the Hessian is continuous but has a kink (−(y/ε²)ûûᵀ), so differences cost h/ε².
    const double h = 1e-6 * eps;
    for (int i = 0; i < 2; ++i) {
      const Vec2 d = Vec2::Unit(i) * h;
      Vec2 gp, gm;
      const double fd = (ClothFriction::element_energy(ml, eps, u + d, &gp, nullptr) -
                         ClothFriction::element_energy(ml, eps, u - d, &gm, nullptr)) / (2 * h);
      EXPECT_NEAR(g[i], fd, 1e-6 * ml) << u.transpose();
      EXPECT_LE((H.col(i) - (gp - gm) / (2 * h)).norm(), 1e-5 * ml / eps) << u.transpose();
    }
    EXPECT_LE((H - H.transpose()).norm(), 1e-12 * H.norm());
    EXPECT_GE(Eigen::SelfAdjointEigenSolver<Mat2>(H).eigenvalues().minCoeff(), -1e-12 * ml / eps) << u.transpose();
    // Coulomb: the force never exceeds μλ, and reaches it once sliding.
    EXPECT_LE(g.norm(), ml * (1 + 1e-12));
    if (u.norm() >= eps) {
      EXPECT_NEAR(g.norm(), ml, 1e-12 * ml);
    }
  }
  // C¹ (indeed C²) where sticking turns into sliding: force and curvature continuous at ‖u‖ = ε.
  Vec2 gl, gr;
  Mat2 Hl, Hr;
  ClothFriction::element_energy(ml, eps, Vec2(eps * (1 - 1e-9), 0.0), &gl, &Hl);
  ClothFriction::element_energy(ml, eps, Vec2(eps * (1 + 1e-9), 0.0), &gr, &Hr);
  EXPECT_NEAR((gl - gr).norm(), 0.0, 1e-8 * ml);
  EXPECT_NEAR((Hl - Hr).norm(), 0.0, 1e-6 * ml / eps);
}

TEST(ClothFriction, FramesHoldTheNearestPointsNormalForceAndAnOrthonormalTangentBasis) {
  std::set<int> kinds;  // nearest-feature types seen (edge–edge types offset by 100)
  for (unsigned seed : {1u, 2u, 3u}) {
    TwoSheets t(seed);
    const auto frames = t.contact->contact_frames(t.x);
    ASSERT_EQ(static_cast<Index>(frames.size()), t.contact->stats(t.x).pairs);
    for (const auto& f : frames) {
      const Vec3 rel = f.c[0] * at(t.x, f.v[0]) + f.c[1] * at(t.x, f.v[1]) + f.c[2] * at(t.x, f.v[2]) +
                       f.c[3] * at(t.x, f.v[3]);
      const Vec3 a = at(t.x, f.v[0]), b = at(t.x, f.v[1]), c = at(t.x, f.v[2]), e = at(t.x, f.v[3]);
      kinds.insert(f.edge_edge ? 100 + static_cast<int>(collision::edge_edge_type(a, b, c, e))
                               : static_cast<int>(collision::point_triangle_type(a, b, c, e)));
      const double d2 = f.edge_edge ? collision::edge_edge_distance_sq(a, b, c, e)
                                    : collision::point_triangle_distance_sq(a, b, c, e);
      // The weights pick the nearest points: their difference is as long as the pair's distance.
      EXPECT_NEAR(rel.squaredNorm(), d2, 1e-9 * d2);
      // Each side's weights are a convex combination (translation moves no relative position).
      const int split = f.edge_edge ? 2 : 1;
      double sa = 0, sb = 0;
      for (int i = 0; i < 4; ++i) {
        (i < split ? sa : sb) += f.c[static_cast<size_t>(i)];
        const double w = i < split ? f.c[static_cast<size_t>(i)] : -f.c[static_cast<size_t>(i)];
        EXPECT_GE(w, -1e-12);
        EXPECT_LE(w, 1 + 1e-12);
      }
      EXPECT_NEAR(sa, 1.0, 1e-12);
      EXPECT_NEAR(sb, -1.0, 1e-12);
      EXPECT_NEAR((f.normal - rel.normalized()).norm(), 0.0, 1e-12);
      EXPECT_LE((f.tangent.transpose() * f.tangent - Mat2::Identity()).norm(), 1e-12);
      EXPECT_LE((f.tangent.transpose() * f.normal).norm(), 1e-12);
      EXPECT_GT(f.normal_force, 0.0);
      EXPECT_EQ(f.surface_a, f.v[0] < t.surfaces[1].offset ? 0 : 1);
      EXPECT_EQ(f.surface_b, f.v[split] < t.surfaces[1].offset ? 0 : 1);
    }
  }
  // Vertex–triangle and edge–edge pairs, with interior and boundary nearest features.
  EXPECT_TRUE(kinds.count(static_cast<int>(collision::PointTriangleType::P_T)));
  EXPECT_TRUE(kinds.count(100 + static_cast<int>(collision::EdgeEdgeType::EA_EB)));
  EXPECT_GE(kinds.size(), 4u);
}

TEST(ClothFriction, GradientAndHessianMatchFiniteDifferencesSlidingAndSticking) {
  const double h = 0.01;
  ClothFrictionParams params;
  params.friction = 0.4;
  for (unsigned seed : {1u, 2u, 3u}) {
    TwoSheets t(seed);
    ClothFriction f(t.num_points(), t.names(), params);
    f.start_step(t.x, t.contact->contact_frames(t.x), h);
    ASSERT_GT(f.num_pairs(), 10);
    const double eps = f.slip_threshold();
    EXPECT_DOUBLE_EQ(eps, params.static_velocity * h);
    std::mt19937 rng(seed);
    std::normal_distribution<double> n01(0.0, 1.0);
    // Moves of the top sheet well inside ε (sticking) and far beyond it (sliding), each point jittered on its own.
    for (double scale : {0.1 * eps, 30.0 * eps}) {
      VecX x = t.x;
      for (Index i = t.surfaces[1].offset; i < t.num_points(); ++i)
        x.segment<3>(3 * i) += scale * Vec3(1.0 + 0.3 * n01(rng), 0.5 + 0.3 * n01(rng), 0.3 * n01(rng));
      f.update_stencils(x);
      EXPECT_GT(f.value(x), 0.0);
      SCOPED_TRACE(scale);
      check_term(f, x, 1e-5);
    }
  }
}

TEST(ClothFriction, ForceOpposesTheSlideAndIsMuTimesTheNormalForce) {
  const double h = 0.01;
  TwoSheets t(4);
  ClothFrictionParams params;
  params.friction = 0.5;
  ClothFriction f(t.num_points(), t.names(), params);
  const auto frames = t.contact->contact_frames(t.x);
  f.start_step(t.x, frames, h);
  // The whole top sheet slides far along x: every pair is sliding, and the force on the top sheet is the sum of
  // μλ_k along each pair's tangential projection of −x̂.
  VecX x = t.x;
  for (Index i = t.surfaces[1].offset; i < t.num_points(); ++i) x[3 * i] += 1e-3;
  VecX g = VecX::Zero(x.size());
  f.add_gradient(x, g);
  Vec3 top = Vec3::Zero(), expected = Vec3::Zero();
  for (Index i = t.surfaces[1].offset; i < t.num_points(); ++i) top += at(g, i);
  // Whichever side of a pair the top sheet is, its points get μλ times the unit tangential part of +x̂.
  for (const auto& fr : frames) {
    ASSERT_NE(fr.surface_a, fr.surface_b);
    expected += 0.5 * fr.normal_force * (fr.tangent * (fr.tangent.transpose() * Vec3::UnitX())).normalized();
  }
  EXPECT_LE((top - expected).norm(), 1e-9 * expected.norm());
  EXPECT_GT(top.x(), 0.0);  // the gradient points along the slide: the force −∇D opposes it
}

TEST(ClothFriction, CoefficientsPerPairOfCloths) {
  TwoSheets t(5);
  const auto frames = t.contact->contact_frames(t.x);
  ClothFrictionParams params;
  params.friction = 0.3;
  params.pairs = {{"b", "a", 0.7}, {"a", "a", 0.0}};
  ClothFriction f(t.num_points(), t.names(), params);
  EXPECT_EQ(f.friction(0, 1), 0.7);
  EXPECT_EQ(f.friction(1, 0), 0.7);
  EXPECT_EQ(f.friction(0, 0), 0.0);
  EXPECT_EQ(f.friction(1, 1), 0.3);
  // A pair naming a cloth of another group (solved separately) is no error here: the scene has checked the names.
  params.pairs.push_back({"a", "elsewhere", 0.9});
  EXPECT_NO_THROW(ClothFriction(t.num_points(), t.names(), params));
  // Frictionless pairs carry nothing.
  params = {};
  params.friction = 0.0;
  ClothFriction none(t.num_points(), t.names(), params);
  none.start_step(t.x, frames, 0.01);
  EXPECT_EQ(none.num_pairs(), 0);
  EXPECT_EQ(none.value(t.x), 0.0);
}

TEST(ClothFriction, SelfContactPairsUseTheClothsOwnCoefficient) {
  // A sheet folded onto itself half a layer apart: every pair inside the layer is one of the cloth with itself.
  VecX x;
  std::vector<ContactSurface> s{sheet("a", 0.1, 121, 0.0, 0, x)};
  for (Index i = 0; i < x.size() / 3; ++i)
    if (x[3 * i] > 0.05 + 1e-9) {
      x[3 * i] = 0.1 - x[3 * i];
      x[3 * i + 2] = 0.5e-3;
    }
  const Index n = static_cast<Index>(x.size() / 3);
  ClothContact contact(s, n, ClothContactParams{});
  const auto frames = contact.contact_frames(x);
  ASSERT_GT(frames.size(), 10u);
  for (const auto& f : frames) {
    EXPECT_EQ(f.surface_a, 0);
    EXPECT_EQ(f.surface_b, 0);
  }
  // The folded half slides along y, far beyond ε: D is linear in the cloth's own μ, whatever the default.
  VecX y = x;
  for (Index i = 0; i < n; ++i)
    if (x[3 * i + 2] > 0.0) y[3 * i + 1] += 1e-3;
  const auto energy = [&](double self) {
    ClothFrictionParams p;
    p.friction = 0.9;
    p.pairs = {{"a", "a", self}};
    ClothFriction f(n, {"a"}, p);
    f.start_step(x, frames, 0.01);
    EXPECT_EQ(f.num_pairs(), self > 0.0 ? static_cast<Index>(frames.size()) : 0);
    return f.value(y);
  };
  EXPECT_GT(energy(0.3), 0.0);
  EXPECT_NEAR(energy(0.7), 0.7 / 0.3 * energy(0.3), 1e-12 * energy(0.7));
  EXPECT_EQ(energy(0.0), 0.0);
}

// The upper sheet of TwoSheets as an obstacle mesh (kinematic points) that slides sideways over the step: it drags
// the cloth under it with μ times the normal force, and a cloth carried along feels nothing.
TEST(ClothFriction, AnObstacleMeshDragsTheClothUnderIt) {
  const double h = 0.01;
  ClothFrictionParams params;
  params.friction = 0.4;
  for (unsigned seed : {1u, 2u}) {
    TwoSheets t(seed);
    const Index na = t.surfaces[1].offset;
    const VecX lower = t.x.head(3 * na), upper = t.x.tail(t.x.size() - 3 * na);
    std::vector<ContactSurface> split = t.surfaces;
    split[1].kinematic = true;
    split[1].offset = 0;
    ClothContact contact(split, na, ClothContactParams{}, upper);
    const auto frames = contact.contact_frames(lower);
    ASSERT_GT(frames.size(), 10u);
    double sum_mu_lambda = 0.0;
    for (const auto& f : frames) sum_mu_lambda += params.friction * f.normal_force;
    const Vec3 slide(2e-5, 0.0, 0.0);  // twice ε_v h: sliding
    VecX motion(upper.size());
    for (Index i = 0; i < motion.size() / 3; ++i) motion.segment<3>(3 * i) = slide;
    ClothFriction f(na, t.names(), params);
    f.start_step(lower, frames, h, &motion);
    EXPECT_EQ(f.num_pairs(), static_cast<Index>(frames.size()));
    VecX g = VecX::Zero(lower.size());
    f.add_gradient(lower, g);
    Vec3 force = Vec3::Zero();
    for (Index i = 0; i < na; ++i) force -= g.segment<3>(3 * i);
    // Along the slide, at most Σ μλ, and most of it: the sheets are nearly flat, most normals nearly z.
    EXPECT_GT(force.x(), 0.8 * sum_mu_lambda);
    EXPECT_LE(force.norm(), sum_mu_lambda * (1 + 1e-9));
    // Carried along with the obstacle, the cloth has not slid relative to it.
    VecX carried = lower;
    for (Index i = 0; i < na; ++i) carried.segment<3>(3 * i) += slide;
    VecX g2 = VecX::Zero(lower.size());
    f.add_gradient(carried, g2);
    EXPECT_LE(g2.norm(), 1e-9 * g.norm());
    f.update_stencils(lower);
    check_term(f, lower, 1e-5);
    // An obstacle that holds still (no motion given) drags nothing at the start point.
    ClothFriction still(na, t.names(), params);
    still.start_step(lower, frames, h);
    VecX g3 = VecX::Zero(lower.size());
    still.add_gradient(lower, g3);
    EXPECT_LE(g3.norm(), 1e-12 * g.norm());
  }
}

TEST(ClothFriction, RejectsBadCoefficients) {
  const std::vector<std::string> names{"a"};
  for (double bad : {-0.1, std::nan(""), kInf}) {
    ClothFrictionParams p;
    p.friction = bad;
    EXPECT_THROW(ClothFriction(3, names, p), InputError) << bad;
    p = {};
    p.pairs = {{"a", "a", bad}};
    EXPECT_THROW(ClothFriction(3, names, p), InputError) << bad;
    p = {};
    p.static_velocity = bad;
    EXPECT_THROW(ClothFriction(3, names, p), InputError) << bad;
  }
}

}  // namespace
}  // namespace mgcloth::physics
