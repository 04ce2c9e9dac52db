#pragma once
#include <mgcloth/core/types.hpp>
#include <mgcloth/geometry/sdf_kernels.hpp>

#include <Eigen/SparseCore>

#include <array>
#include <string>
#include <vector>

namespace mgcloth::physics {

struct TriangleCurvature;

/// What a device pipeline (cuda/) needs to evaluate an objective, in the problem's numbering: every term with a
/// device implementation writes its part (Term::describe_device), so that the pipeline reads flat arrays and never
/// looks at concrete term types. The device kernels are the element math of element_kernels.hpp, the same as the
/// terms' own; one term of each kind.
struct DeviceObjective {
  Index n = 0;  ///< vertices
  // Inertia Σ m_i/(2h²)|x_i − y_i|² (the prediction y comes per step) and gravity −Σ m_i g·x_i with the same masses.
  bool inertia = false, gravity = false;
  std::vector<double> mass, gravity_mass;
  Vec3 g = Vec3::Zero();
  // StVK membrane: triangles, Dm⁻¹ (row-major) and area·thickness per triangle, Lamé parameters.
  bool membrane = false;
  std::vector<std::array<Index, 3>> triangles;
  std::vector<std::array<double, 4>> dm_inv;
  std::vector<double> area_thickness;
  double mu = 0.0, lambda = 0.0;
  // Bending: hinges with their weights (and Bergou's cotangent weights), or the consistent quadratic bending's
  // matrix K and curvature weights (pointers into the term, valid while it lives).
  enum class Bending { None, Hinge, Quadratic, Isometric } bending = Bending::None;
  std::vector<std::array<Index, 4>> hinges;
  std::vector<double> hinge_c;
  std::vector<std::array<double, 4>> hinge_k;
  const Eigen::SparseMatrix<double, Eigen::RowMajor>* bend_matrix = nullptr;
  const TriangleCurvature* curvature = nullptr;
  double bend_stiffness = 0.0;
  // Pins: vertex and stiffness of every pin, in the term's order (targets per step in the same order).
  bool pins = false;
  std::vector<Index> pin_vertex;
  std::vector<double> pin_k;
  // The cubic obstacle penalty: stiffness · area per vertex and the contact thickness (obstacle poses per step).
  bool contact = false;
  std::vector<double> contact_k;
  double thickness = 0.0;

  /// Marks `kind` as described by term `term`; InputError when another term already described it.
  void claim(bool& kind, const std::string& term);
};

/// What changes from one time step to the next, in the problem's numbering: the inertial prediction, the pins'
/// targets, the obstacles' poses at the step's end.
struct DeviceStep {
  VecX y;
  double inv_h2 = 0.0;
  std::vector<Vec3> pin_targets;
  std::vector<hd::ObstacleData> obstacles;
};

}  // namespace mgcloth::physics
