// The device pipeline of fmg-cuda, run by its host backend: the same kernels as on the GPU, compared with the CPU
// objective and multigrid on random states. The GPU itself is exercised where one is present (else skipped).
#include "solvers/hanging_fixture.hpp"

#include <mgcloth/core/error.hpp>
#include <mgcloth/cuda/host_backend.hpp>
#include <mgcloth/cuda/pipeline.hpp>
#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/linalg/galerkin.hpp>
#include <mgcloth/physics/contact.hpp>
#include <mgcloth/physics/seam.hpp>
#include <mgcloth/solvers/fmg_cuda.hpp>
#include <mgcloth/solvers/linear_multigrid.hpp>

#include <gtest/gtest.h>

#include <map>
#include <random>

using namespace mgcloth;
using HostPipeline = cuda::Pipeline<cuda::HostBackend>;

namespace {

/// The hanging cloth with a sphere under it (contact term), quadratic or hinge bending, and its hierarchy.
struct Fixture {
  std::unique_ptr<test::Hanging> cloth;
  hierarchy::TriangleHierarchy h;
  std::vector<const linalg::StencilTable*> tables;
};

/// `friction` > 0: the sphere also moves and spins, so that the friction filter has a surface velocity to match.
Fixture make(Index vertices, bool contact, double friction = 0.0,
             physics::BendingModel bending = physics::BendingModel::Hinge) {
  Fixture f;
  f.cloth = test::hanging(vertices, 1.0 / 30.0, bending);
  if (contact) {
    std::vector<geometry::Obstacle> obstacles(1);
    obstacles[0].shape = std::make_shared<geometry::Sphere>(0.1);
    const Vec3 linear = friction > 0.0 ? Vec3(0.3, -0.2, 0.1) : Vec3::Zero();
    const Vec3 angular = friction > 0.0 ? Vec3(1.0, 4.0, -2.0) : Vec3::Zero();
    obstacles[0].motion = std::make_shared<geometry::ConstantVelocityMotion>(
        geometry::Pose{Eigen::Quaterniond::Identity(), Vec3(0.2, 0.08, -0.2)}, linear, angular);
    obstacles[0].friction = friction;
    physics::ContactParams cp;
    cp.thickness = 0.01;
    const Index n = f.cloth->mesh.num_vertices();
    f.cloth->objective.add(std::make_unique<physics::ObstacleContact>(VecX::Constant(n, 1e-4), obstacles, cp));
    f.cloth->objective.finalize();
  }
  f.h = test::small_hierarchy(*f.cloth);
  for (Index l = 0; l + 1 < f.h.num_levels(); ++l) f.tables.push_back(&f.h.prolongation(l));
  return f;
}

/// A state that bends and stretches the cloth and pushes part of it through the sphere.
VecX perturbed(const Fixture& f, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  VecX x = f.cloth->x0;
  for (Index i = 0; i < x.size() / 3; ++i) {
    x[3 * i + 1] += 0.05 * std::sin(9.0 * x[3 * i]) + 0.004 * n01(rng);
    x[3 * i] += 0.002 * n01(rng);
    x[3 * i + 2] += 0.002 * n01(rng);
  }
  return x;
}

/// fmg-cuda: the FMG cycle the CPU solver runs, over the device pipeline (here its host backend).
std::unique_ptr<solvers::FmgCuda> device_solver(cuda::Backend backend = cuda::Backend::Host, cuda::FmgSettings s = {}) {
  return std::make_unique<solvers::FmgCuda>(backend, std::move(s));
}

/// One solve of the fixture's objective from x; `project`: iterates are made feasible (the device projects with its
/// own copy of the obstacles; the problem's hook only says that it should).
solvers::SolveReport solve(solvers::FmgCuda& solver, const Fixture& f, bool project, VecX& x, double rel_grad,
                           int max_iters) {
  solvers::Problem problem;
  problem.objective = &f.cloth->objective;
  problem.hierarchy = f.h.levels_for_solvers();
  if (project) problem.project = [](VecX&) -> Index { return 0; };
  solvers::Stop stop;
  stop.rel_grad = rel_grad;
  stop.max_iters = max_iters;
  return solver.minimize(problem, x, stop, nullptr);
}

std::vector<double> device_x(const HostPipeline& p, const VecX& x) {
  std::vector<double> xd;
  cuda::to_device_order(p.layout(), x, xd);
  return xd;
}

}  // namespace

