#pragma once
#include <mgcloth/geometry/rigid_motion.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/physics/material.hpp>

#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

namespace mgcloth::bodies {

/// Where a cloth's mesh comes from: an OBJ file or a generator.
struct MeshSource {
  std::string file;             ///< resolved path when the mesh is read from OBJ (empty: generated)
  double material_scale = 1.0;  ///< metres per UV unit
  std::string pattern;            ///< resolved path of a sewing pattern (mesh/pattern.hpp); empty: none
  double pattern_resolution = 0.02;  ///< m, the pattern's triangles' edge length
  std::string generator = "rectangle";  ///< rectangle | tube
  mesh::RectangleSpec rectangle;
  mesh::TubeSpec tube;
};

/// Rigid placement of a cloth's initial state: x = R p + t (R from XYZ Euler angles in degrees).
struct Transform {
  Vec3 translation = Vec3::Zero();
  Vec3 rotation_deg = Vec3::Zero();
  Eigen::Quaterniond rotation() const { return geometry::euler_xyz_deg(rotation_deg); }
};

/// A set of pinned vertices pulled to targets by stiff springs; the targets start at the vertices' initial
/// positions and follow an offset over time (none, constant velocity, or keyframes).
struct PinSpec {
  std::vector<Index> vertices;  ///< by index
  std::vector<Vec2> points;     ///< by material coordinate: the nearest vertex
  std::optional<std::pair<Vec2, Vec2>> region;  ///< every vertex in a material-space box
  double stiffness = 1.0e4;     ///< N/m
  std::string motion = "none";  ///< none | constant_velocity | keyframes | rotation
  Vec3 velocity = Vec3::Zero();  ///< constant_velocity; rotation: the centre's velocity
  /// rotation: the targets turn about the line through `center` (world, at t = 0) along `axis` at
  /// `angular_velocity` (rad/s, right-handed about the axis) for `duration` seconds, then hold.
  Vec3 axis = Vec3::UnitX();
  Vec3 center = Vec3::Zero();
  double angular_velocity = 0.0;
  double duration = kInf;
  std::vector<double> key_times;
  std::vector<Vec3> key_offsets;
};

struct ClothSpec {
  std::string name = "cloth";
  MeshSource mesh;
  Transform transform;
  std::string preset = "cotton";
  physics::Material material;
  std::vector<PinSpec> pins;
  Vec3 initial_velocity = Vec3::Zero();
  /// N/m, the springs closing stitched seams; 0 in a spec means "100 × in-plane stiffness E·t" (resolved at parse).
  double seam_stiffness = 0.0;
  /// m, this cloth's thickness for cloth contact (two cloths touch at the mean of theirs); 0: the scene's.
  double contact_thickness = 0.0;
};

}  // namespace mgcloth::bodies
