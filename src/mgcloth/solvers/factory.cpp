#include <mgcloth/solvers/factory.hpp>
#include <mgcloth/solvers/fas.hpp>
#include <mgcloth/solvers/fmg_cuda.hpp>
#include <mgcloth/solvers/newton.hpp>
#include <mgcloth/solvers/newton_variants.hpp>
#include <mgcloth/solvers/nonlinear_fmg.hpp>
#include <mgcloth/solvers/rmtr.hpp>
#include <mgcloth/solvers/trust_region.hpp>

#include <functional>

namespace mgcloth::solvers {

namespace {

void read_line_search(JsonReader& r, LineSearchParams& p) {
  p.armijo = r.number("armijo", p.armijo, 1e-12, 0.5);
  p.shrink = r.number("backtrack", p.shrink, 0.01, 0.99);
  p.max_steps = r.integer("max_line_search_steps", p.max_steps, 1, 200);
  p.refine = r.integer("line_search_refine", p.refine, 0, 50);
}
void write_line_search(Json& j, const LineSearchParams& p) {
  j["armijo"] = p.armijo;
  j["backtrack"] = p.shrink;
  j["max_line_search_steps"] = p.max_steps;
  j["line_search_refine"] = p.refine;
}

NewtonParams read_newton(JsonReader& r, NewtonParams p) {
  p.linear.method = r.choice("linear_solver", p.linear.method, linear_methods());
  // As a CG preconditioner a V(1,1)-cycle beats V(2,2): about 10 % more CG iterations at 30 % less cost each on the
  // frozen drape systems at 10K-250K vertices, and 0.71x / 0.87x the time of whole newton-mg runs of the shipped
  // drape and hanging scenes (bench/RESULTS.md, issue 3 and "Solver defaults"). `mg` keeps V(2,2): unmeasured.
  if (p.linear.method == "pcg-mg") p.linear.multigrid.pre_smooth = p.linear.multigrid.post_smooth = 1;
  p.linear.rel_tol = r.number("linear_tol", p.linear.rel_tol, 0.0, 0.9);
  p.linear.max_iters = r.integer("linear_max_iters", p.linear.max_iters, 1, 1'000'000);
  p.linear.multigrid.pre_smooth = r.integer("pre_smooth", p.linear.multigrid.pre_smooth, 0, 100);
  p.linear.multigrid.post_smooth = r.integer("post_smooth", p.linear.multigrid.post_smooth, 0, 100);
  p.linear.multigrid.chebyshev = r.boolean("chebyshev", p.linear.multigrid.chebyshev);
  p.project_psd = r.boolean("project_psd", p.project_psd);
  p.exact_hessian_below = r.number("exact_hessian_below", p.exact_hessian_below, 0.0, 1.0);
  p.use_line_search = r.boolean("line_search", p.use_line_search);
  read_line_search(r, p.line_search);
  return p;
}
Json write_newton(const NewtonParams& p) {
  Json j = {{"linear_solver", p.linear.method},
            {"linear_tol", p.linear.rel_tol},
            {"linear_max_iters", p.linear.max_iters},
            {"pre_smooth", p.linear.multigrid.pre_smooth},
            {"post_smooth", p.linear.multigrid.post_smooth},
            {"chebyshev", p.linear.multigrid.chebyshev},
            {"project_psd", p.project_psd},
            {"exact_hessian_below", p.exact_hessian_below},
            {"line_search", p.use_line_search}};
  write_line_search(j, p.line_search);
  return j;
}

FmgParams read_fmg(JsonReader& r, FmgParams p) {
  if (p.single_level) {
    p.multigrid.pre_smooth = r.integer("sweeps", p.multigrid.pre_smooth, 1, 100);
  } else {
    p.multigrid.pre_smooth = r.integer("pre_smooth", p.multigrid.pre_smooth, 0, 100);
    p.multigrid.post_smooth = r.integer("post_smooth", p.multigrid.post_smooth, 0, 100);
    p.residual_levels = r.integer("residual_levels", p.residual_levels, 0, 100);
    p.interleave = r.boolean("interleave", p.interleave);
    p.multigrid.chebyshev = r.boolean("chebyshev_smoothing", p.multigrid.chebyshev);
  }
  p.multigrid.single_precision_smoother =
      r.choice("smoother_precision", p.multigrid.single_precision_smoother ? "single" : "double", {"double", "single"}) == "single";
  p.matrix_update = matrix_update_from_string(r.choice("matrix_update", to_string(p.matrix_update), matrix_update_names()));
  p.refresh_below = r.number("refresh_below", p.refresh_below, 0.0, 1.0);
  p.line_search = r.boolean("line_search", p.line_search);
  p.adaptive_threshold = r.number("adaptive_threshold", p.adaptive_threshold, 0.0, 100.0);
  p.chebyshev_rho = r.number("chebyshev_rho", p.chebyshev_rho, 0.0, 0.9999);
  p.chebyshev_delay = r.integer("chebyshev_delay", p.chebyshev_delay, 0, 1000);
  p.momentum = r.boolean("momentum", p.momentum);
  p.project_psd = r.boolean("project_psd", p.project_psd);
  read_line_search(r, p.line_search_params);
  return p;
}
Json write_fmg(const FmgParams& p) {
  Json j = Json::object();
  if (p.single_level) {
    j["sweeps"] = p.multigrid.pre_smooth;
  } else {
    j["pre_smooth"] = p.multigrid.pre_smooth;
    j["post_smooth"] = p.multigrid.post_smooth;
    j["residual_levels"] = p.residual_levels;
    j["interleave"] = p.interleave;
    j["chebyshev_smoothing"] = p.multigrid.chebyshev;
  }
  j["smoother_precision"] = p.multigrid.single_precision_smoother ? "single" : "double";
  j["matrix_update"] = to_string(p.matrix_update);
  j["refresh_below"] = p.refresh_below;
  j["line_search"] = p.line_search;
  j["adaptive_threshold"] = p.adaptive_threshold;
  j["chebyshev_rho"] = p.chebyshev_rho;
  j["chebyshev_delay"] = p.chebyshev_delay;
  j["momentum"] = p.momentum;
  j["project_psd"] = p.project_psd;
  write_line_search(j, p.line_search_params);
  return j;
}

/// fmg-cuda: the settings the device pipeline implements, and which backend runs it.
struct FmgCudaConfig {
  cuda::FmgSettings s;
  FmgCycleParams cycle = FmgCuda::device_cycle();
  std::string backend = "cuda";
};
FmgCudaConfig read_fmg_cuda(JsonReader& r) {
  FmgCudaConfig c;
  cuda::FmgSettings& p = c.s;
  p.pre_smooth = r.integer("pre_smooth", p.pre_smooth, 0, 100);
  p.post_smooth = r.integer("post_smooth", p.post_smooth, 0, 100);
  p.chebyshev = r.boolean("chebyshev_smoothing", p.chebyshev);
  FmgCycleParams& q = c.cycle;
  q.matrix_update = matrix_update_from_string(r.choice("matrix_update", to_string(q.matrix_update), {"direction", "cycle", "step"}));
  p.adaptive_threshold = r.number("adaptive_threshold", p.adaptive_threshold, 0.0, 100.0);
  q.momentum = r.boolean("momentum", q.momentum);
  read_line_search(r, q.line_search_params);
  p.coarse_solve = r.choice("coarse_solve", p.coarse_solve, {"auto", "device", "host"});
  c.backend = r.choice("backend", c.backend, {"cuda", "host"});
  p.profile = r.boolean("profile", p.profile);
  p.graphs = r.boolean("graphs", p.graphs);
  p.compare_spgemm = r.boolean("compare_spgemm", p.compare_spgemm);
  return c;
}
Json write_fmg_cuda(const FmgCudaConfig& c) {
  const cuda::FmgSettings& p = c.s;
  const FmgCycleParams& q = c.cycle;
  Json j = {{"pre_smooth", p.pre_smooth},
            {"post_smooth", p.post_smooth},
            {"chebyshev_smoothing", p.chebyshev},
            {"matrix_update", to_string(q.matrix_update)},
            {"adaptive_threshold", p.adaptive_threshold},
            {"momentum", q.momentum},
            {"coarse_solve", p.coarse_solve},
            {"backend", c.backend},
            {"profile", p.profile},
            {"graphs", p.graphs},
            {"compare_spgemm", p.compare_spgemm}};
  write_line_search(j, q.line_search_params);
  return j;
}

FasParams read_fas(JsonReader& r, FasParams p) {
  p.pre_smooth = r.integer("pre_smooth", p.pre_smooth, 0, 100);
  p.post_smooth = r.integer("post_smooth", p.post_smooth, 0, 100);
  p.sweeps = r.integer("sweeps", p.sweeps, 1, 100);
  p.coarse_iters = r.integer("coarse_newton_iters", p.coarse_iters, 1, 100);
  p.project_psd = r.boolean("project_psd", p.project_psd);
  read_line_search(r, p.line_search);
  return p;
}
Json write_fas(const FasParams& p) {
  Json j = {{"pre_smooth", p.pre_smooth},
            {"post_smooth", p.post_smooth},
            {"sweeps", p.sweeps},
            {"coarse_newton_iters", p.coarse_iters},
            {"project_psd", p.project_psd}};
  write_line_search(j, p.line_search);
  return j;
}

TrustRegionParams read_trust_region(JsonReader& r, TrustRegionParams p) {
  p.eta1 = r.number("eta1", p.eta1, 0.0, 1.0);
  p.eta2 = r.number("eta2", p.eta2, 0.0, 1.0);
  if (!(0.0 < p.eta1 && p.eta1 <= p.eta2 && p.eta2 < 1.0))
    r.fail(r.has("eta2") ? "eta2" : "eta1", fmt::format("needs 0 < eta1 <= eta2 < 1 (got {}, {})", p.eta1, p.eta2));
  p.gamma1 = r.number("gamma1", p.gamma1, 0.0, 1.0);
  if (!(p.gamma1 > 0.0 && p.gamma1 < 1.0)) r.fail("gamma1", "must lie in (0, 1)");
  p.gamma2 = r.number("gamma2", p.gamma2, 1.0, 1e6);
  if (!(p.gamma2 > 1.0)) r.fail("gamma2", "must be > 1");
  p.delta0 = r.number("delta0", p.delta0, 1e-300, 1e300);
  p.delta_max = r.number("delta_max", p.delta_max, 1e-300, 1e300);
  if (p.delta_max < p.delta0) r.fail("delta_max", fmt::format("must be >= delta0 ({})", p.delta0));
  if (p.qp == TrQp::SteihaugCg) {
    p.stcg_max_iters = r.integer("stcg_max_iters", p.stcg_max_iters, 0, 100'000'000);
    p.stcg_rel_tol = r.number("stcg_rel_tol", p.stcg_rel_tol, 0.0, 0.9);
  }
  p.stagnation_tol = r.number("stagnation_tol", p.stagnation_tol, 0.0, 1.0);
  p.stagnation_delta = r.number("stagnation_delta", p.stagnation_delta, 0.0, kInf);
  p.roundoff_tol = r.number("roundoff_tol", p.roundoff_tol, 0.0, 1e-6);
  const std::string hessian = r.choice("hessian", p.psd_hessian ? "projected" : p.hybrid_hessian ? "hybrid" : "exact",
                                       {"exact", "projected", "hybrid"});
  p.psd_hessian = hessian == "projected";
  p.hybrid_hessian = hessian == "hybrid";
  p.shrink_from_step = r.boolean("shrink_from_step", p.shrink_from_step);
  p.shift_bisections = r.integer("shift_bisections", p.shift_bisections, 0, 20);
  p.radius_shift = r.choice("shift", p.radius_shift ? "radius" : "factorize", {"factorize", "radius"}) == "radius";
  p.extrapolate = r.integer("extrapolate", p.extrapolate, 0, 30);
  return p;
}
Json write_trust_region(const TrustRegionParams& p) {
  Json j = {{"eta1", p.eta1},
            {"eta2", p.eta2},
            {"gamma1", p.gamma1},
            {"gamma2", p.gamma2},
            {"delta0", p.delta0},
            {"delta_max", p.delta_max},
            {"stagnation_tol", p.stagnation_tol},
            {"stagnation_delta", p.stagnation_delta},
            {"roundoff_tol", p.roundoff_tol},
            {"hessian", p.psd_hessian ? "projected" : p.hybrid_hessian ? "hybrid" : "exact"},
            {"shrink_from_step", p.shrink_from_step},
            {"shift_bisections", p.shift_bisections},
            {"shift", p.radius_shift ? "radius" : "factorize"},
            {"extrapolate", p.extrapolate}};
  if (p.qp == TrQp::SteihaugCg) {
    j["stcg_max_iters"] = p.stcg_max_iters;
    j["stcg_rel_tol"] = p.stcg_rel_tol;
  }
  return j;
}

std::string qp_name(TrQp q) {
  return q == TrQp::Dogleg ? "dogleg" : q == TrQp::Exact ? "exact" : q == TrQp::GaussSeidel ? "gauss_seidel" : q == TrQp::Schwarz ? "schwarz" : "stcg";
}

RmtrParams read_rmtr(JsonReader& r, RmtrParams p) {
  p.tr = read_trust_region(r, p.tr);
  p.pre_smoothing = r.integer("pre_smoothing", p.pre_smoothing, 0, 1000);
  p.post_smoothing = r.integer("post_smoothing", p.post_smoothing, 0, 1000);
  if (p.pre_smoothing + p.post_smoothing == 0) r.fail("post_smoothing", "pre_smoothing + post_smoothing must be >= 1");
  p.coarsest_iters = r.integer("coarsest_iters", p.coarsest_iters, 0, 1'000'000);
  p.eps_delta = r.number("eps_delta", p.eps_delta, 0.0, 1.0);
  if (!(p.eps_delta > 0.0 && p.eps_delta < 1.0)) r.fail("eps_delta", "must lie in (0, 1)");
  p.smoother_cg_iters = r.integer("smoother_cg_iters", p.smoother_cg_iters, 1, 1'000'000);

  const auto parse_qp = [](const std::string& s) {
    return s == "dogleg"         ? TrQp::Dogleg
           : s == "exact"        ? TrQp::Exact
           : s == "gauss_seidel" ? TrQp::GaussSeidel
           : s == "schwarz"      ? TrQp::Schwarz
                                 : TrQp::SteihaugCg;
  };
  p.smoother_qp = parse_qp(r.choice("smoother", qp_name(p.smoother_qp), {"stcg", "dogleg", "exact", "gauss_seidel", "schwarz"}));
  p.tr.gs_sweeps = r.integer("smoother_sweeps", p.tr.gs_sweeps, 1, 1000);
  p.coarsest_qp = parse_qp(r.choice("coarsest_qp", qp_name(p.coarsest_qp), {"dogleg", "stcg", "exact"}));
  p.levels = r.integer("levels", p.levels, 0, 20);
  if (p.levels == 1) r.fail("levels", "RMTR needs at least 2 levels (0: all of the hierarchy); use tr-dogleg for one");
  p.projection = r.choice("projection", p.projection, {"reverse_subdivision", "least_squares"});
  p.level_norms = r.boolean("level_norms", p.level_norms);
  p.scaling = r.choice("scaling", p.scaling, {"none", "jacobi", "block_jacobi"});
  p.coarse_model = r.choice("coarse_model", p.coarse_model, {"first_order", "second_order"});
  p.coarse_abs_grad = r.number("coarse_abs_grad", p.coarse_abs_grad, 0.0, kInf);
  p.initial = r.choice("initial", p.initial, {"fine", "nested"});
  p.nested_rel_grad = r.number("nested_rel_grad", p.nested_rel_grad, 0.0, 1.0);
  if (!(p.nested_rel_grad > 0.0 && p.nested_rel_grad < 1.0)) r.fail("nested_rel_grad", "must lie in (0, 1)");
  p.nested_max_cycles = r.integer("nested_max_cycles", p.nested_max_cycles, 1, 1'000'000);
  p.nested_energy_tol = r.number("nested_energy_tol", p.nested_energy_tol, 0.0, 1.0);
  p.correction_backtracking = r.integer("correction_backtracking", p.correction_backtracking, 0, 60);
  p.coarse_start = r.choice("coarse_start", p.coarse_start, {"projection", "best"});
  return p;
}
Json write_rmtr(const RmtrParams& p) {
  TrustRegionParams tp = p.tr;
  tp.qp = TrQp::Dogleg;  // the TR block without the ST-CG keys, which the smoother settings replace
  Json j = write_trust_region(tp);
  j["pre_smoothing"] = p.pre_smoothing;
  j["post_smoothing"] = p.post_smoothing;
  j["coarsest_iters"] = p.coarsest_iters;
  j["eps_delta"] = p.eps_delta;
  j["smoother_cg_iters"] = p.smoother_cg_iters;
  j["smoother"] = qp_name(p.smoother_qp);
  j["smoother_sweeps"] = p.tr.gs_sweeps;
  j["coarsest_qp"] = qp_name(p.coarsest_qp);
  j["levels"] = p.levels;
  j["projection"] = p.projection;
  j["level_norms"] = p.level_norms;
  j["scaling"] = p.scaling;
  j["coarse_model"] = p.coarse_model;
  j["coarse_abs_grad"] = p.coarse_abs_grad;
  j["initial"] = p.initial;
  j["nested_rel_grad"] = p.nested_rel_grad;
  j["nested_max_cycles"] = p.nested_max_cycles;
  j["nested_energy_tol"] = p.nested_energy_tol;
  j["correction_backtracking"] = p.correction_backtracking;
  j["coarse_start"] = p.coarse_start;
  return j;
}

ExactNewtonParams read_exact_newton(JsonReader& r, ExactNewtonParams p) {
  if (p.mode == ExactNewtonMode::LineSearch) read_line_search(r, p.line_search);
  if (p.mode == ExactNewtonMode::Damped) p.alpha = r.number("alpha", p.alpha, 1e-6, 2.0);
  return p;
}
Json write_exact_newton(const ExactNewtonParams& p) {
  Json j = Json::object();
  if (p.mode == ExactNewtonMode::LineSearch) write_line_search(j, p.line_search);
  if (p.mode == ExactNewtonMode::Damped) j["alpha"] = p.alpha;
  return j;
}

/// The built-in configurations behind each solver name (docs/solvers.md documents them).
NewtonParams newton_preset(const std::string& name) {
  NewtonParams p;
  if (name == "newton-amg") p.linear.method = "pcg-amg";
  if (name == "newton-mg") p.linear.method = "pcg-mg";
  if (name == "pd-direct") {
    p.use_line_search = false;
    p.constant_matrix = true;
    p.exact_hessian_below = 0.0;
    p.projective = true;
  }
  return p;
}

FmgParams fmg_preset(const std::string& name) {
  FmgParams p;
  if (name == "gs-chebyshev" || name == "pd-gs-chebyshev") {
    p.single_level = true;
    p.multigrid.chebyshev = false;
    p.multigrid.pre_smooth = 1;
    p.chebyshev_rho = 0.9;
  }
  if (name == "pd-fmg" || name == "pd-gs-chebyshev") {
    p.projective = true;
    p.line_search = false;
    p.matrix_update = MatrixUpdate::Constant;
    p.project_psd = false;
  }
  if (name == "pd-fmg") {
    // Without a line search (§4.4) the coarse corrections of a small hierarchy can stall the iteration (measured:
    // no convergence to 1e-4 on a 100-vertex pinned sheet); with it every direction decreases the PD energy.
    p.line_search = true;
    p.multigrid.pre_smooth = p.multigrid.post_smooth = 2;
    p.chebyshev_rho = 0.0;
  }
  return p;
}

TrustRegionParams trust_region_preset(const std::string& name) {
  TrustRegionParams p;
  p.qp = name == "tr-stcg" ? TrQp::SteihaugCg : TrQp::Dogleg;  // "tr": the paper's TR, the dogleg (§7.3)
  return p;
}

ExactNewtonParams exact_newton_preset(const std::string& name) {
  ExactNewtonParams p;
  if (name == "newton-damped") p.mode = ExactNewtonMode::Damped;
  if (name == "linearized") p.mode = ExactNewtonMode::Linearized;
  return p;
}

/// `rmtr` is the best measured configuration for large motion (bench/RESULTS.md, Table 4 at 4–7 levels): dogleg
/// smoothing, nested iteration, the better of two coarse starts and the hybrid Hessian. `rmtr-paper` is
/// Kopaničáková 2019's own (ST-CG smoothing from the fine start), far slower on every scenario measured.
RmtrParams rmtr_preset(const std::string& name) {
  RmtrParams p;
  if (name == "rmtr") {
    p.smoother_qp = TrQp::Dogleg;
    p.initial = "nested";
    p.coarse_start = "best";
    p.tr.hybrid_hessian = true;
  }
  return p;
}

enum class Kind { Newton, Fmg, FmgCuda, Fas, TrustRegion, ExactNewton, Rmtr };
Kind kind_of(const std::string& name) {
  if (name == "newton" || name == "newton-direct" || name == "newton-amg" || name == "newton-mg" || name == "pd-direct")
    return Kind::Newton;
  if (name == "fas") return Kind::Fas;
  if (name == "fmg-cuda") return Kind::FmgCuda;
  if (name == "tr" || name == "tr-dogleg" || name == "tr-stcg") return Kind::TrustRegion;
  if (name == "rmtr" || name == "rmtr-paper") return Kind::Rmtr;
  if (name == "newton-ls" || name == "newton-damped" || name == "linearized") return Kind::ExactNewton;
  return Kind::Fmg;
}

}  // namespace

std::vector<std::string> solver_names() {
  return {"fmg", "fmg-cuda", "newton-direct", "newton-amg", "newton-mg", "fas", "gs-chebyshev", "pd-direct", "pd-gs-chebyshev",
          "pd-fmg", "newton", "tr", "tr-dogleg", "tr-stcg", "rmtr", "rmtr-paper", "newton-ls", "newton-damped", "linearized"};
}

namespace {
void check_name(const SolverConfig& c, const std::string& file, const std::string& path) {
  const auto names = solver_names();
  if (std::find(names.begin(), names.end(), c.name) == names.end()) {
    const std::string block = path.ends_with(".params") ? path.substr(0, path.size() - 7) : path;
    throw InputError(fmt::format("{}: {}.name: unknown solver \"{}\" (available: {})", file, block, c.name,
                                 fmt::join(names, ", ")));
  }
}
}  // namespace

std::unique_ptr<NonlinearSolver> make_solver(const SolverConfig& c, const std::string& file, const std::string& path) {
  check_name(c, file, path);
  JsonReader r(c.params, file, path);
  std::unique_ptr<NonlinearSolver> s;
  switch (kind_of(c.name)) {
    case Kind::Newton: s = std::make_unique<Newton>(read_newton(r, newton_preset(c.name)), c.name); break;
    case Kind::Fmg: s = std::make_unique<NonlinearFMG>(read_fmg(r, fmg_preset(c.name)), c.name); break;
    case Kind::FmgCuda: {
      const FmgCudaConfig fc = read_fmg_cuda(r);
      r.finish();
      return std::make_unique<FmgCuda>(fc.backend == "host" ? cuda::Backend::Host : cuda::Backend::Cuda, fc.s, fc.cycle, c.name);
    }
    case Kind::Fas: s = std::make_unique<Fas>(read_fas(r, FasParams{})); break;
    case Kind::TrustRegion:
      s = std::make_unique<TrustRegion>(read_trust_region(r, trust_region_preset(c.name)), c.name);
      break;
    case Kind::ExactNewton:
      s = std::make_unique<ExactNewton>(read_exact_newton(r, exact_newton_preset(c.name)), c.name);
      break;
    case Kind::Rmtr: s = std::make_unique<Rmtr>(read_rmtr(r, rmtr_preset(c.name)), c.name); break;
  }
  r.finish();
  return s;
}

Json resolved_params(const SolverConfig& c, const std::string& file, const std::string& path) {
  check_name(c, file, path);
  JsonReader r(c.params, file, path);
  Json j;
  switch (kind_of(c.name)) {
    case Kind::Newton: j = write_newton(read_newton(r, newton_preset(c.name))); break;
    case Kind::Fmg: j = write_fmg(read_fmg(r, fmg_preset(c.name))); break;
    case Kind::FmgCuda: j = write_fmg_cuda(read_fmg_cuda(r)); break;
    case Kind::Fas: j = write_fas(read_fas(r, FasParams{})); break;
    case Kind::TrustRegion: j = write_trust_region(read_trust_region(r, trust_region_preset(c.name))); break;
    case Kind::ExactNewton: j = write_exact_newton(read_exact_newton(r, exact_newton_preset(c.name))); break;
    case Kind::Rmtr: j = write_rmtr(read_rmtr(r, rmtr_preset(c.name))); break;
  }
  r.finish();
  return j;
}

}  // namespace mgcloth::solvers
