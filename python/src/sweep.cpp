// Parameter sweeps (`mgcloth sweep` in one process, sweep/sweep.hpp), with each run's result as a dict.
#include "bindings.hpp"

#include <mgcloth/sweep/sweep.hpp>

#include <pybind11/stl.h>

#include <cmath>
#include <filesystem>

namespace mgcloth::python {

namespace {

py::dict result_dict(const sweep::Sweep& s, size_t run, const std::optional<sweep::RunResult>& r) {
  py::dict d;
  d["run"] = run;
  d["folder"] = sweep::run_folder(".", run).lexically_normal().string();
  py::dict values;
  for (size_t p = 0; p < s.parameters.size(); ++p)
    values[py::str(s.parameters[p].column)] = from_json(s.parameters[p].values[s.runs[run][p]]);
  d["values"] = values;
  py::dict measures;
  const auto columns = s.measure_columns();
  if (!r) {
    d["status"] = "pending";
    d["message"] = "";
  } else {
    d["status"] = r->status;
    d["message"] = r->message;
    d["wall_s"] = r->wall_s;
    d["last_frame"] = r->frames;
    d["steps"] = r->steps;
    d["iterations"] = r->iterations;
    d["unconverged_steps"] = r->unconverged;
    d["resumed_from"] = r->resumed_from;
    for (size_t m = 0; m < columns.size() && m < r->measures.size(); ++m) measures[py::str(columns[m])] = r->measures[m];
  }
  d["measures"] = measures;
  return d;
}

}  // namespace

void bind_sweep(py::module_& m) {
  m.def(
      "run_sweep",
      [](py::handle sweep, const std::string& out, bool resume, bool retry_failed, int threads) {
        if (retry_failed && !resume) throw_input_error("retry_failed: only with resume=True");
        if (threads < 0 || threads > 1024) throw_input_error("threads: must be in [0, 1024] (got {})", threads);
        sweep::Sweep s;
        if (py::isinstance<py::str>(sweep) || py::isinstance(sweep, py::module_::import("os").attr("PathLike"))) {
          s = sweep::load_sweep(py::module_::import("os").attr("fspath")(sweep).cast<std::string>());
        } else {
          s = sweep::parse_sweep(to_json(sweep, "sweep"), "sweep", std::filesystem::current_path());
        }
        std::vector<std::optional<sweep::RunResult>> results;
        {
          py::gil_scoped_release release;
          sweep::RunOptions options;
          options.threads = threads;
          options.default_threads = default_threads();
          // Ctrl-C ends the sweep after the frame in progress (that run stays partial; resume=True continues it).
          options.stop = [] {
            py::gil_scoped_acquire acquire;
            return PyErr_CheckSignals() != 0;
          };
          results = sweep::run_serial(s, out, resume, retry_failed, options);
        }
        if (PyErr_Occurred()) throw py::error_already_set();
        py::list rows;
        for (size_t run = 0; run < s.size(); ++run) rows.append(result_dict(s, run, results[run]));
        return rows;
      },
      py::arg("sweep"), py::arg("out"), py::arg("resume") = false, py::arg("retry_failed") = false,
      py::arg("threads") = 0,
      "Runs a parameter sweep (a sweep file, or a dict in the same format whose relative scene path is the current "
      "folder's) one run after another in this process, as `mgcloth sweep` without MPI: runs/NNNNN/ per run and "
      "summary.csv in `out`. Returns one dict per run: run, status (ok, failed), message, values (column -> the "
      "run's parameter value), measures (column -> number, NaN where undefined), wall_s, last_frame, steps, "
      "iterations, unconverged_steps, resumed_from, folder (relative to `out`). Ctrl-C (KeyboardInterrupt) stops it "
      "after the frame in progress; resume=True continues.");
}

}  // namespace mgcloth::python
