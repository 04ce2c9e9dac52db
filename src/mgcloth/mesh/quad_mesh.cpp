#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/quad_mesh.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

namespace mgcloth::mesh {

Index QuadMesh::num_real_vertices() const {
  Index n = 0;
  for (Index v = 0; v < num_vertices(); ++v) n += is_ghost_vertex(v) ? 0 : 1;
  return n;
}

namespace {

/// Control coordinates c_{-1..n+1} (index i + 1) whose uniform cubic B-spline passes through lines[i] at knot i,
/// with the ghost coordinates extrapolated linearly (then the limit at the ends is c_0 and c_n themselves):
/// (c_{i-1} + 4 c_i + c_{i+1}) / 6 = lines[i] for 0 < i < n, c_0 = lines[0], c_n = lines[n].
std::vector<double> control_coordinates(const std::vector<double>& lines, int n, double h) {
  std::vector<double> c(static_cast<size_t>(n) + 3);
  if (lines.empty()) {
    for (int i = -1; i <= n + 1; ++i) c[i + 1] = i * h;
    return c;
  }
  // Tridiagonal (Thomas) solve for c_1..c_{n-1}.
  std::vector<double> L = lines, diag(n + 1, 4.0 / 6.0), rhs(n + 1);
  for (int i = 1; i < n; ++i) rhs[i] = L[i];
  rhs[1] -= L[0] / 6.0;
  rhs[n - 1] -= L[n] / 6.0;
  for (int i = 2; i < n; ++i) {
    const double m = (1.0 / 6.0) / diag[i - 1];
    diag[i] -= m / 6.0;
    rhs[i] -= m * rhs[i - 1];
  }
  std::vector<double> x(n + 1);
  x[0] = L[0];
  x[n] = L[n];
  for (int i = n - 1; i >= 1; --i) x[i] = (rhs[i] - (i + 1 < n ? x[i + 1] / 6.0 : 0.0)) / diag[i];
  for (int i = 0; i <= n; ++i) c[i + 1] = x[i];
  c[0] = 2.0 * x[0] - x[1];
  c[n + 2] = 2.0 * x[n] - x[n - 1];
  return c;
}

void check_lines(const std::vector<double>& lines, int n, double extent, const char* name) {
  if (lines.empty()) return;
  if (static_cast<int>(lines.size()) != n + 1) throw_input_error("quad grid: {} needs {} values (got {})", name, n + 1, lines.size());
  if (std::abs(lines.front()) > 1e-12 * extent || std::abs(lines.back() - extent) > 1e-12 * extent)
    throw_input_error("quad grid: {} must run from 0 to {}", name, extent);
  for (int i = 1; i <= n; ++i)
    if (!(lines[i] > lines[i - 1])) throw_input_error("quad grid: {} must increase ({}: {} after {})", name, i, lines[i], lines[i - 1]);
}

}  // namespace

QuadMesh make_quad_grid(const QuadGridSpec& s) {
  if (!(s.width > 0.0) || !(s.height > 0.0) || !std::isfinite(s.width) || !std::isfinite(s.height))
    throw_input_error("quad grid: width and height must be positive and finite (got {} x {})", s.width, s.height);
  if (s.nx < 1 || s.ny < 1) throw_input_error("quad grid: needs at least 1 x 1 cells (got {} x {})", s.nx, s.ny);
  const bool notched = s.notch_i0 < s.notch_i1 && s.notch_j0 < s.notch_j1;
  if (notched && (s.notch_i0 < 0 || s.notch_j0 < 0 || s.notch_i1 > s.nx || s.notch_j1 > s.ny))
    throw_input_error("quad grid: notch [{}, {}) x [{}, {}) is outside the {} x {} cells", s.notch_i0, s.notch_i1,
                      s.notch_j0, s.notch_j1, s.nx, s.ny);
  const auto real = [&](int i, int j) {
    if (i < 0 || j < 0 || i >= s.nx || j >= s.ny) return false;
    return !(notched && i >= s.notch_i0 && i < s.notch_i1 && j >= s.notch_j0 && j < s.notch_j1);
  };
  // Cells on an extended grid [-g, n + g) with g = 1 for the ghost layer.
  const int g = s.ghost_layer ? 1 : 0;
  const int cx = s.nx + 2 * g, cy = s.ny + 2 * g;
  std::vector<char> cell(static_cast<size_t>(cx) * cy, 0);  // 0 out, 1 real, 2 ghost
  Index real_cells = 0;
  for (int j = -g; j < s.ny + g; ++j)
    for (int i = -g; i < s.nx + g; ++i) {
      char& c = cell[static_cast<size_t>(j + g) * cx + (i + g)];
      if (real(i, j)) {
        c = 1;
        ++real_cells;
        continue;
      }
      if (!g) continue;
      for (int dj = -1; dj <= 1 && !c; ++dj)
        for (int di = -1; di <= 1 && !c; ++di)
          if (real(i + di, j + dj)) c = 2;
    }
  if (real_cells == 0) throw_input_error("quad grid: the notch removes every cell");

  // Vertices: corners of kept cells, numbered row by row on the extended grid of (cx + 1) × (cy + 1) points.
  const int px = cx + 1, py = cy + 1;
  std::vector<Index> id(static_cast<size_t>(px) * py, -1);
  check_lines(s.lines_u, s.nx, s.width, "lines_u");
  check_lines(s.lines_v, s.ny, s.height, "lines_v");
  if ((!s.lines_u.empty() || !s.lines_v.empty()) && !g)
    throw_input_error("quad grid: non-uniform grid lines need the ghost layer");
  const std::vector<double> cu = control_coordinates(s.lines_u, s.nx, s.width / s.nx);
  const std::vector<double> cv = control_coordinates(s.lines_v, s.ny, s.height / s.ny);
  QuadMesh m;
  std::vector<Vec2> u;
  for (int q = 0; q < py; ++q)
    for (int p = 0; p < px; ++p) {
      bool used = false, on_real = false;
      for (int dj = -1; dj <= 0; ++dj)
        for (int di = -1; di <= 0; ++di) {
          const int ci = p + di, cj = q + dj;
          if (ci < 0 || cj < 0 || ci >= cx || cj >= cy) continue;
          const char c = cell[static_cast<size_t>(cj) * cx + ci];
          used = used || c != 0;
          on_real = on_real || c == 1;
        }
      if (!used) continue;
      id[static_cast<size_t>(q) * px + p] = static_cast<Index>(u.size());
      u.emplace_back(cu[p - g + 1], cv[q - g + 1]);
      m.ghost_vertex.push_back(on_real ? 0 : 1);
    }
  m.u.resize(2, static_cast<Index>(u.size()));
  m.x.setZero(3, static_cast<Index>(u.size()));
  for (size_t v = 0; v < u.size(); ++v) {
    m.u.col(static_cast<Index>(v)) = u[v];
    m.x.col(static_cast<Index>(v)).head<2>() = u[v];
  }
  for (int j = 0; j < cy; ++j)
    for (int i = 0; i < cx; ++i) {
      const char c = cell[static_cast<size_t>(j) * cx + i];
      if (!c) continue;
      const auto at = [&](int p, int q) { return id[static_cast<size_t>(q) * px + p]; };
      m.quads.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});  // counter-clockwise in (u, v)
      m.ghost_face.push_back(c == 2 ? 1 : 0);
    }
  if (!g) {
    m.ghost_vertex.clear();
    m.ghost_face.clear();
  }
  return m;
}

