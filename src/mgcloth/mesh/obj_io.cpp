#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/mesh/obj_io.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include <algorithm>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <initializer_list>
#include <iterator>
#include <optional>
#include <regex>
#include <sstream>
#include <string_view>

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

void check_warnings(const std::string& warn, const std::string& source) {
  std::istringstream in(warn);
  std::string line;
  while (std::getline(in, line)) {
    if (is_benign_warning(line)) continue;
    if (line.rfind("Vertex normal indices out of bounds", 0) == 0)  // tinyobjloader's line number is the last one
      throw_input_error("{}: a face refers to a vertex normal (vn) that the file does not define", source);
    throw_input_error("{}: {}", source, line);
  }
  if (!warn.empty()) logger().debug("{}: tinyobjloader: {}", source, warn);
}

/// A token as it can be quoted in a message: control bytes (a NUL, a stray CR) shown as '?', long ones cut.
std::string quoted(std::string_view token) {
  std::string s;
  for (char c : token.substr(0, 32)) s += static_cast<unsigned char>(c) < 0x20 || c == 0x7f ? '?' : c;
  return fmt::format("\"{}{}\"", s, token.size() > 32 ? "..." : "");
}

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t p = 0;
  while (p < line.size()) {
    while (p < line.size() && is_blank(line[p])) ++p;
    std::size_t e = p;
    while (e < line.size() && !is_blank(line[e])) ++e;
    if (e > p) words.push_back(line.substr(p, e - p));
    p = e;
  }
  return words;
}

/// The whole token must be a decimal number; from_chars takes no '+', so one is skipped. Underflow (1e-400) reads
/// as the nearest double, as strtod gives it; overflow is infinite, so it fails the finiteness check.
std::optional<double> parse_number(std::string_view token) {
  std::string_view t = token;
  if (t.size() > 1 && t[0] == '+' && t[1] != '-') t.remove_prefix(1);
  double d = 0.0;
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), d);
  if (end != t.data() + t.size()) return std::nullopt;
  if (ec == std::errc::result_out_of_range) return std::strtod(std::string(t).c_str(), nullptr);
  if (ec != std::errc()) return std::nullopt;
  return d;
}

void check_numbers(const std::vector<std::string_view>& words, std::initializer_list<std::size_t> counts,
                   std::string_view what, const std::string& where) {
  const std::string_view key = words[0];
  const std::size_t n = words.size() - 1;
  if (std::find(counts.begin(), counts.end(), n) == counts.end())
    throw_input_error("{}: `{}` needs {}, got {} number{}", where, key, what, n, n == 1 ? "" : "s");
  for (std::size_t i = 1; i <= n; ++i) {
    const auto d = parse_number(words[i]);
    if (!d) throw_input_error("{}: `{}` coordinate {} is not a number: {}", where, key, i, quoted(words[i]));
    if (!std::isfinite(*d)) throw_input_error("{}: `{}` coordinate {} is not finite: {}", where, key, i, quoted(words[i]));
  }
}

/// One index of a face corner: a non-zero integer (negative: relative to the last element) that fits an Index.
void check_index(std::string_view token, std::string_view which, std::size_t corner, const std::string& where) {
  long long i = 0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), i);
  const auto fail = [&](std::string_view why) {
    throw_input_error("{}: cannot parse the `f` statement: corner {} ({}): {} index {}", where, corner,
                      quoted(token), which, why);
  };
  if (token.empty()) fail("is missing");
  if (ec == std::errc::result_out_of_range || (ec == std::errc() && end == token.data() + token.size() &&
                                               (i > INT_MAX || i < -static_cast<long long>(INT_MAX))))
    fail(fmt::format("is out of range (at most {})", INT_MAX));
  if (ec != std::errc() || end != token.data() + token.size()) fail("is not an integer");
  if (i == 0) fail("is 0 (OBJ indices start at 1; negative ones count back from the last element)");
}

