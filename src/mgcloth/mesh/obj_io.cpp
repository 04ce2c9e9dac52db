#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/mesh/obj_io.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <regex>
#include <sstream>

namespace mgcloth::mesh {

namespace {

/// A mesh without vt is accepted when no vertex is farther than this from the best-fit plane, relative to the
/// bounding-box diagonal: loose enough for coordinates printed with ~7 significant digits, tight enough that the
/// flattening changes edge lengths by a negligible strain.
constexpr double kPlanarityTolerance = 1e-6;

struct Corner {
  Index v;   ///< position index (0-based)
  Index vt;  ///< texture-coordinate index, -1 when absent
};

/// One face statement as tinyobjloader returned it, faces numbered in file order.
struct Faces {
  std::vector<Index> offsets{0};
  std::vector<Corner> corners;
  Index size() const { return static_cast<Index>(offsets.size()) - 1; }
};

/// Line numbers are only needed for error messages, so the text is scanned again only when one is raised.
/// Returns the 1-based line of the `face`-th (0-based) face statement, or 0 if there are fewer.
Index line_of_face(const std::string& text, Index face) {
  Index line = 0, seen = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    ++line;
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::size_t p = text.find_first_not_of(" \t", pos);
    if (p != std::string::npos && p + 1 < end && text[p] == 'f' && (text[p + 1] == ' ' || text[p + 1] == '\t')) {
      if (seen == face) return line;
      ++seen;
    }
    pos = end + 1;
  }
  return 0;
}

/// The first face statement with fewer than three corners (tinyobjloader drops those with a bare warning).
Index line_of_short_face(const std::string& text) {
  std::istringstream in(text);
  std::string l;
  Index line = 0;
  while (std::getline(in, l)) {
    ++line;
    std::istringstream words(l);
    std::string w;
    if (!(words >> w) || w != "f") continue;
    int n = 0;
    while (words >> w) ++n;
    if (n < 3) return line;
  }
  return 0;
}

std::string face_location(const std::string& text, Index face) {
  const Index line = line_of_face(text, face);
  return line > 0 ? fmt::format("line {}", line) : fmt::format("face {}", face + 1);
}

bool is_benign_warning(const std::string& line) {
  // Materials do not matter to cloth, and the index bounds are checked below with a line number.
  return line.empty() || line == "." || line.find("material") != std::string::npos ||
         line.rfind("Vertex indices out of bounds", 0) == 0 ||
         line.rfind("Vertex texcoord indices out of bounds", 0) == 0 || line.rfind("Empty group name", 0) == 0;
}

void check_warnings(const std::string& warn, const std::string& text, const std::string& source) {
  std::istringstream in(warn);
  std::string line;
  while (std::getline(in, line)) {
    if (is_benign_warning(line)) continue;
    if (line.rfind("Degenerated face", 0) == 0) {
      const Index l = line_of_short_face(text);
      throw_input_error("{}: {}face with fewer than three vertices", source, l > 0 ? fmt::format("line {}: ", l) : "");
    }
    if (line.rfind("Vertex normal indices out of bounds", 0) == 0)  // tinyobjloader's line number is the last one
      throw_input_error("{}: a face refers to a vertex normal (vn) that the file does not define", source);
    throw_input_error("{}: {}", source, line);
  }
  if (!warn.empty()) logger().debug("{}: tinyobjloader: {}", source, warn);
}

Faces collect_faces(const tinyobj::attrib_t& attrib, const std::vector<tinyobj::shape_t>& shapes,
                    const std::string& text, const std::string& source) {
  const Index num_v = static_cast<Index>(attrib.vertices.size() / 3);
  const Index num_vt = static_cast<Index>(attrib.texcoords.size() / 2);
  Faces faces;
  for (const tinyobj::shape_t& shape : shapes) {
    std::size_t corners = 0;
    for (const auto n : shape.mesh.num_face_vertices) corners += n;
    if (corners != shape.mesh.indices.size())  // tinyobjloader counts corners in an unsigned char
      throw_input_error("{}: a face has more than 255 vertices", source);
    std::size_t k = 0;
    for (const auto n : shape.mesh.num_face_vertices) {
      const Index f = faces.size();
      for (unsigned i = 0; i < n; ++i, ++k) {
        const tinyobj::index_t& c = shape.mesh.indices[k];
        // tinyobjloader has already resolved relative (negative) indices; a negative result points before the
        // first element.
        if (c.vertex_index >= num_v)
          throw_input_error("{}: {}: face refers to vertex {}, but the file has {} vertices (v lines)", source,
                            face_location(text, f), c.vertex_index + 1, num_v);
        if (c.vertex_index < 0)
          throw_input_error("{}: {}: face has a relative vertex index before the first vertex", source,
                            face_location(text, f));
        if (c.texcoord_index >= num_vt)
          throw_input_error("{}: {}: face refers to texture coordinate {}, but the file has {} (vt lines)", source,
                            face_location(text, f), c.texcoord_index + 1, num_vt);
        if (c.texcoord_index < -1)
          throw_input_error("{}: {}: face has a relative texture-coordinate index before the first one", source,
                            face_location(text, f));
        faces.corners.push_back({c.vertex_index, c.texcoord_index < 0 ? -1 : c.texcoord_index});
      }
      faces.offsets.push_back(static_cast<Index>(faces.corners.size()));
    }
  }
  if (faces.size() == 0) throw_input_error("{}: contains no faces (f lines)", source);

  // Texture coordinates are all-or-nothing: a mesh cannot be partly parameterized.
  const bool first_has_vt = faces.corners[0].vt >= 0;
  for (Index f = 0; f < faces.size(); ++f)
    for (Index c = faces.offsets[f]; c < faces.offsets[f + 1]; ++c)
      if ((faces.corners[c].vt >= 0) != first_has_vt)
        throw_input_error("{}: {}: face {} texture coordinates (vt) but the first face {}; use them on every face or "
                          "none",
                          source, face_location(text, f), first_has_vt ? "lacks" : "has",
                          first_has_vt ? "has them" : "does not");
  return faces;
}

/// Vertices are the distinct (v, vt) pairs, numbered in (v, vt) order, so that a file written by write_obj
/// (vertex i is v i / vt i) reads back with the same numbering. Bucketing by v keeps this linear.
void split_vertices(const Faces& faces, Index num_v, TriMesh& mesh, std::vector<Index>& corner_vertex,
                    std::vector<Index>& vertex_vt) {
  std::vector<Index> start(static_cast<std::size_t>(num_v) + 1, 0);
  for (const Corner& c : faces.corners) ++start[c.v + 1];
  for (Index v = 0; v < num_v; ++v) start[v + 1] += start[v];
  std::vector<Index> vts(faces.corners.size());
  std::vector<Index> fill(start.begin(), start.end() - 1);
  for (const Corner& c : faces.corners) vts[fill[c.v]++] = c.vt;

  // Sort and deduplicate each bucket in place; `first_vertex[v]` numbers the survivors.
  std::vector<Index> first_vertex(static_cast<std::size_t>(num_v) + 1, 0);
  std::vector<Index> unique_end(num_v);
  for (Index v = 0; v < num_v; ++v) {
    auto b = vts.begin() + start[v], e = vts.begin() + start[v + 1];
    std::sort(b, e);
    unique_end[v] = static_cast<Index>(std::unique(b, e) - vts.begin());
    first_vertex[v + 1] = first_vertex[v] + (unique_end[v] - start[v]);
  }
  const Index n = first_vertex[num_v];
  mesh.source_vertex.resize(n);
  vertex_vt.resize(n);
  for (Index v = 0; v < num_v; ++v)
    for (Index j = start[v]; j < unique_end[v]; ++j) {
      mesh.source_vertex[first_vertex[v] + j - start[v]] = v;
      vertex_vt[first_vertex[v] + j - start[v]] = vts[j];
    }
  corner_vertex.resize(faces.corners.size());
  for (std::size_t c = 0; c < faces.corners.size(); ++c) {
    const Corner& k = faces.corners[c];
    const auto b = vts.begin() + start[k.v], e = vts.begin() + unique_end[k.v];
    corner_vertex[c] = first_vertex[k.v] + static_cast<Index>(std::lower_bound(b, e, k.vt) - b);
  }
}

}  // namespace

