#pragma once
// The pybind11 module `mgcloth._mgcloth`: a thin layer over sim::Scene, sim::Simulator, sim::Recorder and the
// convergence benchmark. The pure-Python package (python/mgcloth/__init__.py) adds the keyword-argument front end.
#include <mgcloth/core/json.hpp>
#include <mgcloth/mesh/tri_mesh.hpp>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <string>

namespace mgcloth::python {

namespace py = pybind11;

/// A Python value (dict, list, str, number, bool, None, NumPy array or scalar, os.PathLike) as JSON, so that a
/// scene dict goes through the same parser as a scene file. `path` names the value in messages ("scene.cloths[0]").
Json to_json(py::handle value, const std::string& path);
py::object from_json(const Json& json);

/// A read-only NumPy view of `rows` x `cols` values at `data` (row-major, `row_stride` elements between rows), kept
/// alive by `owner`: the array is valid as long as the owner's buffer is, and reflects later changes to it.
template <class T>
py::array readonly_view(const T* data, py::ssize_t rows, py::ssize_t cols, py::ssize_t row_stride, py::handle owner) {
  py::array a(py::dtype::of<T>(), {rows, cols},
              {static_cast<py::ssize_t>(sizeof(T)) * row_stride, static_cast<py::ssize_t>(sizeof(T))}, data, owner);
  a.attr("flags").attr("writeable") = false;
  return a;
}
template <class T>
py::array readonly_view(const T* data, py::ssize_t size, py::handle owner) {
  py::array a(py::dtype::of<T>(), {size}, {static_cast<py::ssize_t>(sizeof(T))}, data, owner);
  a.attr("flags").attr("writeable") = false;
  return a;
}

/// `value` (anything numpy.asarray takes) as a C-contiguous float64 array of shape (n, cols) with finite entries;
/// InputError names the array (`name`) and says what a row holds (`what`).
py::array_t<double> float_rows(py::handle value, const std::string& name, py::ssize_t cols, const std::string& what);

/// Vertex positions V (n x 3), triangles F (m x 3, 0-based) and optional material coordinates uv (n x 2, metres) as a
/// validated mesh. Without uv a planar mesh is flattened onto its best-fit plane, as read_obj does for an OBJ without
/// vt. InputError names the array and the row at fault ("F: triangle 7 refers to vertex 120, but V has 100 rows").
mesh::TriMesh mesh_from_arrays(py::handle V, py::handle F, py::handle uv, const std::string& source);

/// What OpenMP would use with no "threads" in a scene (all cores, or OMP_NUM_THREADS), as the process started: the
/// thread count is process-wide, so every simulation sets its own before it steps.
int default_threads();

void bind_errors(py::module_& m);
void bind_mesh(py::module_& m);
void bind_simulator(py::module_& m);
void bind_convergence(py::module_& m);
void bind_sweep(py::module_& m);

}  // namespace mgcloth::python