QuadMesh make_quad_rectangle(double width, double height, int nx, int ny, bool ghost_layer) {
  QuadGridSpec s;
  s.width = width;
  s.height = height;
  s.nx = nx;
  s.ny = ny;
  s.ghost_layer = ghost_layer;
  return make_quad_grid(s);
}

QuadMesh make_notched_square(double size, double notch, int n, bool ghost_layer) {
  if (!(notch > 0.0) || !(notch < size))
    throw_input_error("notched square: the notch ({} m) must be positive and smaller than the square ({} m)", notch, size);
  const double cells = notch / size * n;
  const int k = std::max(1, static_cast<int>(std::lround(cells)));
  if (k >= n)
    throw_input_error("notched square: a {} m notch takes {} of the {} cells across a {} m square; it must leave at "
                      "least one cell", notch, k, n, size);
  QuadGridSpec s;
  if (std::abs(cells - k) > 1e-9) {
    if (!ghost_layer) throw_input_error("notched square: a notch of {} cells needs the ghost layer", cells);
    for (int i = 0; i <= n; ++i)
      s.lines_u.push_back(i <= n - k ? (size - notch) * i / (n - k) : size - notch + notch * (i - (n - k)) / k);
    s.lines_v = s.lines_u;
  }
  s.width = s.height = size;
  s.nx = s.ny = n;
  s.notch_i0 = s.notch_j0 = n - k;
  s.notch_i1 = s.notch_j1 = n;
  s.ghost_layer = ghost_layer;
  return make_quad_grid(s);
}

}  // namespace mgcloth::mesh

