// The convergence benchmark of `mgcloth bench convergence` (studies/convergence.hpp), with its trace as arrays.
#include "bindings.hpp"

#include <mgcloth/core/file_io.hpp>
#include <mgcloth/studies/convergence.hpp>

#include <pybind11/stl.h>

#include <filesystem>

namespace mgcloth::python {

namespace {

struct PyConvergence {
  studies::ConvergenceResult result;
  studies::ConvergenceOptions options;
};

std::vector<std::string> labels(const studies::ConvergenceResult& r) {
  std::vector<std::string> out;
  for (const auto& s : r.summaries) out.push_back(s.solver);
  return out;
}

py::dict trace_of(const studies::ConvergenceResult& r, const std::string& solver) {
  std::vector<const studies::ConvergenceRow*> rows;
  for (const auto& row : r.rows)
    if (row.solver == solver) rows.push_back(&row);
  if (rows.empty()) {
    const auto names = labels(r);
    if (std::find(names.begin(), names.end(), solver) == names.end())
      throw_input_error("solver: \"{}\" was not benchmarked (benchmarked: {})", solver, fmt::join(names, ", "));
  }
  const auto n = static_cast<py::ssize_t>(rows.size());
  py::array_t<int> iteration(n);
  py::array_t<double> wall_s(n), energy(n), grad_norm(n), error(n);
  for (py::ssize_t i = 0; i < n; ++i) {
    iteration.mutable_at(i) = rows[i]->iteration;
    wall_s.mutable_at(i) = rows[i]->wall_s;
    energy.mutable_at(i) = rows[i]->energy;
    grad_norm.mutable_at(i) = rows[i]->grad_norm;
    error.mutable_at(i) = rows[i]->rel_energy_error;
  }
  py::dict d;
  d["iteration"] = iteration;
  d["wall_s"] = wall_s;
  d["energy"] = energy;
  d["grad_norm"] = grad_norm;
  d["rel_energy_error"] = error;
  return d;
}

/// The checks `mgcloth bench convergence` makes before anything runs, with its messages ("solvers" for
/// "--solvers", and so on).
void check(const studies::ConvergenceOptions& opt, Index vertices) {
  if (opt.step < 1) throw_input_error("step: must be at least 1 (got {})", opt.step);
  if (!(opt.budget_seconds > 0.0) || !std::isfinite(opt.budget_seconds))
    throw_input_error("budget: must be a positive number of seconds (got {})", opt.budget_seconds);
  if (opt.max_iters < 1) throw_input_error("max_iters: must be at least 1 (got {})", opt.max_iters);
  if (!(opt.reference_max_seconds > 0.0) || !std::isfinite(opt.reference_max_seconds))
    throw_input_error("reference_seconds: must be a positive number of seconds (got {})", opt.reference_max_seconds);
  if (opt.threads < 0) throw_input_error("threads: must be non-negative (got {})", opt.threads);
  if (vertices < 0) throw_input_error("vertices: must be positive (got {})", vertices);
  for (size_t i = 0; i < opt.solvers.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (opt.solvers[i].label == opt.solvers[j].label)
        throw_input_error("solvers: \"{}\" is listed twice", opt.solvers[i].label);
  for (const auto& s : opt.solvers) {
    try {
      studies::check_solver_spec(s);
    } catch (const InputError& e) {
      throw InputError(fmt::format("solvers: {}", e.what()));
    }
  }
}

}  // namespace

void bind_convergence(py::module_& m) {
  py::class_<PyConvergence>(m, "ConvergenceResult",
                            "The outcome of mgcloth.convergence(): every solver's trace on the frozen step, as arrays, "
                            "and the summary that convergence.json holds.")
      .def_property_readonly("solvers", [](const PyConvergence& c) { return labels(c.result); },
                             "The benchmarked solver specs (labels), in the order given.")
      .def("trace", [](const PyConvergence& c, const std::string& solver) { return trace_of(c.result, solver); },
           py::arg("solver"),
           "One solver's timed run, one entry per iteration (iteration 0 is the start point): a dict of arrays "
           "iteration, wall_s, energy, grad_norm and rel_energy_error = (E_k - E*)/(E_0 - E*).")
      .def_property_readonly(
          "traces",
          [](const PyConvergence& c) {
            py::dict d;
            for (const auto& s : labels(c.result)) d[py::str(s)] = trace_of(c.result, s);
            return d;
          },
          "trace() of every solver, by label.")
      .def_property_readonly("summary", [](const PyConvergence& c) { return from_json(studies::to_json(c.result, c.options)); },
                             "What convergence.json holds: E* per energy form and how it was reached, the options, "
                             "and per solver the time to errors 1e-2, 1e-3 and 1e-4, the final error and the iterations.")
      .def_property_readonly("vertices", [](const PyConvergence& c) { return c.result.vertices; },
                             "Vertices of the benchmarked cloth (cloth 0).")
      .def_property_readonly("cloth", [](const PyConvergence& c) { return c.result.cloth; },
                             "Name of the benchmarked cloth.")
      .def_property_readonly("step", [](const PyConvergence& c) { return c.result.step; },
                             "The benchmarked step K.")
      .def("csv", [](const PyConvergence& c) { return studies::convergence_csv(c.result); },
           "The text of convergence.csv (solver,iteration,wall_s,energy,grad_norm,rel_energy_error).")
      .def("__repr__", [](const PyConvergence& c) {
        return fmt::format("<mgcloth.ConvergenceResult step {} of \"{}\" ({} vertices): {}>", c.result.step,
                           c.result.cloth, c.result.vertices, fmt::join(labels(c.result), ", "));
      });

  m.def(
      "_convergence",
      [](py::handle scene, const std::string& file, const std::string& base_dir, const std::vector<std::string>& solvers,
         int step, double budget, int max_iters, int threads, std::optional<Index> vertices,
         const std::string& state_cache, double reference_seconds, py::handle out, const std::string& body) {
        Json j;
        try {
          j = to_json(scene, "");
        } catch (const InputError& e) {
          throw InputError(fmt::format("{}: {}", file, e.what()));
        }
        sim::Scene s = sim::parse_scene(j, file, base_dir);
        auto c = std::make_unique<PyConvergence>();
        auto& opt = c->options;
        if (solvers.empty()) throw_input_error("solvers: needs at least one solver");
        for (const auto& spec : solvers) {
          try {
            opt.solvers.push_back(studies::parse_solver_spec(spec));
          } catch (const InputError& e) {
            throw InputError(fmt::format("solvers: {}", e.what()));
          }
        }
        opt.step = step;
        opt.budget_seconds = budget;
        opt.max_iters = max_iters;
        opt.threads = threads;
        opt.state_cache = state_cache;
        opt.body = body;
        opt.reference_max_seconds = reference_seconds;
        check(opt, vertices.value_or(1));
        if (vertices) {
          try {
            s = studies::with_vertex_count(std::move(s), *vertices);
          } catch (const InputError& e) {
            throw InputError(fmt::format("vertices: {}", e.what()));
          }
        }
        {
          py::gil_scoped_release release;
          c->result = studies::run_convergence(s, opt);
        }
        if (!out.is_none()) {
          const std::filesystem::path dir = py::module_::import("os").attr("fspath")(out).cast<std::string>();
          std::filesystem::create_directories(dir);
          write_file_atomic(dir / "convergence.csv", studies::convergence_csv(c->result));
          write_file_atomic(dir / "convergence.json", studies::to_json(c->result, opt).dump(2) + "\n");
        }
        return c;
      },
      py::arg("scene"), py::arg("file"), py::arg("base_dir"), py::arg("solvers"), py::arg("step"), py::arg("budget"),
      py::arg("max_iters"), py::arg("threads"), py::arg("vertices"), py::arg("state_cache"),
      py::arg("reference_seconds"), py::arg("out"), py::arg("body") = "",
      "The convergence benchmark on a scene dict (mgcloth.convergence() is the front end): see "
      "studies::run_convergence and `mgcloth bench convergence`.");
}

}  // namespace mgcloth::python
