#pragma once
#include <mgcloth/mesh/tri_mesh.hpp>

#include <filesystem>

namespace mgcloth::mesh {

/// Reads a triangle (or polygon, fan-triangulated) OBJ. With `vt`, material coordinates are the vt values times
/// `material_scale` (metres per UV unit), and vertices are split where a position has several vt (UV seams).
/// Without vt, a planar mesh is flattened onto its best-fit plane (u in metres); a non-planar one is an error.
/// The result is validated (see validate()). Errors name the file and line or element.
/// With `check` false the mesh is returned as read (for `mgcloth info`, which reports problems instead).
TriMesh read_obj(const std::filesystem::path& path, double material_scale = 1.0, bool check = true);

/// Writes positions `x` (3 x N, may differ from mesh.x) with the mesh's material coordinates as `vt` (divided by
/// `material_scale`), atomically (temp file + rename).
void write_obj(const std::filesystem::path& path, const TriMesh& mesh, const Mat3X& x, double material_scale = 1.0);

}  // namespace mgcloth::mesh