Mat2X flatten_planar(const Mat3X& x, const std::vector<Tri>& tris, const std::string& source, std::string_view what,
                     std::string_view remedy) {
  const Vec3 centroid = x.rowwise().mean();
  const Mat3X d = x.colwise() - centroid;
  Eigen::SelfAdjointEigenSolver<Mat3> eig(d * d.transpose());
  Vec3 normal = eig.eigenvectors().col(0);  // eigenvalues ascending: least variance
  const double diagonal = (x.rowwise().maxCoeff() - x.rowwise().minCoeff()).norm();
  const double off_plane = (normal.transpose() * d).cwiseAbs().maxCoeff();
  if (off_plane > kPlanarityTolerance * diagonal)
    throw_input_error("{}: {} (a vertex lies {:.3g} from the best-fit plane, bounding-box diagonal {:.3g}); {}", source,
                      what, off_plane, diagonal, remedy);

  for (int a = 0; a < 3; ++a)  // snap an axis-aligned plane so that u copies x exactly
    if (std::abs(normal[a]) > 1.0 - 1e-14) normal = Vec3::Unit(a) * (normal[a] > 0 ? 1.0 : -1.0);
  Vec3 winding = Vec3::Zero();
  for (const Tri& f : tris) winding += (x.col(f[1]) - x.col(f[0])).cross(x.col(f[2]) - x.col(f[0]));
  if (winding.dot(normal) < 0.0) normal = -normal;

  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(normal[a]) < std::abs(normal[axis]) - 1e-12) axis = a;
  const Vec3 e1 = (Vec3::Unit(axis) - normal[axis] * normal).normalized();
  const Vec3 e2 = normal.cross(e1);
  Mat2X u(2, x.cols());
  u.row(0) = e1.transpose() * x;
  u.row(1) = e2.transpose() * x;
  return u;
}


