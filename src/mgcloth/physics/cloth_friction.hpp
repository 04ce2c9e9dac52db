#pragma once
#include <mgcloth/physics/cloth_contact.hpp>
#include <mgcloth/physics/term.hpp>

#include <array>
#include <string>
#include <vector>

namespace mgcloth::physics {

/// Coulomb coefficient μ for one unordered pair of cloths (a cloth with itself when both names are equal).
struct ClothFrictionPair {
  std::string a, b;
  double friction = 0.0;
};

struct ClothFrictionParams {
  /// μ of every pair of cloths, a cloth with itself included, unless `pairs` sets its own. Fabrics on fabrics
  /// measure about 0.3 to 0.6; one μ serves as both the static and the kinetic coefficient here, and the kinetic one,
  /// which governs layers sliding over each other, is the lower: the low end.
  double friction = 0.3;
  std::vector<ClothFrictionPair> pairs;
  /// ε_v (m/s): relative tangential speeds below it are static friction, smoothed (Li et al. 2020, §5): a load
  /// below μ times the normal force lets a contact creep at most ε_v. Small against cloth motions (cm/s to m/s),
  /// large enough that the sticking part of the energy stays well conditioned (its curvature is 2μλ/(ε_v h)).
  double static_velocity = 1e-3;
};

/// Lagged Coulomb friction between cloths and within a cloth (Li et al. 2020, IPC, §5): at the start of every step
/// the pairs inside the contact layer at the step's start x⁰ are frozen (ClothContact::contact_frames: normal force
/// λ_k, nearest-point weights c_k, tangent basis T_k), and the step minimizes, with the rest of the incremental
/// potential,
///   D(x) = Σ_k μ_k λ_k f0(‖u_k‖),   u_k = T_kᵀ Σ_i c_ki (x_i − x⁰_i)   (x_i of a kinematic point: where it ends)
/// with IPC's mollifier for ε_x = ε_v h: f0(y) = −y³/(3ε_x²) + y²/ε_x + ε_x/3 below ε_x, y above,
/// so that f0' = f1 rises smoothly from 0 to 1 (static friction) and stays 1 (sliding: the force is μλ). D is C²;
/// its exact Hessian is positive semi-definite, so no projection is needed. It limits no step.
class ClothFriction final : public Term {
 public:
  /// `surfaces`: the contact term's surface names in its order (the frames' surface indices refer to them).
  ClothFriction(Index num_points, const std::vector<std::string>& surfaces, const ClothFrictionParams& params);

  std::string name() const override { return "cloth_friction"; }
  double value(const VecX& x) const override;
  void add_gradient(const VecX& x, VecX& g) const override;
  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const override;
  void collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const override;
  void bind(const linalg::BlockMatrix3& pattern) override;
  bool update_stencils(const VecX& x) override;

  /// Freezes the step's friction at its start x0 from the contact frames there, for a step of length h. Frames may
  /// hold kinematic points (numbered after the unknown's, as in ClothContact); `kinematic_motion` is their
  /// displacement over the step (3 per point; null: they hold still), so that an obstacle drags what sticks to it.
  void start_step(const VecX& x0, const std::vector<ClothContact::ContactFrame>& frames, double h,
                  const VecX* kinematic_motion = nullptr);
  /// μ between surfaces a and b.
  double friction(Index a, Index b) const { return m_mu[static_cast<size_t>(a * m_surfaces + b)]; }
  /// Number of frozen pairs that carry friction this step.
  Index num_pairs() const { return static_cast<Index>(m_elements.size()); }
  /// ε_x = ε_v h of this step: tangential displacements below it are (smoothed) static friction.
  double slip_threshold() const { return m_eps; }

  /// μλ f0(‖u‖) of one frozen pair at relative tangential displacement u, with its derivatives in u.
  static double element_energy(double mu_lambda, double eps, const Vec2& u, Vec2* g, Mat2* H);

 private:
  struct Element {
    std::array<Index, 4> v;
    std::array<double, 4> c;
    Eigen::Matrix<double, 3, 2> T;
    Vec3 base;  ///< Σ c_i x⁰_i
    double weight;  ///< μλ
    Index stencil;  ///< index into m_stencils
  };
  Vec2 displacement(const Element& e, const VecX& x) const;
  std::vector<std::array<Index, 4>> stencils() const;

  Index m_n;
  Index m_surfaces;
  ClothFrictionParams m_params;
  std::vector<double> m_mu;  ///< μ per (surface a, surface b), symmetric
  double m_eps = 0.0;
  std::vector<Element> m_elements;
  std::vector<std::array<Index, 4>> m_stencils;  ///< sorted, unique
  bool m_stencils_pending = false;
  std::vector<std::array<Index, 16>> m_slots;  ///< per stencil, the pattern positions of its 4×4 blocks
};

}  // namespace mgcloth::physics
