#include <mgcloth/sim/cantilever.hpp>

#include <gtest/gtest.h>

#include <cmath>

using namespace mgcloth;

TEST(Cantilever, ElasticaMatchesTheLinearTheoryForSmallLoads) {
  // w L³/B = 1e-4: the small-deflection cantilever under its own weight, z(L) = w L⁴ / (8 B).
  const double B = 1.0, w = 1e-4, L = 1.0;
  const auto z = sim::elastica_deflection(B, w, L, {L, 0.5 * L});
  EXPECT_NEAR(z[0], w / 8, 1e-4 * w / 8);
  // z(s) = w s² (6L² − 4Ls + s²) / (24 B)
  EXPECT_NEAR(z[1], w * 0.25 * (6 - 2 + 0.25) / 24, 1e-4 * w);
  EXPECT_NEAR(sim::elastica_rigidity(z[0], w, L, {L}), B, 1e-6);
}

TEST(Cantilever, ElasticaMatchesAChainOfRigidLinksAtLargeDeflection) {
  // w L³/B = 8 (L = 2c): the tip droops 0.6406 L, by the energy minimum of a chain of N rigid links with bending
  // springs B/Δs (N = 400 and 1600, extrapolated in 1/N), computed independently of the shooting method here.
  const double B = 1.0, w = 8.0, L = 1.0;
  const double tip = sim::elastica_deflection(B, w, L, {L})[0];
  EXPECT_NEAR(tip, 0.6406, 0.0005);
  EXPECT_NEAR(sim::elastica_rigidity(tip, w, L, {L}), B, 1e-6);
}

TEST(Cantilever, StripsHaveTheirSizeAndDirection) {
  for (bool unstructured : {false, true})
    for (double angle : {0.0, 90.0, 45.0}) {
      const sim::Strip s = sim::make_strip(unstructured, angle, 1500, 0.04, 0.01);
      const double area = s.mesh.total_material_area();
      EXPECT_NEAR(area, 0.04 * 0.01, (angle == 45.0 ? 0.08 : 1e-9) * 0.04 * 0.01) << unstructured << " " << angle;
      EXPECT_GE(s.mesh.u.row(0).minCoeff(), -0.002);
      EXPECT_LE(s.mesh.u.row(0).maxCoeff(), 0.042);
      EXPECT_NEAR(s.mesh.num_vertices(), 1500, 200);
    }
}
