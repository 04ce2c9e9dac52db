#include <mgcloth/studies/cantilever.hpp>

#include <gtest/gtest.h>

#include <cmath>

using namespace mgcloth;

TEST(Cantilever, ElasticaMatchesTheLinearTheoryForSmallLoads) {
  // w L³/B = 1e-4: the small-deflection cantilever under its own weight, z(L) = w L⁴ / (8 B).
  const double B = 1.0, w = 1e-4, L = 1.0;
  const auto z = studies::elastica_deflection(B, w, L, {L, 0.5 * L});
  EXPECT_NEAR(z[0], w / 8, 1e-4 * w / 8);
  // z(s) = w s² (6L² − 4Ls + s²) / (24 B)
  EXPECT_NEAR(z[1], w * 0.25 * (6 - 2 + 0.25) / 24, 1e-4 * w);
  EXPECT_NEAR(studies::elastica_rigidity(z[0], w, L, {L}), B, 1e-6);
}

TEST(Cantilever, ElasticaMatchesAChainOfRigidLinksAtLargeDeflection) {
  // w L³/B = 8 (L = 2c): the tip droops 0.6406 L, by the energy minimum of a chain of N rigid links with bending
  // springs B/Δs (N = 400 and 1600, extrapolated in 1/N), computed independently of the shooting method here.
  const double B = 1.0, w = 8.0, L = 1.0;
  const double tip = studies::elastica_deflection(B, w, L, {L})[0];
  EXPECT_NEAR(tip, 0.6406, 0.0005);
  EXPECT_NEAR(studies::elastica_rigidity(tip, w, L, {L}), B, 1e-6);
}

TEST(Cantilever, StripsHaveTheirSizeAndDirection) {
  for (bool unstructured : {false, true})
    for (double angle : {0.0, 90.0, 45.0}) {
      const studies::Strip s = studies::make_strip(unstructured, angle, 1500, 0.04, 0.01);
      const double area = s.mesh.total_material_area();
      EXPECT_NEAR(area, 0.04 * 0.01, (angle == 45.0 ? 0.08 : 1e-9) * 0.04 * 0.01) << unstructured << " " << angle;
      EXPECT_GE(s.mesh.u.row(0).minCoeff(), -0.002);
      EXPECT_LE(s.mesh.u.row(0).maxCoeff(), 0.042);
      EXPECT_NEAR(s.mesh.num_vertices(), 1500, 200);
    }
}

// The measurement itself: a chain-like strip whose rigidity is known exactly cannot be built from triangles, so the
// clamp fit is checked for what it must not do: move the clamp more than a couple of edges, or disagree with the
// single-overhang measurement by more than that offset explains.
TEST(Cantilever, ClampFitStaysWithinAnEdgeOfThePins) {
  physics::Material mat;
  mat.bending = physics::BendingModel::Quadratic;
  const double c = std::cbrt(mat.bending_stiffness / (mat.areal_density() * 9.81)), L = 2.0 * c;
  const studies::Strip strip = studies::make_strip(false, 0.0, 1200, 1.1 * L, 0.25 * L);
  const studies::Strip half = studies::truncate_strip(strip, 0.1 * L + 0.5 * L);
  EXPECT_NEAR(half.mesh.total_material_area(), 0.6 * L * 0.25 * L, 0.02 * 0.6 * L * 0.25 * L);
  const double h = std::sqrt(1.1 * L * 0.25 * L / 1200);
  const studies::CantileverResult r = studies::cantilever(strip, mat, 0.1 * L, 1.5 * h);
  EXPECT_LT(std::abs(r.clamp_offset), 1.5 * r.edge_length);
  EXPECT_NEAR(r.rigidity / r.rigidity_at_pins, 1.0, 0.1);
}

// Issue 25's acceptance test: the heavy elastica (L/c = 2, a large deflection: the tip drops 0.64 L) realizes
// the material's bending rigidity within 2% with the quadratic model on the regular and the unstructured generator,
// for strips along u, v and the diagonal. (The hinge model realizes 0.85 along the grid's axes and 1.25 along its
// diagonal on the same strips: bench/RESULTS.md.)
TEST(Cantilever, QuadraticBendingRealizesItsRigidityOnEveryMeshAndDirection) {
  physics::Material mat;
  mat.bending = physics::BendingModel::Quadratic;
  const double c = std::cbrt(mat.bending_stiffness / (mat.areal_density() * 9.81)), L = 2.0 * c, W = 0.25 * L;
  const Index n = 3000;
  for (bool unstructured : {false, true})
    for (double angle : {0.0, 90.0, 45.0}) {
      const studies::Strip strip = studies::make_strip(unstructured, angle, n, 1.1 * L, W);
      const double h = std::sqrt(L * W / static_cast<double>(n));
      const studies::CantileverResult r = studies::cantilever(strip, mat, 0.1 * L, 1.5 * h);
      EXPECT_NEAR(r.rigidity / mat.bending_stiffness, 1.0, 0.02)
          << (unstructured ? "unstructured" : "regular") << " strip at " << angle << " degrees";
    }
}
