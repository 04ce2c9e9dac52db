#pragma once
#include <mgcloth/geometry/rigid_motion.hpp>
#include <mgcloth/geometry/sdf_kernels.hpp>
#include <mgcloth/geometry/shapes.hpp>
#include <mgcloth/geometry/skin.hpp>

#include <memory>
#include <string>

namespace mgcloth::geometry {

/// A triangle mesh in an obstacle's own frame. Cloth touches it through the cloth-contact term (its vertices as
/// kinematic points), with the same guarantee as cloth touching cloth.
struct TriangleSurface {
  Mat3X vertices;      ///< in the obstacle's frame (a sequence's first frame)
  std::vector<Tri> tris;
  /// A deforming mesh: its vertices at times k / rate (k = 0, 1, …), interpolated linearly between them; held at the
  /// last after it, or with `loop` repeated with period frames.size() / rate (the last frame blends into the first).
  /// Empty: the mesh keeps `vertices`.
  std::vector<Mat3X> frames;
  double rate = 0.0;  ///< frames per second
  bool loop = false;
  /// A skinned mesh (glTF skin, the generated mannequin): the vertices at time t are its linear blend skinning
  /// (`vertices` its pose at t = 0, `tris` its triangles); null: `frames` or `vertices`. With `loop`, its animation repeats
  /// with period skin->duration().
  std::shared_ptr<const SkinnedMesh> skin;
  /// The vertices at time t in the obstacle's frame.
  Mat3X at(double t) const;
  /// The vertices at time t in the world, placed by `pose`, as one vector (3 per vertex).
  VecX placed(const Pose& pose, double t) const;
};

/// A moving rigid obstacle: a signed-distance shape or a triangle mesh, its motion, and its contact parameters.
struct Obstacle {
  std::string name;
  std::shared_ptr<const Shape> shape;  ///< null for a mesh obstacle
  std::shared_ptr<const RigidMotion> motion;  ///< null: fixed at the identity pose
  double friction = 0.0;  ///< Coulomb coefficient
  std::shared_ptr<const TriangleSurface> mesh;  ///< a mesh obstacle's surface (null: `shape` is one)
  double contact_thickness = 0.0;               ///< m, a mesh obstacle's side of the contact layer (0: the cloths')

  /// The pose at time t.
  Pose pose(double t) const { return motion ? motion->pose(t) : Pose{}; }
  /// A mesh obstacle's vertices in the world at time t (its pose, and its frame of a sequence).
  VecX mesh_positions(double t) const { return mesh->placed(pose(t), t); }

  /// World-frame signed distance at time t (gradient and Hessian rotated into the world frame).
  SdfSample sdf(const Vec3& p, double t) const;
  /// Same at a pose computed once (motion->pose(t)), for evaluating many points at one time:
  /// phi(p) = phi_local(Rᵀ(p - c)), grad = R grad_local, H = R H_local Rᵀ.
  SdfSample sdf(const Vec3& p, const Pose& pose) const;
  /// phi alone at a pose (no derivatives), the cheap test before sdf().
  double distance(const Vec3& p, const Pose& pose) const { return shape->distance(pose.to_local(p)); }
  /// The obstacle at time t (pose and velocity) as plain data for the shared kernels (hd::contact_psd,
  /// hd::project_out, hd::filter_velocity).
  hd::ObstacleData data(double t) const;
};

}  // namespace mgcloth::geometry
