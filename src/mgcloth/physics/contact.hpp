#pragma once
#include <mgcloth/geometry/obstacle.hpp>
#include <mgcloth/physics/element_kernels.hpp>
#include <mgcloth/physics/element_term.hpp>

namespace mgcloth::physics {

struct ContactParams {
  double thickness = 0.005;   ///< m: the penalty acts where the signed distance is below this
  double stiffness = 1.0e5;   ///< N/m³: penalty per unit of the vertex's area, k_i = stiffness · A_i
};

/// What every obstacle penalty shares: the obstacles (placed at the end-of-step time, set per step), the contact
/// layer of thickness d, per-vertex weights from the lumped areas, and the penalty's normal force, which friction
/// (apply_friction) needs whatever the penalty's form (ObstacleContact, PDObstacleContact).
class ObstaclePenalty : public ElementTerm<1> {
 public:
  /// Places the obstacles at time t for the following evaluations.
  void set_time(double t);
  const std::vector<geometry::Obstacle>& obstacles() const { return m_obstacles; }
  const std::vector<geometry::Pose>& poses() const { return m_poses; }
  /// The obstacles at their poses as plain data for the shared kernels (hd::contact_psd), set with the poses.
  const std::vector<hd::ObstacleData>& obstacle_data() const { return m_data; }
  const ContactParams& params() const { return m_params; }
  /// k_i = stiffness · A_i.
  double vertex_stiffness(Index i) const { return m_params.stiffness * m_area[i]; }
  /// Magnitude of the penalty force on vertex i at depth gap = d − φ > 0 into the contact layer of one obstacle.
  virtual double normal_force(Index i, double gap) const = 0;

 protected:
  /// One element per vertex; `vertex_area` gives the number of vertices.
  ObstaclePenalty(VecX vertex_area, std::vector<geometry::Obstacle> obstacles, const ContactParams& params);

 private:
  VecX m_area;
  std::vector<geometry::Obstacle> m_obstacles;
  std::vector<geometry::Pose> m_poses;
  std::vector<hd::ObstacleData> m_data;
  ContactParams m_params;
};

/// Obstacle penalty: E = Σ_i Σ_o k_i/(3d) (d − φ_o(x_i))³ where φ_o < d (Wang 2018 §4.5 uses penalties for
/// obstacle contact). Cubic rather than quadratic so that the Hessian is continuous where a vertex enters the
/// contact layer: with the C¹ quadratic penalty Newton zigzags across φ = d (measured 12% more iterations on the
/// sphere drape). The force k_i (d − φ)²/d reaches k_i d at the surface. Exact Hessian
/// (k/d)(2(d − φ)∇φ∇φᵀ − (d − φ)²∇²φ); the curvature part is negative on convex obstacles and clamped by projection.
class ObstacleContact final : public ObstaclePenalty {
 public:
  bool describe_device(DeviceObjective& out) const override;
  void describe_device_step(DeviceStep& out) const override;
  ObstacleContact(VecX vertex_area, std::vector<geometry::Obstacle> obstacles, const ContactParams& params);
  std::string name() const override { return "contact"; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;
  /// Σ_o 2(k/d)(d − φ_o) ∇φ_o∇φ_oᵀ (hd::contact_psd): each obstacle's term projected to PSD in closed form.
  void element_psd_hessian(Index e, const Local& xe, LocalHessian& H) const override;
  double normal_force(Index i, double gap) const override {
    return hd::contact_normal_force(vertex_stiffness(i), gap, params().thickness);
  }
};

/// Moves every vertex that lies inside an obstacle (φ < 0) back onto its surface along ∇φ (hd::project_vertex);
/// returns how many moved. `pushed` (if non-null) receives, per vertex, the distance moved.
Index project_out_of_obstacles(VecX& x, const std::vector<hd::ObstacleData>& obstacles, VecX* pushed = nullptr);

/// Coulomb friction by velocity filtering (hd::filter_velocity, Bridson et al. 2002) against the obstacles at the
/// contact's current time: for a vertex in contact, the normal velocity change is the penalty impulse h·f_n/m
/// (f_n = contact.normal_force) plus the projection push / h.
void apply_friction(const VecX& x, VecX& v, const VecX& mass, const ObstaclePenalty& contact, double h,
                    const VecX& pushed);

}  // namespace mgcloth::physics