namespace mgcloth::mesh {

namespace {
using EdgeKey = std::pair<Index, Index>;
EdgeKey undirected(Index a, Index b) { return {std::min(a, b), std::max(a, b)}; }
}  // namespace

std::vector<std::pair<Index, int>> real_boundary_edges(const QuadMesh& m) {
  std::map<EdgeKey, int> real_count;
  for (Index f = 0; f < m.num_faces(); ++f)
    if (!m.is_ghost_face(f))
      for (int k = 0; k < 4; ++k) ++real_count[undirected(m.quads[f][k], m.quads[f][(k + 1) % 4])];
  std::vector<std::pair<Index, int>> out;
  for (Index f = 0; f < m.num_faces(); ++f)
    if (!m.is_ghost_face(f))
      for (int k = 0; k < 4; ++k)
        if (real_count[undirected(m.quads[f][k], m.quads[f][(k + 1) % 4])] == 1) out.emplace_back(f, k);
  return out;
}

void validate(const QuadMesh& m, const std::string& source) {
  const Index n = m.num_vertices();
  if (m.num_faces() == 0) throw_input_error("{}: the control mesh is empty: it has no quads (f lines)", source);
  if (m.u.cols() != n) throw_input_error("{}: {} positions but {} material coordinates", source, n, m.u.cols());
  if (!m.ghost_face.empty() && static_cast<Index>(m.ghost_face.size()) != m.num_faces())
    throw_input_error("{}: ghost flags for {} of {} quads", source, m.ghost_face.size(), m.num_faces());
  for (Index v = 0; v < n; ++v)
    if (!m.x.col(v).allFinite() || !m.u.col(v).allFinite()) throw_input_error("{}: point {} is not finite", source, v + 1);
  std::set<EdgeKey> directed;
  std::map<EdgeKey, int> count;
  std::vector<char> used(static_cast<size_t>(n), 0);
  Index real = 0;
  for (Index f = 0; f < m.num_faces(); ++f) {
    const Quad& q = m.quads[f];
    real += m.is_ghost_face(f) ? 0 : 1;
    for (int k = 0; k < 4; ++k) {
      if (q[k] < 0 || q[k] >= n) throw_input_error("{}: quad {} refers to point {}, but there are {} points", source, f + 1, q[k] + 1, n);
      used[q[k]] = 1;
      for (int j = 0; j < k; ++j)
        if (q[j] == q[k]) throw_input_error("{}: quad {} is degenerate (point {} appears twice)", source, f + 1, q[k] + 1);
    }
    for (int k = 0; k < 4; ++k) {
      const Index a = q[k], b = q[(k + 1) % 4];
      if (!directed.insert({a, b}).second)
        throw_input_error("{}: edge ({}, {}) is traversed twice in the same direction (quad {}): a duplicate quad or "
                          "inconsistent orientation", source, a + 1, b + 1, f + 1);
      if (++count[undirected(a, b)] > 2)
        throw_input_error("{}: edge ({}, {}) is shared by more than two quads (non-manifold, quad {})", source, a + 1, b + 1, f + 1);
    }
  }
  for (Index v = 0; v < n; ++v)
    if (!used[v]) throw_input_error("{}: point {} belongs to no quad", source, v + 1);
  if (real == 0) throw_input_error("{}: every quad is a ghost quad", source);
}

void add_ghost_layer(QuadMesh& m) {
  if (!m.ghost_face.empty())
    for (char g : m.ghost_face)
      if (g) throw_input_error("add_ghost_layer: the mesh has ghost faces already");
  std::map<EdgeKey, std::vector<std::pair<Index, int>>> edge_faces;
  std::vector<std::vector<Index>> vertex_faces(static_cast<size_t>(m.num_vertices()));
  for (Index f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 4; ++k) {
      edge_faces[undirected(m.quads[f][k], m.quads[f][(k + 1) % 4])].emplace_back(f, k);
      vertex_faces[m.quads[f][k]].push_back(f);
    }
  std::vector<Vec3> gx;
  std::vector<Vec2> gu;
  std::map<EdgeKey, Index> ghost_of;  // (point, neighbour inside) -> ghost point
  const Index n0 = m.num_vertices();
  const auto ghost = [&](Index v, Index inside) {
    auto [it, fresh] = ghost_of.try_emplace({v, inside}, n0 + static_cast<Index>(gx.size()));
    if (fresh) {
      gx.push_back(2.0 * m.x.col(v) - m.x.col(inside));
      gu.push_back(2.0 * m.u.col(v) - m.u.col(inside));
    }
    return it->second;
  };
  std::vector<Quad> faces;
  std::set<Index> corners;
  for (const auto& [edge, fs] : edge_faces) {
    if (fs.size() != 1) continue;
    const auto [f, k] = fs[0];
    const Quad& q = m.quads[f];
    const Index a = q[k], b = q[(k + 1) % 4], b_in = q[(k + 2) % 4], a_in = q[(k + 3) % 4];
    for (Index v : {a, b}) {
      const size_t nf = vertex_faces[v].size();
      if (nf > 2)
        throw_input_error("boundary point {} is shared by {} quads (a concave corner or irregular boundary): model "
                          "its ghost quads in the input (group \"ghost\") or switch the ghost layer off", v + 1, nf);
      if (nf == 1) corners.insert(v);
    }
    faces.push_back({b, a, ghost(a, a_in), ghost(b, b_in)});
  }
  for (Index v : corners) {
    // The corner quad (v, a, c, b) gets the ghost quad (v, 2v − a, 2v − c, 2v − b) diagonally across v.
    const Index f = vertex_faces[v][0];
    const Quad& q = m.quads[f];
    int k = 0;
    while (q[k] != v) ++k;
    const Index a = q[(k + 1) % 4], c = q[(k + 2) % 4], b = q[(k + 3) % 4];
    faces.push_back({v, ghost(v, a), ghost(v, c), ghost(v, b)});
  }
  const Index n = n0 + static_cast<Index>(gx.size());
  m.x.conservativeResize(3, n);
  m.u.conservativeResize(2, n);
  for (size_t i = 0; i < gx.size(); ++i) {
    m.x.col(n0 + static_cast<Index>(i)) = gx[i];
    m.u.col(n0 + static_cast<Index>(i)) = gu[i];
  }
  m.ghost_face.assign(m.quads.size(), 0);
  for (const Quad& q : faces) {
    m.quads.push_back(q);
    m.ghost_face.push_back(1);
  }
  m.ghost_vertex.assign(static_cast<size_t>(n), 0);
  for (Index i = n0; i < n; ++i) m.ghost_vertex[i] = 1;
}

}  // namespace mgcloth::mesh

