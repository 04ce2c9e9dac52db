#pragma once
#include <mgcloth/core/types.hpp>

#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace mgcloth::geometry {

/// How a keyframe track is read between its keys (glTF 2.0 animation sampler interpolation).
enum class Interpolation { Linear, Step, CubicSpline };

/// Keyframes of one vector or quaternion quantity. CubicSpline keys carry an in- and an out-tangent per key
/// (glTF 2.0 Appendix C: Hermite spline over each interval, tangents scaled by its length). Quaternions are
/// stored as (x, y, z, w) in a Vector4d, as glTF stores them.
template <int N>
struct Track {
  using Value = Eigen::Matrix<double, N, 1>;
  std::vector<double> times;  ///< s, strictly increasing; empty: the joint keeps its rest value
  std::vector<Value> values;
  std::vector<Value> in_tangents, out_tangents;  ///< CubicSpline only, one per key
  Interpolation interpolation = Interpolation::Linear;
  bool empty() const { return times.empty(); }
  /// The value at time t, held at the first key before it and at the last after it. Rotations (N = 4) are
  /// slerped between Linear keys and normalized after a CubicSpline.
  Value at(double t) const;
};

/// A joint's local transform as glTF writes it: translation, rotation, scale (applied scale first).
struct JointTransform {
  Vec3 translation = Vec3::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Vec3 scale = Vec3::Ones();
  Eigen::Affine3d matrix() const;
};

/// A triangle mesh deformed by linear blend skinning (glTF 2.0 skins): vertex v at time t is
/// placement · Σ_k w_vk · world_{j_vk}(t) · inverse_bind_{j_vk} · rest_v.
struct SkinnedMesh {
  Mat3X rest;  ///< the bind-pose vertices, in the skin's own coordinates
  std::vector<Tri> tris;
  Eigen::Matrix4Xi joints;   ///< per vertex up to 4 joint indices (into joint_names)
  Eigen::Matrix4Xd weights;  ///< per vertex, ≥ 0, summing to 1 (unused slots: weight 0)

  std::vector<std::string> joint_names;
  std::vector<int> parent;               ///< per joint, the index of its parent joint (< its own), or −1
  std::vector<JointTransform> rest_local;  ///< per joint, its local transform where it has no track
  std::vector<Eigen::Affine3d> inverse_bind;  ///< per joint
  /// Per joint, its animation (each of the three may be empty).
  struct JointTracks {
    Track<3> translation;
    Track<4> rotation;
    Track<3> scale;
  };
  std::vector<JointTracks> tracks;
  /// Applied to every skinned position (e.g. glTF's y-up into mgcloth's z-up, or a user's placement).
  Eigen::Affine3d placement = Eigen::Affine3d::Identity();

  Index num_vertices() const { return static_cast<Index>(rest.cols()); }
  Index num_joints() const { return static_cast<Index>(joint_names.size()); }
  /// The last key time of any track (0 when nothing is animated).
  double duration() const;
  /// Per joint, its local transform at time t (tracks where present, rest_local otherwise).
  std::vector<JointTransform> local_at(double t) const;
  /// Per joint, its world transform at time t (parents composed; placement not applied).
  std::vector<Eigen::Affine3d> world_at(double t) const;
  /// The skinned vertices at time t, placement applied.
  Mat3X at(double t) const;
  /// Throws InputError naming `what` when the arrays disagree in size, a parent does not come before its child, a
  /// joint index is out of range, a weight is negative or not finite, a vertex's weights do not sum to 1 within
  /// 1e-3, a transform or key is not finite or a rotation is zero, or a track's times are not strictly increasing.
  void validate(const std::string& what) const;
};

}  // namespace mgcloth::geometry