TEST(DeviceLayout, ColorsAreContiguousIndependentRowRangesAndTheNumberingIsABijection) {
  const Fixture f = make(600, true);
  const cuda::Layout L = cuda::build_layout(f.cloth->objective, f.tables);
  ASSERT_EQ(L.levels.size(), f.tables.size() + 1);
  ASSERT_GE(L.levels.size(), 3u);
  for (const auto& level : L.levels) {
    std::vector<Index> seen(level.perm.size(), 0);
    for (Index v : level.perm) ++seen[static_cast<size_t>(v)];
    for (Index c : seen) EXPECT_EQ(c, 1);
    std::vector<Index> color(static_cast<size_t>(level.n), -1);
    for (size_t c = 0; c + 1 < level.color_offsets.size(); ++c)
      for (Index r = level.color_offsets[c]; r < level.color_offsets[c + 1]; ++r) color[static_cast<size_t>(r)] = static_cast<Index>(c);
    for (Index r = 0; r < level.n; ++r) {
      ASSERT_GE(color[static_cast<size_t>(r)], 0);
      for (Index k = level.pattern.row_offsets()[r]; k < level.pattern.row_offsets()[r + 1]; ++k) {
        const Index c = level.pattern.col_indices()[k];
        if (c != r) {
          EXPECT_NE(color[static_cast<size_t>(c)], color[static_cast<size_t>(r)]) << "rows " << r << ", " << c;
        }
      }
    }
  }
  // Element colors: no two elements of a color share a vertex.
  for (const cuda::ElementGroup* g : {&L.objective.tris, &L.objective.hinges}) {
    EXPECT_GT(g->size(), 0);
    for (size_t c = 0; c + 1 < g->color_offsets.size(); ++c) {
      std::vector<char> used(static_cast<size_t>(L.objective.n), 0);
      for (Index e = g->color_offsets[c]; e < g->color_offsets[c + 1]; ++e)
        for (int a = 0; a < g->arity; ++a) {
          const Index v = g->vertices[static_cast<size_t>(e * g->arity + a)];
          EXPECT_FALSE(used[static_cast<size_t>(v)]) << "color " << c << " vertex " << v;
          used[static_cast<size_t>(v)] = 1;
        }
    }
  }
}

class DevicePipelineBending : public ::testing::TestWithParam<physics::BendingModel> {};

TEST_P(DevicePipelineBending, EnergyGradientAndHessianEqualTheCpuObjective) {
  const Fixture f = make(500, true, 0.0, GetParam());
  HostPipeline p(cuda::FmgSettings{});
  p.build(f.cloth->objective, f.tables);
  p.upload_step(f.cloth->objective);
  const auto& perm = p.layout().levels[0].perm;
  for (std::uint64_t seed : {1u, 2u}) {
    const VecX x = perturbed(f, seed);
    std::vector<double> xd = device_x(p, x);
    const double e_cpu = f.cloth->objective.value(x);
    EXPECT_NEAR(p.energy_at(xd.data()), e_cpu, 1e-12 * std::abs(e_cpu));
    EXPECT_GT(f.cloth->objective.term_values(x).back().second, 0.0) << "the state must be in contact";
    VecX g_cpu;
    f.cloth->objective.gradient(x, g_cpu);
    std::vector<double> gd(xd.size());
    p.gradient_at(xd.data(), gd.data());
    VecX g_dev;
    cuda::from_device_order(p.layout(), gd, g_dev);
    EXPECT_LE((g_dev - g_cpu).norm(), 1e-11 * g_cpu.norm());
    linalg::BlockMatrix3 H = f.cloth->objective.hessian_pattern();
    f.cloth->objective.hessian(x, H, /*project_psd=*/true);
    p.hessian(xd.data());
    const auto& top = p.levels()[0];
    const linalg::BlockMatrix3& pattern = p.layout().levels[0].pattern;
    std::vector<double> blocks;
    top.blocks.download(blocks);
    double err = 0.0, scale = 0.0;
    for (Index r = 0; r < top.n; ++r)
      for (Index k = pattern.row_offsets()[r]; k < pattern.row_offsets()[r + 1]; ++k) {
        const Index c = pattern.col_indices()[k];
        const Mat3& ref = H.block(H.find(perm[static_cast<size_t>(r)], perm[static_cast<size_t>(c)]));
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            err = std::max(err, std::abs(blocks[9 * static_cast<size_t>(k) + 3 * i + j] - ref(i, j)));
            scale = std::max(scale, std::abs(ref(i, j)));
          }
      }
    EXPECT_LE(err, 1e-12 * scale);
  }
}