void check_face(const std::vector<std::string_view>& words, const std::string& where) {
  if (words.size() < 4) throw_input_error("{}: face with fewer than three vertices", where);
  for (std::size_t c = 1; c < words.size(); ++c) {
    const std::string_view corner = words[c];
    const std::size_t s1 = corner.find('/');
    const std::size_t s2 = s1 == std::string_view::npos ? s1 : corner.find('/', s1 + 1);
    if (s2 != std::string_view::npos && corner.find('/', s2 + 1) != std::string_view::npos)
      throw_input_error("{}: cannot parse the `f` statement: corner {} ({}) has more than three indices", where, c,
                        quoted(corner));
    check_index(corner.substr(0, s1), "vertex", c, where);
    if (s1 == std::string_view::npos) continue;
    const std::string_view vt = corner.substr(s1 + 1, s2 == std::string_view::npos ? s2 : s2 - s1 - 1);
    // "v//vn" has an empty texture index; "v/" has neither.
    if (!vt.empty() || s2 == std::string_view::npos) check_index(vt, "texture-coordinate", c, where);
    if (s2 != std::string_view::npos) check_index(corner.substr(s2 + 1), "normal", c, where);
  }
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

void check_obj_statements(std::string_view text, const std::string& source) {
  std::size_t pos = 0;
  for (Index line = 1; pos < text.size(); ++line) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view l = text.substr(pos, end - pos);
    pos = end + 1;
    l = l.substr(0, l.find('#'));  // a comment may follow a statement
    const auto words = split_words(l);
    if (words.empty()) continue;
    const std::string_view key = words[0];
    if (key != "v" && key != "vt" && key != "vn" && key != "f") continue;
    const std::string where = fmt::format("{}: line {}", source, line);
    if (key == "v") check_numbers(words, {3, 4, 6}, "3 coordinates (x y z; optionally a weight w, or a colour r g b)", where);
    if (key == "vt") check_numbers(words, {2, 3}, "2 coordinates (u v; optionally w)", where);
    if (key == "vn") check_numbers(words, {3}, "3 coordinates (x y z)", where);
    if (key == "f") check_face(words, where);
  }
}

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


namespace {

/// The file's text, checked, and what tinyobjloader read of it.
struct LoadedObj {
  std::string text;
  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
};

LoadedObj load_obj(const std::filesystem::path& path, const std::string& source) {
  LoadedObj obj;
  obj.text = read_file(path);  // InputError "<path>: cannot open file"
  const std::string& text = obj.text;
  // tinyobjloader reads what it cannot parse as 0, pads short statements and truncates face indices: check first.
  check_obj_statements(text, source);

  tinyobj::attrib_t& attrib = obj.attrib;
  std::vector<tinyobj::shape_t>& shapes = obj.shapes;
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
  check_warnings(warn, source);
  return obj;
}

}  // namespace

TriMesh read_obj(const std::filesystem::path& path, double material_scale, bool check) {
  const std::string source = path.string();
  if (!(material_scale > 0.0) || !std::isfinite(material_scale))
    throw_input_error("{}: material_scale must be positive and finite (got {})", source, material_scale);
  const LoadedObj obj = load_obj(path, source);
  const tinyobj::attrib_t& attrib = obj.attrib;
  const Index num_v = static_cast<Index>(attrib.vertices.size() / 3);
  const Faces faces = collect_faces(attrib, obj.shapes, obj.text, source);

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

Surface read_obj_surface(const std::filesystem::path& path) {
  const std::string source = path.string();
  const LoadedObj obj = load_obj(path, source);
  const tinyobj::attrib_t& attrib = obj.attrib;
  const Index num_v = static_cast<Index>(attrib.vertices.size() / 3);
  Faces faces = collect_faces(attrib, obj.shapes, obj.text, source);
  // A surface is numbered by position alone: texture coordinates would split it at its UV seams.
  std::vector<Index> vertex(static_cast<size_t>(num_v), -1);
  std::vector<Index> used;
  for (Corner& c : faces.corners) {
    Index& v = vertex[static_cast<size_t>(c.v)];
    if (v < 0) {
      v = static_cast<Index>(used.size());
      used.push_back(c.v);
    }
    c = {v, -1};
  }
  Surface out;
  out.x.resize(3, static_cast<Index>(used.size()));
  for (size_t i = 0; i < used.size(); ++i)
    for (int c = 0; c < 3; ++c) out.x(c, static_cast<Index>(i)) = attrib.vertices[3 * static_cast<size_t>(used[i]) + c];
  // Near-collinear corners, relative to the longest edge: a triangle that covers nothing has no place in the contact
  // pairs, whose nearest-feature classification assumes a proper triangle.
  constexpr double kCollinear = 1e-10;
  Index dropped = 0, first_dropped = -1;
  for (Index f = 0; f < faces.size(); ++f)
    for (Index c = faces.offsets[f] + 1; c + 1 < faces.offsets[f + 1]; ++c) {
      const Tri t{faces.corners[faces.offsets[f]].v, faces.corners[c].v, faces.corners[c + 1].v};
      const Vec3 a = out.x.col(t[0]), b = out.x.col(t[1]), d = out.x.col(t[2]);
      const double longest = std::max({(b - a).squaredNorm(), (d - b).squaredNorm(), (a - d).squaredNorm()});
      if (!((b - a).cross(d - a).norm() > kCollinear * longest)) {
        if (dropped++ == 0) first_dropped = f;
        continue;
      }
      out.tris.push_back(t);
    }
  if (out.tris.empty()) throw_input_error("{}: every face has zero area", source);
  if (dropped > 0)
    logger().warn("{}: {} face{} of zero area (or repeating a vertex) dropped, the first at {}", source, dropped,
                  dropped == 1 ? "" : "s", face_location(obj.text, first_dropped));
  return out;
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
