// Meshes between NumPy arrays and mesh::TriMesh.
#include "bindings.hpp"

#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/mesh/obj_io.hpp>

#include <Eigen/Eigenvalues>
#include <pybind11/stl.h>

#include <cmath>

namespace mgcloth::python {

// Triangles are viewed and copied as rows of three indices.
static_assert(sizeof(Tri) == 3 * sizeof(Index));

namespace {

std::string dtype_name(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t k = 0; k < a.ndim(); ++k) s += fmt::format("{}{}", k ? ", " : "", a.shape(k));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

}  // namespace

py::array_t<double> float_rows(py::handle value, const std::string& name, py::ssize_t cols, const std::string& what) {
  const py::array a = py::module_::import("numpy").attr("asarray")(value);
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw_input_error("{}: expected an (n, {}) array of {} (numbers), got dtype {}", name, cols, what, dtype_name(a));
  if (a.ndim() != 2 || a.shape(1) != cols)
    throw_input_error("{}: expected an (n, {}) array of {}, got shape {}", name, cols, what, shape_text(a));
  auto d = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  const auto r = d.unchecked<2>();
  for (py::ssize_t i = 0; i < r.shape(0); ++i)
    for (py::ssize_t k = 0; k < cols; ++k)
      if (!std::isfinite(r(i, k)))
        throw_input_error("{}: row {} is not finite ({})", name, i,
                          py::repr(py::array(d)[py::int_(i)].attr("tolist")()).cast<std::string>());
  return d;
}

namespace {

py::tuple arrays_of(const mesh::TriMesh& m) {
  py::array_t<double> V({static_cast<py::ssize_t>(m.num_vertices()), py::ssize_t{3}});
  std::memcpy(V.mutable_data(), m.x.data(), sizeof(double) * m.x.size());
  py::array_t<Index> F({static_cast<py::ssize_t>(m.num_triangles()), py::ssize_t{3}});
  if (!m.tris.empty()) std::memcpy(F.mutable_data(), m.tris.data(), sizeof(Tri) * m.tris.size());
  return py::make_tuple(V, F);
}

}  // namespace

mesh::TriMesh mesh_from_arrays(py::handle V, py::handle F, py::handle uv, const std::string& source) {
  const auto x = float_rows(V, "V", 3, "vertex positions");
  const py::ssize_t n = x.shape(0);
  if (n < 3) throw_input_error("V: a mesh needs at least 3 vertices, got {}", n);
  const py::array f = py::module_::import("numpy").attr("asarray")(F);
  if (f.dtype().kind() != 'i' && f.dtype().kind() != 'u')
    throw_input_error("F: expected an (m, 3) array of integer vertex indices, got dtype {}{}", dtype_name(f),
                      f.dtype().kind() == 'f' ? " (convert whole numbers with F.astype(int))" : "");
  if (f.ndim() != 2 || f.shape(1) != 3)
    throw_input_error("F: expected an (m, 3) array of vertex indices (one triangle a row), got shape {}", shape_text(f));
  if (f.shape(0) == 0) throw_input_error("F: a mesh needs at least one triangle, got none");
  const auto tri = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(f);
  const auto t = tri.unchecked<2>();

  mesh::TriMesh m;
  m.x.resize(3, n);
  std::memcpy(m.x.data(), x.data(), sizeof(double) * 3 * n);
  m.tris.resize(t.shape(0));
  for (py::ssize_t j = 0; j < t.shape(0); ++j)
    for (int k = 0; k < 3; ++k) {
      const long long v = t(j, k);
      if (v < 0 || v >= n)
        throw_input_error("F: triangle {} refers to vertex {}, but V has {} rows (indices are 0-based)", j, v, n);
      m.tris[j][k] = static_cast<Index>(v);
    }
  if (uv.is_none()) {
    m.u = mesh::flatten_planar(m.x, m.tris, source, "no material coordinates (uv) given and the mesh is not planar",
                               "pass uv, an (n, 2) array in metres");
  } else {
    const auto u = float_rows(uv, "uv", 2, "material coordinates");
    if (u.shape(0) != n)
      throw_input_error("uv: has {} rows but V has {} (one material coordinate per vertex)", u.shape(0), n);
    m.u.resize(2, n);
    std::memcpy(m.u.data(), u.data(), sizeof(double) * 2 * n);
  }
  mesh::validate(m, source);
  return m;
}

void bind_mesh(py::module_& m) {
  py::class_<mesh::TriMesh, std::shared_ptr<mesh::TriMesh>>(
      m, "Mesh",
      "A validated triangle mesh with material (rest) coordinates: what a cloth is made of. Its arrays are read-only "
      "views; build a new Mesh to change it.")
      .def(py::init([](py::handle V, py::handle F, py::handle uv) {
             return std::make_shared<mesh::TriMesh>(mesh_from_arrays(V, F, uv, "mesh arrays"));
           }),
           py::arg("V"), py::arg("F"), py::arg("uv") = py::none(),
           "Builds a mesh from vertex positions V (n, 3), triangles F (m, 3; 0-based integer indices) and optional "
           "material coordinates uv (n, 2, metres: the flat rest shape). Without uv the mesh must be planar and is "
           "flattened onto its best-fit plane (a sheet in z = 0 gets uv = (x, y)), as for an OBJ without vt. Raises "
           "InputError naming the array and row at fault: wrong shapes or dtypes, non-finite values, out-of-range "
           "indices, and what mgcloth rejects in any mesh (zero-area or repeated-vertex triangles, unused vertices, "
           "edges shared by more than two triangles, inconsistent orientation).")
      .def_static(
          "read_obj",
          [](const std::string& path, double material_scale) {
            return std::make_shared<mesh::TriMesh>(mesh::read_obj(path, material_scale));
          },
          py::arg("path"), py::arg("material_scale") = 1.0,
          "Reads an OBJ file as a scene's mesh file is read: vt times material_scale (metres per UV unit) as material "
          "coordinates, vertices split at UV seams (stitched again by seam springs), a planar mesh without vt "
          "flattened.")
      .def(
          "write_obj",
          [](const mesh::TriMesh& mesh, const std::string& path, py::handle positions) {
            if (positions.is_none()) return mesh::write_obj(path, mesh, mesh.x, 1.0);
            const auto x = float_rows(positions, "positions", 3, "vertex positions");
            if (x.shape(0) != mesh.num_vertices())
              throw_input_error("positions: has {} rows but the mesh has {} vertices", x.shape(0), mesh.num_vertices());
            mesh::write_obj(path, mesh, Eigen::Map<const Mat3X>(x.data(), 3, mesh.num_vertices()), 1.0);
          },
          py::arg("path"), py::arg("positions") = py::none(),
          "Writes the mesh as OBJ (positions, or the mesh's own when None; material coordinates as vt in metres), "
          "atomically, in the format of mgcloth's frame files.")
      .def_property_readonly(
          "vertices",
          [](py::object self) {
            const auto& t = self.cast<const mesh::TriMesh&>();
            return readonly_view(t.x.data(), t.num_vertices(), 3, 3, self);
          },
          "Vertex positions, a read-only (n, 3) float64 view.")
      .def_property_readonly(
          "triangles",
          [](py::object self) {
            const auto& t = self.cast<const mesh::TriMesh&>();
            return readonly_view(t.tris.empty() ? nullptr : t.tris[0].data(), t.num_triangles(), 3, 3, self);
          },
          "Triangles, a read-only (m, 3) int32 view of 0-based vertex indices, counter-clockwise in material space.")
      .def_property_readonly(
          "material_coordinates",
          [](py::object self) {
            const auto& t = self.cast<const mesh::TriMesh&>();
            return readonly_view(t.u.data(), t.num_vertices(), 2, 2, self);
          },
          "Material (rest) coordinates in metres, a read-only (n, 2) float64 view.")
      .def_property_readonly("num_vertices", &mesh::TriMesh::num_vertices, "Number of vertices.")
      .def_property_readonly("num_triangles", &mesh::TriMesh::num_triangles, "Number of triangles.")
      .def("__repr__", [](const mesh::TriMesh& t) {
        return fmt::format("<mgcloth.Mesh: {} vertices, {} triangles>", t.num_vertices(), t.num_triangles());
      });

  m.def(
      "grid",
      [](double width, double height, long long vertices, bool unstructured, std::uint64_t seed) {
        // The scene's limits (a billion vertices would allocate until the system killed the process).
        if (vertices < 4 || vertices > mesh::kMaxGeneratedVertices)
          throw_input_error("grid: vertices must be in [4, {}], got {}", mesh::kMaxGeneratedVertices, vertices);
        if (!(width > 0.0 && std::isfinite(width)) || !(height > 0.0 && std::isfinite(height)))
          throw_input_error("grid: width and height must be positive and finite, got {} and {}", width, height);
        mesh::RectangleSpec spec;
        spec.width = width;
        spec.height = height;
        spec.target_vertices = static_cast<Index>(vertices);
        spec.unstructured = unstructured;
        spec.seed = seed;
        return arrays_of(mesh::make_rectangle(spec));
      },
      py::arg("width") = 1.0, py::arg("height") = 1.0, py::arg("vertices") = 10000, py::arg("unstructured") = false,
      py::arg("seed") = 1,
      "A rectangular cloth [0, width] x [0, height] in the plane z = 0 with about `vertices` vertices, as the scene "
      "generator \"rectangle\" makes it (regular grid with alternating diagonals, or with unstructured=True a "
      "Poisson-disk triangulation). Returns (V, F): float64 positions (n, 3) and int32 triangles (m, 3); vertices are "
      "numbered row by row from (0, 0). InputError (a ValueError) for vertices outside [4, 5000000], as in a scene.");
}

}  // namespace mgcloth::python
