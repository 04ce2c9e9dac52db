// Galerkin coarse operators on a cloth Hessian: mgcloth's block RAP with a precomputed gather map against Eigen's
// generic sparse triple product Pᵀ A P on the same scalar matrices, per level; and the color counts of each level's
// block graph (cf. Wang 2018, Table 1).
//   mgcloth_bench_galerkin --vertices N [--repeat R]
#include <mgcloth/core/timer.hpp>
#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/linalg/coloring.hpp>
#include <mgcloth/linalg/galerkin.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/topology.hpp>
#include <mgcloth/physics/bending.hpp>
#include <mgcloth/physics/inertia.hpp>
#include <mgcloth/physics/membrane.hpp>
#include <mgcloth/physics/objective.hpp>

#include <CLI/CLI.hpp>

#include <cstdio>

using namespace mgcloth;

int main(int argc, char** argv) {
  CLI::App app{"Galerkin RAP benchmark"};
  int vertices = 40000, repeat = 5;
  app.add_option("--vertices", vertices);
  app.add_option("--repeat", repeat);
  CLI11_PARSE(app, argc, argv);

  mesh::RectangleSpec spec;
  spec.target_vertices = vertices;
  spec.unstructured = true;
  const auto m = mesh::make_rectangle(spec);
  const auto topo = mesh::build_topology(m);
  physics::Material mat;
  const Index n = m.num_vertices();
  physics::Objective obj(n);
  auto& inertia = obj.add(std::make_unique<physics::InertiaTerm>(VecX::Constant(n, 1e-5)));
  VecX x = as_stacked(m.x);
  for (Index i = 0; i < n; ++i) x[3 * i + 2] = 0.05 * std::sin(6.0 * x[3 * i]);
  inertia.set_prediction(x, 1.0 / 30.0);
  obj.add(std::make_unique<physics::StVKMembrane>(m, mat));
  obj.add(std::make_unique<physics::HingeBending>(m, topo, mat));
  obj.finalize();
  linalg::BlockMatrix3 A;
  obj.hessian(x, A, true);
  const auto h = hierarchy::build_triangle_hierarchy(m, {});

  std::printf("| level | vertices | colors | blocks | mgcloth RAP (ms) | Eigen PᵀAP (ms) | ratio |\n|---:|---:|---:|---:|---:|---:|---:|\n");
  linalg::BlockMatrix3 current = A;
  for (Index l = 0; l < h.num_levels(); ++l) {
    const auto colors = linalg::color_rows(current);
    if (l + 1 == h.num_levels()) {
      std::printf("| %d | %d | %zu | %d | – | – | – |\n", l, current.rows(), colors.size(), current.num_blocks());
      break;
    }
    const auto& P = h.prolongation(l);
    linalg::GalerkinProduct rap(current, P);
    linalg::BlockMatrix3 coarse;
    rap.compute(current, coarse);
    Timer t;
    for (int r = 0; r < repeat; ++r) rap.compute(current, coarse);
    const double ours = t.ms() / repeat;
    // Eigen: the same product on scalar matrices, P ⊗ I₃ expanded.
    std::vector<Eigen::Triplet<double>> trip;
    for (Index i = 0; i < P.num_rows; ++i)
      for (Index k = P.offsets[i]; k < P.offsets[i + 1]; ++k)
        for (int d = 0; d < 3; ++d) trip.emplace_back(3 * i + d, 3 * P.indices[k] + d, P.weights[k]);
    Eigen::SparseMatrix<double> Ps(3 * P.num_rows, 3 * P.num_cols);
    Ps.setFromTriplets(trip.begin(), trip.end());
    const Eigen::SparseMatrix<double> As = current.to_sparse();
    const Eigen::SparseMatrix<double> Pt = Ps.transpose();
    Eigen::SparseMatrix<double> Ac = Pt * As * Ps;
    t.reset();
    for (int r = 0; r < repeat; ++r) Ac = Pt * As * Ps;
    const double eigen = t.ms() / repeat;
    const double diff = (Eigen::SparseMatrix<double>(coarse.to_sparse()) - Ac).norm() / Ac.norm();
    std::printf("| %d | %d | %zu | %d | %.2f | %.2f | %.1f× (rel. diff %.0e) |\n", l, current.rows(), colors.size(),
                current.num_blocks(), ours, eigen, eigen / ours, diff);
    current = coarse;
  }
}
