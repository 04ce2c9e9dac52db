#pragma once
#include <mgcloth/core/types.hpp>
#include <mgcloth/physics/shell_material.hpp>

#include <optional>
#include <string>
#include <vector>

namespace mgcloth::bodies {

/// Where a shell's coarsest control mesh comes from: a generator or an all-quad OBJ file.
struct ShellMeshSpec {
  std::string generator = "rectangle";  ///< rectangle | notched_square (ignored with a file)
  std::string file;                     ///< resolved path of an OBJ control mesh (empty: generated)
  double material_scale = 1.0;
  bool ghost_layer = true;
  double width = 1.0, height = 1.0;     ///< rectangle (m); notched_square uses width as its side
  int cells_u = 4, cells_v = 4;         ///< quads of the coarsest level along u and v
  double notch = 0.3;                   ///< notched_square: side of the removed top-right square (m)
};

/// A selection of boundary or surface sampling sites: named sides of the real region's material bounding box
/// ("left", "right", "bottom", "top", "all"), boundary segments whose midpoint lies in a material-space box,
/// material points, and (boundary conditions only) control points of the finest level by index.
struct ShellSelection {
  std::vector<std::string> sides;
  std::optional<std::pair<Vec2, Vec2>> region;
  std::vector<Vec2> points;
  std::vector<Index> control_points;
};

/// A penalty boundary condition (Kopaničáková 2019, eq. 3.6): "fixed" holds positions, "clamped" also the
/// tangent plane (the cross-boundary derivative). The target is the rest position plus `displacement`, reached
/// linearly over `ramp_time` seconds (0: at once) in dynamic runs, and scaled by the load factor in static runs.
struct ShellBoundarySpec {
  std::string type = "fixed";
  ShellSelection where;
  Vec3 displacement = Vec3::Zero();
  double ramp_time = 0.0;
};

/// An external load: "point" (a force at material points), "edge" (force per length on boundary segments),
/// "pressure" (Pa along the reference normal, a dead load). Ramped like displacements.
struct ShellLoadSpec {
  std::string type = "point";
  ShellSelection where;
  Vec3 force = Vec3::Zero();  ///< N (point) or N/m (edge)
  double pressure = 0.0;
  double ramp_time = 0.0;
};

struct ShellSpec {
  std::string name = "shell";
  ShellMeshSpec mesh;
  int level = 3;                 ///< the paper's level: the coarsest mesh subdivided level - 1 times
  std::string preset = "denim";  ///< denim (Table 1) | stvk (isotropic, the material block's values)
  physics::ShellMaterial material;
  int quadrature = 3;            ///< Gauss points per face side
  double sigma = 5.0;            ///< β = h^-σ (§7.1)
  double beta = 0.0;             ///< explicit β (0: h^-σ)
  std::string analysis = "dynamic";  ///< dynamic (implicit Euler) | static (load stepping)
  Vec3 translation = Vec3::Zero(), rotation_deg = Vec3::Zero();
  std::vector<ShellBoundarySpec> boundary;
  std::vector<ShellLoadSpec> loads;
  std::vector<Vec2> probes;      ///< material points written to probes.csv
  int display_samples = 3;       ///< limit-surface samples per face side in the frame files
};

}  // namespace mgcloth::bodies