TEST_P(DevicePipelineBending, AStepSolvesTheCpuObjective) {
  // fmg-cuda's minimize on the host backend, judged by the CPU objective's own gradient at its result.
  const Fixture f = make(600, true, 0.0, GetParam());
  auto solver = device_solver();
  VecX x = f.cloth->x0;
  VecX g0;
  f.cloth->objective.gradient(x, g0);
  const solvers::SolveReport out = solve(*solver, f, true, x, 1e-6, 300);
  EXPECT_EQ(out.status, "converged");
  VecX g;
  f.cloth->objective.gradient(x, g);
  EXPECT_LE(g.norm(), 1.01e-6 * g0.norm());
  EXPECT_LT(f.cloth->objective.value(x), f.cloth->objective.value(f.cloth->x0));
}

INSTANTIATE_TEST_SUITE_P(Models, DevicePipelineBending,
                         ::testing::Values(physics::BendingModel::Hinge, physics::BendingModel::Quadratic,
                                           physics::BendingModel::QuadraticBergou),
                         [](const auto& info) {
                           std::string n = physics::to_string(info.param);
                           for (char& c : n)
                             if (c == '-') c = '_';
                           return n;
                         });

TEST(DevicePipeline, GalerkinOperatorsAndSmoothersMatchTheCpuMultigrid) {
  const Fixture f = make(600, false);
  HostPipeline p(cuda::FmgSettings{});
  p.build(f.cloth->objective, f.tables);
  p.upload_step(f.cloth->objective);
  const VecX x = perturbed(f, 3);
  std::vector<double> xd = device_x(p, x);
  p.hessian(xd.data());
  p.update_hierarchy();
  // CPU: A_{l+1} = Pᵀ A_l P in the problem's numbering.
  linalg::BlockMatrix3 A = f.cloth->objective.hessian_pattern();
  f.cloth->objective.hessian(x, A, true);
  for (size_t l = 0; l + 1 < p.levels().size(); ++l) {
    const auto& P = *f.tables[l];
    const linalg::GalerkinProduct rap(A, P);
    linalg::BlockMatrix3 Ac;
    rap.compute(A, Ac);
    const auto& level = p.levels()[l + 1];
    const linalg::BlockMatrix3& pattern = p.layout().levels[l + 1].pattern;
    const auto& perm = p.layout().levels[l + 1].perm;
    std::vector<double> blocks;
    level.blocks.download(blocks);
    double err = 0.0, scale = 0.0;
    for (Index r = 0; r < level.n; ++r)
      for (Index k = pattern.row_offsets()[r]; k < pattern.row_offsets()[r + 1]; ++k) {
        const Mat3& ref = Ac.block(Ac.find(perm[static_cast<size_t>(r)], perm[static_cast<size_t>(pattern.col_indices()[k])]));
        for (int i = 0; i < 9; ++i) {
          err = std::max(err, std::abs(blocks[9 * static_cast<size_t>(k) + static_cast<size_t>(i)] - ref(i / 3, i % 3)));
          scale = std::max(scale, std::abs(ref(i / 3, i % 3)));
        }
      }
    EXPECT_LE(err, 1e-12 * scale) << "level " << l + 1;
    A = Ac;
    EXPECT_GT(level.rho + p.levels()[l].rho, 0.0);
  }
}

