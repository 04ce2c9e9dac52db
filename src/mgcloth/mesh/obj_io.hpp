#pragma once
#include <mgcloth/mesh/tri_mesh.hpp>

#include <filesystem>
#include <string_view>

namespace mgcloth::mesh {

/// Material coordinates for a mesh given without them (an OBJ without vt, arrays without uv): the positions in an
/// orthonormal frame of the best-fit plane. The frame's first axis is the world axis closest to the plane (so a
/// mesh in z = 0 gets u = (x, y) exactly) and its normal points to the side the faces wind around, so the faces
/// come out counter-clockwise. A mesh off its plane by more than 1e-6 of its bounding-box diagonal is an
/// InputError "<source>: <what> (a vertex lies …); <remedy>".
Mat2X flatten_planar(const Mat3X& x, const std::vector<Tri>& tris, const std::string& source, std::string_view what,
                     std::string_view remedy);

/// The strict syntax check that every OBJ reader here runs before tinyobjloader, which reads a number it cannot
/// parse as 0, pads short statements with zeros, truncates "3.5" or "3x" to 3 and wraps indices past 2^32. It
/// requires: `v` with 3 numbers (4 or 6 with a weight or a colour), `vt` with 2 or 3, `vn` with 3, each a finite
/// decimal number parsed whole; `f` with at least three corners `v`, `v/vt`, `v//vn` or `v/vt/vn`, each index a
/// non-zero integer of at most 2^31 - 1 in magnitude. Other statements (groups, materials, lines) pass; `#` starts
/// a comment anywhere. InputError "<source>: line N: …" naming the statement, the coordinate or corner and the token.
void check_obj_statements(std::string_view text, const std::string& source);

/// Reads a triangle (or polygon, fan-triangulated) OBJ. With `vt`, material coordinates are the vt values times
/// `material_scale` (metres per UV unit), and vertices are split where a position has several vt (UV seams).
/// Without vt, a planar mesh is flattened onto its best-fit plane (u in metres); a non-planar one is an error.
/// The result is validated (see validate()). Errors name the file and line or element.
/// With `check` false the mesh is returned as read (for `mgcloth info`, which reports problems instead).
///
/// Details: vertices are the distinct (v, vt) pairs in (v, vt) order, so a file from write_obj reads back with
/// the same numbering; `v` lines no face uses are dropped. Polygons are fanned from their first corner. "Planar"
/// means every vertex within 1e-6 x the bounding-box diagonal of the best-fit (PCA) plane; the flattened u then
/// has the world axis closest to the plane as its first axis (a sheet in z = 0 gets u = (x, y) exactly), is in
/// metres whatever `material_scale`, and the faces' winding decides which side is up. Normals, materials and
/// groups are ignored. Parse errors name the line; a missing file is "<path>: cannot open file". Even with `check`
/// false, a non-planar mesh without vt is an error, as it has no material coordinates at all.
TriMesh read_obj(const std::filesystem::path& path, double material_scale = 1.0, bool check = true);

/// A triangle surface in world space without material coordinates: an obstacle's mesh.
struct Surface {
  Mat3X x;
  std::vector<Tri> tris;
};

/// Reads an OBJ as a world-space surface (an obstacle). Vertices are the `v` statements in the order faces first use
/// them (`v` lines no face uses are dropped); texture coordinates and normals are ignored, so a closed mesh with UV
/// seams stays closed; polygons are fanned from their first corner. Syntax and indices are checked as read_obj
/// checks them (errors name the file and line). Faces of zero area (corners collinear to 1e-10 of the longest edge,
/// or a repeated vertex) cover nothing and are dropped with a warning naming the first one's line. Open boundaries,
/// non-manifold edges, inconsistent orientation and self-intersections are accepted: contact with an obstacle
/// uses unsigned distances to its triangles and edges, which none of them disturbs.
Surface read_obj_surface(const std::filesystem::path& path);

/// Writes positions `x` (3 x N, may differ from mesh.x) with the mesh's material coordinates as `vt` (divided by
/// `material_scale`), atomically (temp file + rename). Numbers are written in the shortest form that a correctly
/// rounding parser reads back as the same double (tinyobjloader's parser is within a few ulps); faces as
/// `f i/i j/j k/k`.
void write_obj(const std::filesystem::path& path, const TriMesh& mesh, const Mat3X& x, double material_scale = 1.0);

}  // namespace mgcloth::mesh
