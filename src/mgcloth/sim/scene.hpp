#pragma once
#include <mgcloth/bodies/cloth_body.hpp>
#include <mgcloth/core/json.hpp>
#include <mgcloth/geometry/mannequin.hpp>
#include <mgcloth/geometry/obstacle.hpp>
#include <mgcloth/hierarchy/triangle_hierarchy.hpp>
#include <mgcloth/mesh/generators.hpp>
#include <mgcloth/physics/cloth_friction.hpp>
#include <mgcloth/physics/contact.hpp>
#include <mgcloth/physics/energy_form.hpp>
#include <mgcloth/physics/material.hpp>
#include <mgcloth/sim/shell_scene.hpp>
#include <mgcloth/solvers/factory.hpp>

#include <filesystem>
#include <optional>

namespace mgcloth::sim {

using bodies::ClothSpec;
using bodies::MeshSource;
using bodies::PinSpec;
using bodies::Transform;

struct ObstacleSpec {
  std::string name;
  std::string shape = "sphere";  ///< plane | sphere | box | capsule | mesh | body
  /// mesh: the OBJ file (absolute), a sequence's pattern (one %d or %0Nd), or a glTF file (.glb, .gltf)
  std::string mesh;
  std::string gltf_mesh;       ///< glTF: the mesh's name (empty: the first skinned one)
  std::string gltf_animation;  ///< glTF: the animation's name (empty: the first)
  bool gltf_y_up = true;       ///< glTF: its y axis is up (the glTF convention), turned into mgcloth's z
  geometry::MannequinParams body;  ///< body: the generated mannequin
  geometry::WalkParams walk;       ///< body: its walk
  double mesh_rate = 0.0;        ///< a sequence's frames per second
  int mesh_first = 0;            ///< a sequence's first frame number
  bool mesh_loop = false;        ///< a sequence (or a glTF animation) repeats
  double contact_thickness = 0.0;  ///< mesh: its side of the contact layer (0: "cloth_contact"'s thickness)
  std::shared_ptr<const geometry::TriangleSurface> surface;  ///< mesh, body: made once, when the scene is parsed
  double radius = 0.25;          ///< sphere, capsule
  Vec3 half_extents{0.5, 0.5, 0.5};  ///< box
  double half_length = 0.25;     ///< capsule
  Vec3 position = Vec3::Zero();
  Vec3 rotation_deg = Vec3::Zero();
  std::string motion = "static";  ///< static | constant_velocity | keyframes
  Vec3 linear_velocity = Vec3::Zero();
  Vec3 angular_velocity = Vec3::Zero();  ///< rad/s, world frame, about the obstacle's origin
  std::vector<double> key_times;
  std::vector<Vec3> key_positions;
  std::vector<Vec3> key_rotations_deg;
  double friction = 0.0;

  geometry::Obstacle build() const;
};

/// Contact between cloths and within each cloth (self-contact): on when the scene has "cloth_contact".
struct ClothContactSpec {
  bool enabled = false;
  double thickness = 1e-3;  ///< m, every cloth's unless it sets "contact_thickness"
  physics::ClothContactParams params;
  /// Lagged Coulomb friction between cloths ("friction", "friction_pairs", "static_friction_velocity").
  physics::ClothFrictionParams friction;
  /// Count intersections with the exact checker (collision::find_intersections) after every step (stats.csv's
  /// "intersections"); the guarantee is the solvers', this is the independent check of it.
  bool check_intersections = true;
};

struct OutputSpec {
  std::string dir = "out";
  int every = 1;  ///< write every n-th frame
  std::vector<std::string> formats{"obj"};
};

/// A parsed, validated scene. Construction of the simulation from it is separate (Simulator).
struct Scene {
  std::string file;  ///< where it was read from (for messages)
  Vec3 gravity{0.0, 0.0, -9.81};
  double frame_time = 1.0 / 30.0;  ///< seconds per frame
  int substeps = 1;                ///< implicit-Euler steps per frame: h = frame_time / substeps
  int frames = 60;
  int threads = 0;                 ///< 0: all cores
  /// The form of the cloths' energy that every step minimizes; the solver must be able to minimize it.
  physics::EnergyForm energy_form = physics::EnergyForm::Elastic;
  /// Whether a step minimizes one objective over every body ("jointly", the default: what terms that couple bodies
  /// need) or each body's on its own ("separately", one solver per body).
  bool solve_jointly = true;
  std::vector<ClothSpec> cloths;
  /// Subdivision Kirchhoff-Love shells (Kopaničáková 2019): stepped with the same solver; no obstacle contact.
  std::vector<ShellSpec> shells;
  std::vector<ObstacleSpec> obstacles;
  physics::ContactParams contact;
  ClothContactSpec cloth_contact;
  solvers::SolverConfig solver;
  hierarchy::HierarchyParams hierarchy;  ///< mesh hierarchy for the multilevel solvers (pins are always kept)
  OutputSpec output;

  double step_size() const { return frame_time / substeps; }
  /// Steps of the whole run (frames × substeps): static shells reach the full load at the last one.
  long total_steps() const { return static_cast<long>(frames) * substeps; }
};

/// Parses a scene file: unknown keys, wrong types and out-of-range values are InputError naming file and path.
/// Relative mesh paths are resolved against the scene file's folder.
Scene load_scene(const std::filesystem::path& path);
Scene parse_scene(const Json& json, const std::string& file, const std::filesystem::path& base_dir);
/// Every field with its value, defaults included (written next to the outputs as the resolved scene).
Json to_json(const Scene& scene);
/// What the scene gives every cloth body (bodies::ClothEnvironment): its obstacles (built from their specs),
/// contact, gravity, energy form and hierarchy settings.
bodies::ClothEnvironment cloth_environment(const Scene& scene);
/// Material presets by name ("cotton", "silk", "denim", "leather").
physics::Material material_preset(const std::string& name);
std::vector<std::string> material_presets();

}  // namespace mgcloth::sim