TEST(DevicePipeline, TheGalerkinGatherEqualsAGeneralSpgemmOfTheScalarMatrices) {
  // compare_spgemm's reference (Eigen's SpGEMM on the host backend, cuSPARSE's on the GPU) from the same fine
  // matrix: every coarse level must come out the same, and the counters must report both timings.
  const Fixture f = make(1500, true);
  cuda::FmgSettings s;
  s.compare_spgemm = true;
  auto solver = device_solver(cuda::Backend::Host, s);
  VecX x = perturbed(f, 11);
  const solvers::SolveReport out = solve(*solver, f, true, x, 1e-6, 1);
  std::map<std::string, double> c(out.counters.begin(), out.counters.end());
  ASSERT_TRUE(c.count("spgemm_max_rel_diff")) << "no comparison in the counters";
  EXPECT_LT(c["spgemm_max_rel_diff"], 1e-13);
  EXPECT_GT(c["spgemm_gather_ms"], 0.0);
  EXPECT_GT(c["spgemm_reference_ms"], 0.0);
  // The scalar forms themselves: P ⊗ I₃ has 3 entries per vertex weight, and its product with a coarse vector
  // is the prolongation.
  HostPipeline p(cuda::FmgSettings{});
  p.build(f.cloth->objective, f.tables);
  const cuda::LevelLayout &F = p.layout().levels[0], &C = p.layout().levels[1];
  const cuda::ScalarCsr P = cuda::expand_table(F.P, C.n);
  EXPECT_EQ(P.values.size(), 3 * F.P.weights.size());
  EXPECT_EQ(P.rows, 3 * F.n);
  EXPECT_EQ(P.cols, 3 * C.n);
}

TEST(DevicePipeline, VCyclesContractLikeTheCpuMultigridWithEitherCoarseSolve) {
  const Fixture f = make(800, true);
  const VecX x = perturbed(f, 4);
  // The CPU multigrid's contraction per V-cycle on the same matrix (same hierarchy, smoother and sweeps).
  linalg::BlockMatrix3 A = f.cloth->objective.hessian_pattern();
  f.cloth->objective.hessian(x, A, true);
  solvers::MultigridParams mp;
  mp.pre_smooth = mp.post_smooth = 3;
  mp.chebyshev = true;
  solvers::LinearMultigrid cpu(f.tables, A, mp);
  cpu.set_matrix(A);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01(0.0, 1.0);
  VecX b_cpu(A.rows() * 3);
  for (Index i = 0; i < b_cpu.size(); ++i) b_cpu[i] = n01(rng);
  const double cpu_rate = cpu.contraction(b_cpu);
  EXPECT_LT(cpu_rate, 0.9);
  for (const std::string coarse : {"device", "host"}) {
    cuda::FmgSettings s;
    s.coarse_solve = coarse;
    HostPipeline p(s);
    p.build(f.cloth->objective, f.tables);
    p.upload_step(f.cloth->objective);
    std::vector<double> xd = device_x(p, x);
    p.hessian(xd.data());
    p.update_hierarchy();
    auto& top = const_cast<HostPipeline::Level&>(p.levels()[0]);
    const Index n3 = 3 * top.n;
    std::vector<double> b;
    cuda::to_device_order(p.layout(), b_cpu, b);
    top.b.upload(b);
    p.fill(top.x.data(), 0.0, n3);
    std::vector<double> r(static_cast<size_t>(n3));
    double r3 = 0.0, r10 = 0.0;
    for (int k = 1; k <= 10; ++k) {
      p.cycle(0, k == 1);
      p.residual(top, top.b.data(), top.x.data(), r.data());
      const double rn = std::sqrt(p.dot(r.data(), r.data(), n3));
      if (k == 3) r3 = rn;
      if (k == 10) r10 = rn;
    }
    const double rate = std::pow(r10 / r3, 1.0 / 7.0);
    // Another vertex order of the Gauss-Seidel colors gives another (equally good) smoother, not the same numbers.
    EXPECT_LT(rate, 1.15 * cpu_rate + 0.02) << coarse << ": device " << rate << ", CPU " << cpu_rate;
  }
}