#include <mgcloth/core/file_io.hpp>
#include <mgcloth/mesh/obj_io.hpp>

#include <sstream>
#include <tiny_obj_loader.h>

namespace mgcloth::mesh {

QuadMesh read_quad_obj(const std::filesystem::path& path, double material_scale, bool ghost_layer) {
  const std::string source = path.string();
  if (!(material_scale > 0.0) || !std::isfinite(material_scale))
    throw_input_error("{}: material_scale must be positive and finite (got {})", source, material_scale);
  const std::string text = read_file(path);
  check_obj_statements(text, source);
  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::string warn, err;
  std::istringstream stream(text);
  if (!tinyobj::LoadObj(&attrib, &shapes, &materials, &warn, &err, &stream, nullptr, /*triangulate=*/false) || !err.empty())
    throw_input_error("{}: cannot parse: {}", source, err.substr(0, err.find('\n')));
  QuadMesh m;
  const Index n = static_cast<Index>(attrib.vertices.size() / 3);
  const Index num_vt = static_cast<Index>(attrib.texcoords.size() / 2);
  m.x.resize(3, n);
  for (Index i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) m.x(k, i) = attrib.vertices[3 * i + k];
  std::vector<Index> vt_of(static_cast<size_t>(n), -1);
  bool any_vt = false, any_ghost = false;
  Index face = 0;
  for (const auto& shape : shapes) {
    const bool ghost = shape.name == "ghost";
    size_t corners_total = 0;
    for (const auto c : shape.mesh.num_face_vertices) corners_total += c;
    if (corners_total != shape.mesh.indices.size())  // tinyobjloader counts corners in an unsigned char
      throw_input_error("{}: a face has more than 255 corners; a Catmull-Clark control mesh must be all quads", source);
    size_t offset = 0;
    for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f, ++face) {
      const int corners = shape.mesh.num_face_vertices[f];
      if (corners != 4)
        throw_input_error("{}: face {} has {} corners; a Catmull-Clark control mesh must be all quads", source, face + 1, corners);
      Quad q;
      for (int c = 0; c < 4; ++c) {
        const auto& idx = shape.mesh.indices[offset + c];
        if (idx.vertex_index < 0 || idx.vertex_index >= n)
          throw_input_error("{}: face {} refers to point {}, but there are {} points", source, face + 1, idx.vertex_index + 1, n);
        q[c] = idx.vertex_index;
        // tinyobjloader only warns about a vt index past the last vt line (and resolves a relative one before the
        // first to a negative number); read unchecked, it was a read past the end of the texture coordinates.
        if (idx.texcoord_index >= num_vt || idx.texcoord_index < -1)
          throw_input_error("{}: face {} refers to texture coordinate {}, but there are {} (vt lines)", source,
                            face + 1, idx.texcoord_index + 1, num_vt);
        if (idx.texcoord_index >= 0) {
          any_vt = true;
          Index& vt = vt_of[q[c]];
          if (vt >= 0 && vt != idx.texcoord_index)
            throw_input_error("{}: point {} has two texture coordinates (a UV seam); a shell's control mesh needs one "
                              "material coordinate per point", source, q[c] + 1);
          vt = idx.texcoord_index;
        }
      }
      offset += 4;
      m.quads.push_back(q);
      m.ghost_face.push_back(ghost ? 1 : 0);
      any_ghost = any_ghost || ghost;
    }
  }
  m.u.resize(2, n);
  for (Index i = 0; i < n; ++i) {
    if (any_vt && vt_of[i] < 0 && std::count(vt_of.begin(), vt_of.end(), -1) < n)
      throw_input_error("{}: point {} has no texture coordinate while others do", source, i + 1);
    m.u.col(i) = any_vt && vt_of[i] >= 0
                     ? Vec2(attrib.texcoords[2 * vt_of[i]], attrib.texcoords[2 * vt_of[i] + 1]) * material_scale
                     : Vec2(m.x(0, i), m.x(1, i)) * material_scale;
  }
  if (!any_ghost) m.ghost_face.clear();
  validate(m, source);
  if (any_ghost) {
    m.ghost_vertex.assign(static_cast<size_t>(n), 1);
    for (Index f = 0; f < m.num_faces(); ++f)
      if (!m.is_ghost_face(f))
        for (Index v : m.quads[f]) m.ghost_vertex[v] = 0;
  } else if (ghost_layer) {
    try {
      add_ghost_layer(m);
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}", source, e.what()));
    }
  }
  return m;
}

}  // namespace mgcloth::mesh
