#include "bindings.hpp"

#include <mgcloth/core/log.hpp>
#include <mgcloth/core/out_of_memory.hpp>
#include <mgcloth/core/parallel.hpp>
#include <mgcloth/sim/scene.hpp>
#include <mgcloth/solvers/factory.hpp>

#include <pybind11/stl.h>

#include <cmath>

namespace mgcloth::python {

namespace {
std::string where(const std::string& path) { return path.empty() ? "(top level)" : path; }
}  // namespace

Json to_json(py::handle value, const std::string& path) {
  if (value.is_none()) return nullptr;
  // bool before int: Python's bool is an int.
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>();
  if (py::isinstance<py::int_>(value)) {
    try {
      return value.cast<long long>();
    } catch (const py::cast_error&) {
      throw_input_error("{}: integer {} is too large", where(path), py::str(value).cast<std::string>());
    }
  }
  if (py::isinstance<py::float_>(value)) return value.cast<double>();
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  // NumPy arrays and scalars (np.float64, np.int32, np.bool_): their Python equivalents.
  if (py::hasattr(value, "dtype") && py::hasattr(value, "tolist")) return to_json(value.attr("tolist")(), path);
  if (py::isinstance(value, py::module_::import("os").attr("PathLike")))
    return py::module_::import("os").attr("fspath")(value).cast<std::string>();
  if (py::isinstance<py::dict>(value) ||
      py::isinstance(value, py::module_::import("collections.abc").attr("Mapping"))) {
    Json j = Json::object();
    for (auto item : value.attr("items")()) {
      const auto kv = item.cast<py::tuple>();
      if (!py::isinstance<py::str>(kv[0]))
        throw_input_error("{}: keys must be strings, got {} {}", where(path), py::str(py::type::of(kv[0]).attr("__name__")).cast<std::string>(),
                          py::repr(kv[0]).cast<std::string>());
      const std::string key = kv[0].cast<std::string>();
      j[key] = to_json(kv[1], path.empty() ? key : path + "." + key);
    }
    return j;
  }
  if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
    Json j = Json::array();
    size_t i = 0;
    for (auto item : value) j.push_back(to_json(item, fmt::format("{}[{}]", path, i++)));
    return j;
  }
  throw_input_error("{}: cannot use a {} here (expected a dict, list, string, number, bool or None)", where(path),
                    py::str(py::type::of(value).attr("__name__")).cast<std::string>());
}

py::object from_json(const Json& j) {
  switch (j.type()) {
    case Json::value_t::null: return py::none();
    case Json::value_t::boolean: return py::bool_(j.get<bool>());
    case Json::value_t::number_integer: return py::int_(j.get<long long>());
    case Json::value_t::number_unsigned: return py::int_(j.get<unsigned long long>());
    case Json::value_t::number_float: return py::float_(j.get<double>());
    case Json::value_t::string: return py::str(j.get<std::string>());
    case Json::value_t::array: {
      py::list l;
      for (const auto& v : j) l.append(from_json(v));
      return l;
    }
    case Json::value_t::object: {
      py::dict d;
      for (const auto& [k, v] : j.items()) d[py::str(k)] = from_json(v);
      return d;
    }
    default: return py::none();  // binary and discarded values never come out of the library
  }
}

void bind_errors(py::module_& m) {
  // The CLI prints e.what() of these; Python gets the same text. InputError is also a ValueError, so that code
  // catching ValueError for bad arguments keeps working.
  static py::handle error = PyErr_NewExceptionWithDoc(
      "mgcloth.Error", "Every failure mgcloth reports; the message names the file, JSON path or element.",
      PyExc_RuntimeError, nullptr);
  static py::handle input_error = PyErr_NewExceptionWithDoc(
      "mgcloth.InputError", "Bad user input: a scene, a mesh, an array, a parameter (also a ValueError).",
      py::make_tuple(error, py::handle(PyExc_ValueError)).release().ptr(), nullptr);
  static py::handle solve_error = PyErr_NewExceptionWithDoc(
      "mgcloth.SolveError", "A solve that cannot continue: non-finite energy, a failed line search, a failed factorization.",
      error.ptr(), nullptr);
  static py::handle out_of_memory = PyErr_NewExceptionWithDoc(
      "mgcloth.OutOfMemoryError", "Memory ran out; the message says what was being built (also a MemoryError).",
      py::make_tuple(error, py::handle(PyExc_MemoryError)).release().ptr(), nullptr);
  m.add_object("Error", error);
  m.add_object("OutOfMemoryError", out_of_memory);
  m.add_object("InputError", input_error);
  m.add_object("SolveError", solve_error);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      PyErr_SetString(input_error.ptr(), e.what());
    } catch (const SolveError& e) {
      PyErr_SetString(solve_error.ptr(), e.what());
    } catch (const OutOfMemory& e) {
      PyErr_SetString(out_of_memory.ptr(), e.what());
    } catch (const std::bad_alloc&) {
      PyErr_SetString(out_of_memory.ptr(), "out of memory in mgcloth (where is not known: no builder named it)");
    } catch (const Error& e) {
      PyErr_SetString(error.ptr(), e.what());
    }
  });
}

}  // namespace mgcloth::python

using namespace mgcloth;
using namespace mgcloth::python;

PYBIND11_MODULE(_mgcloth, m) {
  m.doc() = "mgcloth's compiled core: meshes, the simulator, the recorder and the convergence benchmark (pybind11).";
  m.attr("__version__") = MGCLOTH_VERSION;
  bind_errors(m);
  bind_mesh(m);
  bind_simulator(m);
  bind_convergence(m);
  bind_sweep(m);

  m.def("solver_names", &solvers::solver_names,
        "Names of the solvers this build provides (a scene's solver.name, Simulation(solver=...)).");
  m.def("material_presets", &sim::material_presets, "Names of the material presets (a cloth's material.preset).");
  m.def(
      "load_json", [](const std::string& path) { return from_json(load_json(path)); }, py::arg("path"),
      "Reads a JSON file (a scene) into Python values with mgcloth's parser, whose syntax errors name the file, line "
      "and column as the CLI's do.");
  m.def(
      "set_log_level",
      [](const std::string& level) {
        const auto l = spdlog::level::from_str(level);
        if (l == spdlog::level::off && level != "off")
          throw_input_error("log level: unknown \"{}\" (expected trace, debug, info, warning, error, critical or off)", level);
        logger().set_level(l);
      },
      py::arg("level"),
      "Sets the level of the library's log on stderr: \"debug\", \"info\", \"warning\" (the default), \"error\" or "
      "\"off\".");
  m.def("num_threads", &num_threads,
        "Worker threads the library uses now (OpenMP); each simulation sets its scene's \"threads\" when it steps.");
}