TEST(DevicePipeline, ProjectionMovesVerticesOutOfTheObstacle) {
  const Fixture f = make(400, true);
  HostPipeline p(cuda::FmgSettings{});
  p.build(f.cloth->objective, f.tables);
  p.upload_step(f.cloth->objective);
  VecX x = perturbed(f, 6);
  for (Index i = 0; i < x.size() / 3; ++i) x[3 * i + 1] += 0.12 * std::exp(-50.0 * (Vec3(x[3 * i], 0.0, x[3 * i + 2]) - Vec3(0.2, 0.0, -0.2)).squaredNorm());
  VecX x_cpu = x;
  const auto* contact = dynamic_cast<const physics::ObstacleContact*>(f.cloth->objective.terms().back().get());
  ASSERT_NE(contact, nullptr);
  const Index moved_cpu = physics::project_out_of_obstacles(x_cpu, contact->obstacle_data());
  std::vector<double> xd = device_x(p, x);
  EXPECT_GT(moved_cpu, 0);
  EXPECT_EQ(p.project_at(xd.data()), moved_cpu);
  VecX x_dev;
  cuda::from_device_order(p.layout(), xd, x_dev);
  EXPECT_LE((x_dev - x_cpu).lpNorm<Eigen::Infinity>(), 1e-15);
}

TEST(DevicePipeline, TheStepEndsOnTheDeviceAsOnTheCpuWithProjectionVelocityAndFriction) {
  const Fixture f = make(500, true, 0.6);
  const double h = 1.0 / 30.0;
  // A solution that the sphere overlaps (so projection and both friction regimes occur) from a few FMG cycles.
  VecX x = perturbed(f, 7);
  for (Index i = 0; i < x.size() / 3; ++i)
    x[3 * i + 1] += 0.12 * std::exp(-50.0 * (Vec3(x[3 * i], 0.0, x[3 * i + 2]) - Vec3(0.2, 0.0, -0.2)).squaredNorm());
  const VecX x_old = f.cloth->x0;
  auto device = device_solver();
  solve(*device, f, false, x, 1e-6, 2);
  VecX x_dev, v_dev;
  device->finish_step(x_old, h, x_dev, v_dev);

  const auto& terms = f.cloth->objective.terms();
  const auto* contact = dynamic_cast<const physics::ObstacleContact*>(terms.back().get());
  const auto* inertia = dynamic_cast<const physics::InertiaTerm*>(terms.front().get());
  ASSERT_NE(contact, nullptr);
  ASSERT_NE(inertia, nullptr);
  VecX x_cpu = x, pushed;
  const Index moved = physics::project_out_of_obstacles(x_cpu, contact->obstacle_data(), &pushed);
  VecX v_cpu = (x_cpu - x_old) / h;
  const VecX v_unfiltered = v_cpu;
  physics::apply_friction(x_cpu, v_cpu, inertia->mass(), *contact, h, pushed);
  EXPECT_GT(moved, 0);
  EXPECT_GT((v_cpu - v_unfiltered).norm(), 0.1 * v_unfiltered.norm()) << "friction should change the velocities";
  EXPECT_LE((x_dev - x_cpu).lpNorm<Eigen::Infinity>(), 1e-14);
  EXPECT_LE((v_dev - v_cpu).lpNorm<Eigen::Infinity>(), 1e-10 * v_cpu.lpNorm<Eigen::Infinity>());
}

