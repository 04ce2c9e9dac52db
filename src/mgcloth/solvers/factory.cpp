#include <mgcloth/solvers/factory.hpp>
#include <mgcloth/solvers/newton.hpp>

namespace mgcloth::solvers {

namespace {
NewtonParams newton_params(const Json& j, const std::string& file, const std::string& path) {
  JsonReader r(j, file, path);
  NewtonParams p;
  p.linear.method = r.choice("linear_solver", p.linear.method, linear_methods());
  p.linear.rel_tol = r.number("linear_tol", p.linear.rel_tol, 0.0, 0.9);
  p.linear.max_iters = r.integer("linear_max_iters", p.linear.max_iters, 1, 1'000'000);
  p.linear.multigrid.pre_smooth = r.integer("pre_smooth", p.linear.multigrid.pre_smooth, 0, 100);
  p.linear.multigrid.post_smooth = r.integer("post_smooth", p.linear.multigrid.post_smooth, 0, 100);
  p.linear.multigrid.chebyshev = r.boolean("chebyshev", p.linear.multigrid.chebyshev);
  p.project_psd = r.boolean("project_psd", p.project_psd);
  p.exact_hessian_below = r.number("exact_hessian_below", p.exact_hessian_below, 0.0, 1.0);
  p.line_search.armijo = r.number("armijo", p.line_search.armijo, 1e-12, 0.5);
  p.line_search.shrink = r.number("backtrack", p.line_search.shrink, 0.01, 0.99);
  p.line_search.max_steps = r.integer("max_line_search_steps", p.line_search.max_steps, 1, 200);
  r.finish();
  return p;
}
Json to_json(const NewtonParams& p) {
  return {{"linear_solver", p.linear.method},
          {"linear_tol", p.linear.rel_tol},
          {"linear_max_iters", p.linear.max_iters},
          {"pre_smooth", p.linear.multigrid.pre_smooth},
          {"post_smooth", p.linear.multigrid.post_smooth},
          {"chebyshev", p.linear.multigrid.chebyshev},
          {"project_psd", p.project_psd},
          {"exact_hessian_below", p.exact_hessian_below},
          {"armijo", p.line_search.armijo},
          {"backtrack", p.line_search.shrink},
          {"max_line_search_steps", p.line_search.max_steps}};
}
}  // namespace

std::vector<std::string> solver_names() { return {"newton"}; }

std::unique_ptr<NonlinearSolver> make_solver(const SolverConfig& c, const std::string& file, const std::string& path) {
  if (c.name == "newton") return std::make_unique<Newton>(newton_params(c.params, file, path));
  throw InputError(fmt::format("{}: {}.name: unknown solver \"{}\" (available: {})", file, path, c.name,
                               fmt::join(solver_names(), ", ")));
}

Json resolved_params(const SolverConfig& c, const std::string& file, const std::string& path) {
  if (c.name == "newton") return to_json(newton_params(c.params, file, path));
  return c.params;
}

}  // namespace mgcloth::solvers
