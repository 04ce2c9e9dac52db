// Subdivision is exact refinement: a coarse control mesh and its prolongation S q describe the same limit surface,
// so every level's rediscretized step gives a prolongated state the same shell energy up to quadrature, and the
// same boundary penalties and loads exactly (they are the finest level's samples restricted through S). This is
// what lets nested iteration and coarse corrections carry coarse solutions to fine levels.
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/sim/simulator.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace mgcloth;

TEST(ShellLevels, ProlongatedStatesKeepTheirEnergyTermByTerm) {
  for (const std::string name : {"trampoline", "drooping", "reentrant", "drape"}) {
    sim::Scene scene = sim::load_scene(std::string(MGCLOTH_SOURCE_DIR) + "/scenes/shell_" + name + ".json");
    scene.shells[0].level = 3;
    scene.solver.name = "rmtr";
    sim::Simulator sim(scene);
    VecX x;
    sim.prepare_problem(0, x);
    bodies::ShellBody& body = *sim.shells()[0];
    // A smooth sag of the coarsest control mesh: z -= 0.2 sin(pi u) sin(pi v) over its bounding box.
    VecX q;
    body.project(1, x, q);
    VecX q0;
    body.project(0, q, q0);
    double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
    for (Index i = 0; i < q0.size() / 3; ++i) {
      xmin = std::min(xmin, q0[3 * i]), xmax = std::max(xmax, q0[3 * i]);
      ymin = std::min(ymin, q0[3 * i + 1]), ymax = std::max(ymax, q0[3 * i + 1]);
    }
    for (Index i = 0; i < q0.size() / 3; ++i) {
      const double u = (q0[3 * i] - xmin) / (xmax - xmin), v = (q0[3 * i + 1] - ymin) / (ymax - ymin);
      q0[3 * i + 2] -= 0.2 * std::sin(M_PI * u) * std::sin(M_PI * v);
    }
    // Plus control-point noise, which bends the held edges between the coarse surface's own edge samples.
    std::mt19937 rng(5);
    std::normal_distribution<double> noise(0.0, 0.01);
    for (Index i = 0; i < q0.size(); ++i) q0[i] += noise(rng);
    VecX q1, q2;
    body.hierarchy().subdivision(0).apply(q0, q1);
    body.hierarchy().subdivision(1).apply(q1, q2);
    const auto t0 = body.level_objective(0).term_values(q0);
    const auto t1 = body.level_objective(1).term_values(q1);
    const auto t2 = body.level_objective(2).term_values(q2);
    ASSERT_EQ(t0.size(), t1.size());
    for (size_t k = 0; k < t0.size(); ++k) {
      SCOPED_TRACE(name + " " + t0[k].first);
      if (t0[k].first == "shell") {
        EXPECT_NEAR(t1[k].second, t2[k].second, 2e-2 * std::abs(t2[k].second));
      } else {
        EXPECT_NEAR(t0[k].second, t2[k].second, 1e-9 * std::abs(t2[k].second));
        EXPECT_NEAR(t1[k].second, t2[k].second, 1e-9 * std::abs(t2[k].second));
      }
    }
  }
}