TEST(DevicePipeline, TermsWithoutADeviceImplementationAreRejectedByName) {
  Fixture f = make(300, false);
  f.cloth->objective.add(std::make_unique<physics::SeamTerm>(std::vector<std::vector<Index>>{{0, 1}}, 1.0, f.cloth->mesh.num_vertices()));
  f.cloth->objective.finalize();
  try {
    cuda::build_layout(f.cloth->objective, f.tables);
    FAIL() << "a seam term was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("\"seam"), std::string::npos) << e.what();
  }
}

TEST(DevicePipeline, TheCudaBackendRunsWhereAGpuIsPresentAndSaysWhyNotElsewhere) {
  std::string why;
  if (!cuda::cuda_available(&why)) {
    EXPECT_FALSE(why.empty());
    try {
      cuda::make_device_fmg(cuda::Backend::Cuda, {});
      FAIL() << "a CUDA solver was made without a GPU";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("no GPU"), std::string::npos) << e.what();
    }
    GTEST_SKIP() << "no GPU here (" << why << "); the CUDA kernels are tested on the GPU machine";
  }
  // Same start, same settings: the GPU pipeline and its host emulation reach the same minimizer.
  const Fixture f = make(2000, true);
  VecX x_gpu = f.cloth->x0, x_host = f.cloth->x0;
  auto gpu = device_solver(cuda::Backend::Cuda);
  auto host = device_solver(cuda::Backend::Host);
  const solvers::SolveReport a = solve(*gpu, f, true, x_gpu, 1e-6, 500);
  const solvers::SolveReport b = solve(*host, f, true, x_host, 1e-6, 500);
  EXPECT_EQ(a.status, "converged") << gpu->device();
  EXPECT_EQ(b.status, "converged");
  EXPECT_LE((x_gpu - x_host).norm(), 1e-5 * x_host.norm());
  EXPECT_NEAR(a.energy, b.energy, 1e-9 * std::abs(b.energy));
  // The step's end (projection, velocity, friction) on each.
  const Fixture moving = make(2000, true, 0.6);
  VecX xg = moving.cloth->x0, xh = moving.cloth->x0, xg_end, vg, xh_end, vh;
  solve(*gpu, moving, true, xg, 1e-6, 500);
  solve(*host, moving, true, xh, 1e-6, 500);
  gpu->finish_step(moving.cloth->x0, 1.0 / 30.0, xg_end, vg);
  host->finish_step(moving.cloth->x0, 1.0 / 30.0, xh_end, vh);
  EXPECT_LE((xg_end - xh_end).norm(), 1e-5 * xh_end.norm());
  EXPECT_LE((vg - vh).norm(), 1e-4 * std::max(1.0, vh.norm()));
}

TEST(DevicePipeline, AReplayedVCycleGraphGivesTheSameSolveAsDirectLaunches) {
  // The host backend's graph records launches with their arguments frozen at capture, as CUDA stream capture does:
  // replaying it every direction (with new matrices in the same buffers) must give the same iterates bit for bit.
  const Fixture f = make(700, true);
  std::vector<VecX> results;
  std::vector<double> launches;
  for (const bool graphs : {true, false}) {
    cuda::FmgSettings s;
    s.graphs = graphs;
    auto solver = device_solver(cuda::Backend::Host, s);
    VecX x = f.cloth->x0;
    const solvers::SolveReport out = solve(*solver, f, true, x, 1e-6, 200);
    EXPECT_EQ(out.status, "converged");
    results.push_back(x);
    for (const auto& [name, value] : out.counters)
      if (name == "graph_launches") launches.push_back(value);
  }
  ASSERT_EQ(launches.size(), 2u);
  EXPECT_GT(launches[0], 3.0);
  EXPECT_EQ(launches[1], 0.0);
  EXPECT_EQ((results[0] - results[1]).norm(), 0.0);
}
