#pragma once
#include <mgcloth/geometry/skin.hpp>

#include <array>
#include <filesystem>
#include <optional>
#include <string>

namespace mgcloth::sim {

struct SkinReadOptions {
  /// The glTF mesh to read, by name. Empty: the first mesh that a node instances with a skin, or, when no node has
  /// a skin, the first mesh (read as one rigid joint, placed by its node).
  std::string mesh;
  /// The animation to read, by name. Empty: the first that animates a node of the skeleton (none is fine).
  std::string animation;
  /// glTF is y-up, mgcloth z-up: when set, `placement` maps glTF's (x, y, z) to (x, −z, y).
  bool y_up = true;
  /// Multiplies every position (e.g. 0.01 for a file in centimetres), folded into `placement`.
  double scale = 1.0;
};

/// Reads a skinned, animated triangle mesh from a .glb or .gltf (glTF 2.0 skins and animations):
/// - the mesh's primitives (TRIANGLES only) merged into one vertex list in their accessors' order, leaving out
///   vertices in no triangle, vertices at the same position welded into one (glTF splits vertices at UV and normal
///   seams; the cloth contact needs the closed surface), keeping the first one's weights;
/// - its influences from JOINTS_n / WEIGHTS_n, the four largest kept and renormalized to sum 1;
/// - the skeleton: the skin's joints and every node above them (whose transforms move the joints too), parents
///   first, each with its rest transform from its node, its inverse bind matrix (identity where absent or not a
///   joint), and the translation, rotation and scale channels of the animation that target it (LINEAR, STEP or
///   CUBICSPLINE; morph "weights" channels and channels on other nodes are ignored).
/// A static mesh gives one joint and no animation, with its node's world transform applied to the vertices.
/// Throws InputError naming the file and the glTF element for a file that is missing or not glTF, a mesh or
/// animation not found, a primitive that is not triangles, an accessor out of range or of the wrong type, a vertex
/// without weight, a skeleton node whose matrix has shear; Error when this build has no glTF support.
geometry::SkinnedMesh read_skinned_gltf(const std::filesystem::path& file, const SkinReadOptions& opt = {});

struct SkinWriteOptions {
  std::string name = "skin";            ///< the mesh's and its node's name
  std::string animation = "animation";  ///< the animation's name
  std::string material = "skin";
  std::array<double, 3> colour = {0.6, 0.6, 0.65};  ///< base colour, linear RGB
};

/// Writes `skin` as one binary glTF 2.0 file (atomically): the mesh in its bind pose with JOINTS_0, WEIGHTS_0 and
/// normals, a skin over a node per joint (named by joint_names, posed by rest_local) and one animation holding
/// every track with its interpolation. The joints hang under one root node holding skin.placement and the turn of
/// mgcloth's z-up into glTF's y-up, so that read_skinned_gltf with y_up gives back at(t) to float precision. Throws
/// Error naming the file when the skin does not validate, has more than 65536 joints or key times that float
/// rounding merges, or the build has no glTF support. (Defined in gltf_export.cpp, beside the simulation's glb
/// writer, whose buffer building it shares.)
void write_skinned_glb(const std::filesystem::path& file, const geometry::SkinnedMesh& skin,
                       const SkinWriteOptions& opt = {});

/// The translation, rotation and scale that compose into `m` (a mirror as a negative x scale), as a glTF node
/// holds them; nullopt when `m` has shear, a zero scale, or non-finite entries (the columns of its rotation
/// orthonormal within `tolerance`).
std::optional<geometry::JointTransform> to_trs(const Eigen::Affine3d& m, double tolerance = 1e-6);

}  // namespace mgcloth::sim