TriMesh read_obj(const std::filesystem::path& path, double material_scale, bool check) {
  const std::string source = path.string();
  if (!(material_scale > 0.0) || !std::isfinite(material_scale))
    throw_input_error("{}: material_scale must be positive and finite (got {})", source, material_scale);
  const std::string text = read_file(path);  // InputError "<path>: cannot open file"

  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::string warn, err;
  std::istringstream stream(text);
  // No material reader: mtllib lines are skipped, a cloth needs no .mtl. Polygons are fanned below, not by
  // tinyobjloader (which splits quads along the shorter diagonal).
  const bool ok = tinyobj::LoadObj(&attrib, &shapes, &materials, &warn, &err, &stream, nullptr,
                                   /*triangulate=*/false, /*default_vcols_fallback=*/false);
  if (!ok || !err.empty()) {
    // tinyobjloader's parse errors are indices it cannot read: "Failed parse `f' line(...line N.)".
    std::smatch m;
    if (std::regex_search(err, m, std::regex("`([a-z]+)' line.*line ([0-9]+)")))
      throw_input_error("{}: line {}: cannot parse the `{}` statement (indices must be non-zero integers)", source,
                        m[2].str(), m[1].str());
    const std::string first = err.substr(0, err.find('\n'));
    throw_input_error("{}: {}", source, first.empty() ? "cannot parse" : first);
  }
  check_warnings(warn, text, source);

  const Index num_v = static_cast<Index>(attrib.vertices.size() / 3);
  const Faces faces = collect_faces(attrib, shapes, text, source);

  TriMesh mesh;
  std::vector<Index> corner_vertex, vertex_vt;
  split_vertices(faces, num_v, mesh, corner_vertex, vertex_vt);
  const Index n = static_cast<Index>(mesh.source_vertex.size());
  mesh.x.resize(3, n);
  for (Index i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) mesh.x(k, i) = attrib.vertices[3 * mesh.source_vertex[i] + k];

  for (Index f = 0; f < faces.size(); ++f)  // fan: (c0, c_i, c_i+1)
    for (Index c = faces.offsets[f] + 1; c + 1 < faces.offsets[f + 1]; ++c)
      mesh.tris.push_back({corner_vertex[faces.offsets[f]], corner_vertex[c], corner_vertex[c + 1]});

  if (vertex_vt[0] >= 0) {
    mesh.u.resize(2, n);
    for (Index i = 0; i < n; ++i)
      for (int k = 0; k < 2; ++k) mesh.u(k, i) = material_scale * attrib.texcoords[2 * vertex_vt[i] + k];
  } else {
    mesh.u = flatten_planar(mesh.x, mesh.tris, source, "has no texture coordinates (vt) and is not planar",
                            "cannot infer material coordinates");
  }
  if (check) validate(mesh, source);
  return mesh;
}

void write_obj(const std::filesystem::path& path, const TriMesh& mesh, const Mat3X& x, double material_scale) {
  const Index n = mesh.num_vertices();
  if (x.cols() != n || mesh.u.cols() != n)
    throw_error("{}: cannot write {} positions and {} material coordinates for a mesh of {} vertices", path.string(),
                x.cols(), mesh.u.cols(), n);
  if (!(material_scale > 0.0) || !std::isfinite(material_scale))
    throw_error("{}: material_scale must be positive and finite (got {})", path.string(), material_scale);

  fmt::memory_buffer buf;
  auto out = std::back_inserter(buf);
  fmt::format_to(out, "# mgcloth: {} vertices, {} triangles; vt = material coordinates / {} m\n", n,
                 mesh.num_triangles(), material_scale);
  // "{}" prints the shortest representation that parses back to the same double.
  for (Index i = 0; i < n; ++i) fmt::format_to(out, "v {} {} {}\n", x(0, i), x(1, i), x(2, i));
  for (Index i = 0; i < n; ++i)
    fmt::format_to(out, "vt {} {}\n", mesh.u(0, i) / material_scale, mesh.u(1, i) / material_scale);
  for (const Tri& f : mesh.tris)
    fmt::format_to(out, "f {0}/{0} {1}/{1} {2}/{2}\n", f[0] + 1, f[1] + 1, f[2] + 1);
  write_file_atomic(path, [&](std::ostream& o) { o.write(buf.data(), static_cast<std::streamsize>(buf.size())); });
}

}  // namespace mgcloth::mesh
