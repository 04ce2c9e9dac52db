// The bending rigidity each bending model realizes, measured as the textile cantilever test (ASTM D1388) does: a
// strip clamped at one end droops under its own weight, and the rigidity B for which the heavy elastica droops as far
// is the realized one (studies/cantilever.hpp: two overhangs fix both B and where the clamp acts). Regular and unstructured meshes, strips along u, v and the diagonal, at
// two resolutions; a realized B / bending_stiffness of 1 is a mesh-independent discretization.
#include <mgcloth/studies/cantilever.hpp>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cmath>

using namespace mgcloth;

int main(int argc, char** argv) {
  CLI::App app{"mgcloth_bench_bending: realized bending rigidity of cantilever strips"};
  double ratio = 2.0, aspect = 0.25, clamp = 0.1;
  std::vector<Index> vertices{3000, 12000};
  std::vector<std::string> models{"quadratic", "hinge", "quadratic-bergou"};
  app.add_option("--length-ratio", ratio, "strip length over the bending length c = (k_b / (rho t g))^(1/3)")
      ->check(CLI::Range(0.1, 5.0));
  app.add_option("--aspect", aspect, "strip width over length")->check(CLI::Range(0.01, 1.0));
  app.add_option("--vertices", vertices, "strip resolutions")->delimiter(',');
  app.add_option("--models", models, "bending models")->delimiter(',')->check(CLI::IsMember({"hinge", "quadratic", "quadratic-bergou"}));
  CLI11_PARSE(app, argc, argv);

  physics::Material mat;
  const double c = std::cbrt(mat.bending_stiffness / (mat.areal_density() * 9.81));
  const double L = ratio * c, W = aspect * L;
  fmt::print("cotton (k_b = {:g} N m, {:g} kg/m2): c = {:.4f} m, free length L = {:.4f} m (L/c = {:g}), width {:.4f} m,"
             " clamp {:.4f} m\n", mat.bending_stiffness, mat.areal_density(), c, L, ratio, W, clamp * L);
  fmt::print("{:>16} {:>12} {:>9} {:>9} {:>11} {:>13} {:>10} {:>12} {:>14}\n", "model", "mesh", "direction", "vertices",
             "drop [m]", "elastica [m]", "B/k_b", "clamp c*/h", "B/k_b at pins");
  for (const auto& model : models) {
    mat.bending = model == "quadratic"          ? physics::BendingModel::Quadratic
                  : model == "quadratic-bergou" ? physics::BendingModel::QuadraticBergou
                                                : physics::BendingModel::Hinge;
    for (bool unstructured : {false, true})
      for (double angle : {0.0, 90.0, 45.0})
        for (Index n : vertices) {
          const studies::Strip strip = studies::make_strip(unstructured, angle, n, L + clamp * L, W);
          const double h = std::sqrt(L * W / static_cast<double>(n));
          const studies::CantileverResult r = studies::cantilever(strip, mat, clamp * L, 1.5 * h);
          fmt::print("{:>16} {:>12} {:>9} {:>9} {:>11.6f} {:>13.6f} {:>10.4f} {:>12.2f} {:>14.4f}\n", model,
                     unstructured ? "unstructured" : "regular", angle == 0.0 ? "u" : angle == 90.0 ? "v" : "diagonal",
                     strip.mesh.num_vertices(), r.drop, r.elastica_drop, r.rigidity / mat.bending_stiffness,
                     r.clamp_offset / r.edge_length, r.rigidity_at_pins / mat.bending_stiffness);
          std::fflush(stdout);
        }
  }
  return 0;
}
