#include <mgcloth/solvers/factory.hpp>
#include <mgcloth/solvers/fas.hpp>
#include <mgcloth/solvers/newton.hpp>
#include <mgcloth/solvers/nonlinear_fmg.hpp>

#include <functional>

namespace mgcloth::solvers {

namespace {

void read_line_search(JsonReader& r, LineSearchParams& p) {
  p.armijo = r.number("armijo", p.armijo, 1e-12, 0.5);
  p.shrink = r.number("backtrack", p.shrink, 0.01, 0.99);
  p.max_steps = r.integer("max_line_search_steps", p.max_steps, 1, 200);
}
void write_line_search(Json& j, const LineSearchParams& p) {
  j["armijo"] = p.armijo;
  j["backtrack"] = p.shrink;
  j["max_line_search_steps"] = p.max_steps;
}

NewtonParams read_newton(JsonReader& r, NewtonParams p) {
  p.linear.method = r.choice("linear_solver", p.linear.method, linear_methods());
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

enum class Kind { Newton, Fmg, Fas };
Kind kind_of(const std::string& name) {
  if (name == "newton" || name == "newton-direct" || name == "newton-amg" || name == "newton-mg" || name == "pd-direct")
    return Kind::Newton;
  if (name == "fas") return Kind::Fas;
  return Kind::Fmg;
}

}  // namespace

std::vector<std::string> solver_names() {
  return {"fmg", "newton-direct", "newton-amg", "newton-mg", "fas", "gs-chebyshev", "pd-direct", "pd-gs-chebyshev",
          "pd-fmg", "newton"};
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
    case Kind::Fas: s = std::make_unique<Fas>(read_fas(r, FasParams{})); break;
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
    case Kind::Fas: j = write_fas(read_fas(r, FasParams{})); break;
  }
  r.finish();
  return j;
}

}  // namespace mgcloth::solvers
