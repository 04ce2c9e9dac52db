#pragma once
#include <mgcloth/collision/broad_phase.hpp>
#include <mgcloth/physics/term.hpp>

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace mgcloth::physics {

/// The contact layer's energy per unit weight as a function of the distance d between two primitives, for a layer
/// of thickness r (the distance at which two cloth mid-surfaces of thicknesses t_a, t_b touch: (t_a + t_b)/2):
///   ψ(d) = k/(3r)·(r − d)³ + κ·b(d),   b(d) = −(d − τ)² ln(d/τ) for d < τ, else 0,   κ = k·r/τ.
/// The cubic is the obstacle penalty's (C² where a pair enters the layer, curvature at most 2k); the log term is
/// the barrier of Li et al. 2020 (IPC, eq. 6), C² at τ, which makes d = 0 unreachable. With τ = r/4 the curvature
/// is bounded in the outer three quarters of the layer, where contact rests under cloth loads (with the default
/// stiffness a few percent of r deep); the barrier only acts on impacts the cubic cannot stop. κ = k·r/τ makes
/// the barrier's force at d = τ/2 about the cubic's largest force k·r.
struct ContactLayer {
  double r = 1e-3;
  double tau = 0.25e-3;
  double k = 1.0;
  ContactLayer() = default;
  ContactLayer(double r, double tau_fraction, double k) : r(r), tau(tau_fraction * r), k(k) {}
  double kappa() const { return k * r / tau; }
  /// ψ(d), ψ'(d), ψ''(d) (derivatives filled when non-null); ψ = +∞ for d <= 0.
  double value(double d, double* d1 = nullptr, double* d2 = nullptr) const;
};

struct ClothContactParams {
  /// N/m³: k of a pair = stiffness × the area the pair stands for. Stiff enough that contact rests in the cubic's
  /// part of the layer: on two sheets falling onto a sphere (4K vertices, 12 steps) 1e5 took 1487 FMG cycles with
  /// several steps at the iteration limit, 1e7 1081, 1e8 331 (the same scene without cloth contact: 298).
  double stiffness = 1.0e8;
  double barrier_fraction = 0.25;  ///< τ/r
  /// Continuous collision detection stops a motion where a pair has come down to this fraction of its distance
  /// (Li et al. 2021, Alg. 1's s): the largest admissible step keeps every pair at least this far apart relative to
  /// where it started, or where the piece of the step that max_step checks started.
  double ccd_separation = 0.1;
};

/// One cloth (or a part of the unknown) that takes part in contact: its triangles in the unknown's numbering, its
/// material coordinates (pairs of one piece nearer than twice the layer in material space get a thinner layer)
/// and its contact thickness. A kinematic surface (an obstacle mesh) is not part of the unknown: its points are the
/// contact term's kinematic points, placed by ClothContact::set_kinematic_positions, and it touches the cloths but
/// never itself.
struct ContactSurface {
  std::string name;
  Index offset = 0;         ///< first point of this cloth in the unknown (of a kinematic surface: in the kinematic points)
  std::vector<Tri> tris;    ///< in the cloth's own numbering
  Mat2X material;           ///< per point of the cloth (unused for a kinematic surface)
  /// Points sewn together (Topology::stitch_groups, the cloth's numbering): the seam's sides lie in different charts
  /// of `material`; primitives sharing a point of a closed seam are never paired (ClothContact::close_seams).
  std::vector<std::vector<Index>> stitch_groups;
  VecX area;                ///< lumped area per point of the cloth (m²; of a kinematic surface: of its surface)
  double thickness = 1e-3;  ///< m
  bool kinematic = false;
};

/// What the contact term saw at the last point it was evaluated for statistics (contact_pairs, min_distance).
struct ContactStats {
  Index pairs = 0;                ///< pairs inside the contact layer
  double min_distance = kInf;     ///< over the pairs within the candidates' reach (kInf: none)
  Index cached = 0;               ///< pairs the near-pair cache holds (those that can enter their layer nearby)
};

/// Where the contact term's collision detection spent its time since the last take_times() (ms): broad phase with
/// the exact distances of its candidates (cache rebuilds), the distances of cached pairs per iterate, and continuous
/// collision detection of the cached pairs along steps. The energy, gradient and Hessian of the pairs are not in it.
struct ContactTimes {
  double broad_phase_ms = 0.0;
  double distances_ms = 0.0;
  double ccd_ms = 0.0;
  double detection_ms() const { return broad_phase_ms + distances_ms + ccd_ms; }
};

/// The Hessian blocks of 4-point stencils (every ordered pair of a stencil's points), shared by the contact and
/// friction terms.
void collect_stencil_pattern(const std::vector<std::array<Index, 4>>& stencils,
                             std::vector<std::pair<Index, Index>>& pairs,
                             Index unknown_points = std::numeric_limits<Index>::max());
/// Per stencil, the positions of its 4×4 blocks in `pattern` (`what` names the term in the error of a missing block).
/// Blocks of points at or beyond `unknown_points` (kinematic points, which have no rows) get the slot −1 and are
/// left out of the pattern by collect_stencil_pattern alike.
std::vector<std::array<Index, 16>> stencil_slots(const std::vector<std::array<Index, 4>>& stencils,
                                                 const linalg::BlockMatrix3& pattern, const char* what,
                                                 Index unknown_points = std::numeric_limits<Index>::max());

/// Contact between the triangles of every surface and within each (self-contact): vertex–triangle and edge–edge
/// pairs whose distance is below the layer r = (t_a + t_b)/2 carry the energy w·ψ(d) (ContactLayer) with
/// w = stiffness × the pair's area (the vertex's lumped area; for an edge a third of its triangles' areas, the two
/// edges averaged). Pairs that share a point are never formed; pairs of one piece of a cloth nearer than 2r in
/// material space act within half that distance instead of r (Pair::layer).
///
/// Intersection-freeness is the solvers' part: every trial point is limited by max_step() (continuous collision
/// detection along the step), so that a point reached from an intersection-free one never has a pair at d = 0,
/// where the energy is +∞.
///
/// Obstacle meshes take part as kinematic surfaces: their points follow the unknown's (index n + k for kinematic
/// point k), hold still within a solve and move between solves (set_kinematic_positions, after max_joint_step has
/// checked the motion). Pairs between kinematic points alone are never formed; the energy's gradient and Hessian
/// have the unknown's rows only.
///
/// The pairs near a point are cached: a rebuild at x_b finds every pair within ρ + 2δ (broad phase, then exact
/// distances; ρ = max(layer, r/2), cache_layer), which holds every pair inside its layer at any x whose points all
/// lie within δ of x_b after one common translation (distances ignore it). When only a few points are farther (at
/// most kLocalUpdateFraction of them), those alone get new bases and their pairs are searched again
/// (BroadPhase::find_touching): the other pairs keep their guarantee, and a cloth at rest whose edge flutters does
/// not pay for a whole search. Otherwise the cache is rebuilt. When many points move far, max_step() builds the
/// cache along its step x_b + [0, 1]·s instead, in a frame
/// moving with the step's mean (swept boxes of s − mean; each pair kept if its distance is below ρ + 2δ plus how far
/// its own points move relative to each other), so that the trial points of the line search that follows find it
/// valid, and a stack of cloths falling together does not sweep everything it passes; when few do, it searches only
/// their pairs along the step, for collision detection. A step that moves points farther than about a mesh spacing
/// relative to its mean is checked in pieces of that length, up to the first with a collision, and the cache then
/// holds the last piece checked. A step whose two ends the cache covers needs neither: the
/// points it covers form a convex set. Every step starts from a fresh cache (reset_near). The Hessian's stencils
/// are the pairs within layer + δ at the last change, kept until a pair inside the layer is missing from them, so
/// the pattern (and the multigrid's Galerkin maps and colorings) changes only when the contact set does.
class ClothContact final : public Term {
 public:
  /// `kinematic_positions`: the kinematic surfaces' points where they start (3 per point), which also give their
  /// triangles' areas.
  ClothContact(std::vector<ContactSurface> surfaces, Index num_points, const ClothContactParams& params,
               VecX kinematic_positions = {});
  ~ClothContact() override;

  std::string name() const override { return "cloth_contact"; }
  double value(const VecX& x) const override;
  void add_gradient(const VecX& x, VecX& g) const override;
  void add_hessian(const VecX& x, linalg::BlockMatrix3& H, bool project_psd) const override;
  void collect_pattern(std::vector<std::pair<Index, Index>>& pairs) const override;
  void bind(const linalg::BlockMatrix3& pattern) override;
  bool update_stencils(const VecX& x) override;
  double max_step(const VecX& x, const VecX& d, double alpha_max) const override;
  bool limits_steps() const override { return true; }

  const ClothContactParams& params() const { return m_params; }
  const std::vector<ContactSurface>& surfaces() const { return m_surfaces; }
  /// Every triangle of every surface, in the numbering of with_kinematic(x).
  const std::vector<Tri>& triangles() const { return m_topology.triangles; }
  /// Per point of triangles(), the first point of its stitch group where the seam was closed at the step's start
  /// (close_seams), else itself: the intersection checker's `joined` points (collision::find_intersections), so
  /// that triangles meeting across a closed seam share the point there as triangles of one chart do and as contact
  /// treats them. Points of an open seam keep their own: contact kept them apart.
  const std::vector<Index>& joined_points() const { return m_seam_point; }
  /// How many of triangles() are the cloths'; the kinematic surfaces' follow them.
  size_t cloth_triangles() const { return m_cloth_triangles; }
  Index num_kinematic() const { return m_m; }
  const VecX& kinematic_positions() const { return m_y; }
  /// Places the kinematic points for the evaluations that follow. Whether the motion there crosses a cloth is the
  /// caller's to check first (max_joint_step).
  void set_kinematic_positions(const VecX& y);
  /// x followed by the kinematic points: the positions triangles() refers to.
  VecX with_kinematic(const VecX& x) const;
  /// The largest fraction in [0, 1] of the joint motion in which the cloths move from x to x + dx and the kinematic
  /// points from where they are to y_end (straight lines), by the rule of max_step: no pair comes closer than
  /// ccd_separation times its distance on the way.
  double max_joint_step(const VecX& x, const VecX& dx, const VecX& y_end) const;
  /// Surface and own index of triangle t of triangles().
  std::pair<size_t, Index> triangle_owner(Index t) const;
  ContactStats stats(const VecX& x) const;
  /// The stencils from x alone (the pairs within r + δ), at the start of every step: within a step the pattern
  /// follows the iterates with hysteresis, but every step starts from a pattern that depends on its start point
  /// only, so a run resumed from a checkpoint assembles on the same patterns as the uninterrupted one.
  void start_step(const VecX& x);
  /// Drops the cache of near pairs, which local updates make depend on the iterates since its last rebuild: a step
  /// that starts from a fresh one sees the same pairs whether the run was resumed before it or not.
  void reset_near() { m_near_base.resize(0); }
  /// The seams closed at a step's start x: a stitch group whose points all lie within twice their layer of its first
  /// point. During the step, primitives sharing a point of a closed seam are never paired (never_paired); an open
  /// seam's two sides are contact like any other primitives, so that panels being sewn do not pass through each
  /// other (at the ends of seams, where several meet). Drops the cache of near pairs, whose pairs it changes.
  void close_seams(const VecX& x);
  /// The detection times accumulated since the last call, which resets them.
  ContactTimes take_times() const {
    const ContactTimes t = m_times;
    m_times = {};
    return t;
  }

 private:
  struct Pair {
    std::array<Index, 4> v;  ///< points (kinematic ones after the unknown's): (p, t0, t1, t2) or (a0, a1, b0, b1)
    bool edge_edge = false;
    double weight = 0.0;     ///< w
    double r = 0.0;          ///< the cloths' layer for this pair
    /// The layer its energy acts within: r, or for two primitives of one piece nearer than 2r in material space,
    /// half that material distance (material_layer).
    double layer = 0.0;
  };
  /// How far the cache reaches for pair p, less its margin: its layer, but never below kCacheFloor·r, so that a pair
  /// outside a valid cache is at least kCacheFloor·r_min apart (what collision_time relies on).
  static double cache_layer(const Pair& p) { return std::max(p.layer, kCacheFloor * p.r); }
  /// x (the unknown's points) followed by the kinematic points; x itself when there are none. Every private member
  /// takes and keeps points in this numbering.
  const VecX& extended(const VecX& x) const;
  /// The first point of surface c in the extended numbering.
  Index start(const ContactSurface& c) const { return c.kinematic ? m_n + c.offset : c.offset; }
  /// Pairs never formed: every point kinematic, or the two sides sharing a sewn point. Across a seam the charts
  /// do not meet, and such primitives touch at the seam as primitives sharing a vertex do (which the broad phase
  /// never pairs); the seam springs pull them to distance 0, which a layer would forbid.
  bool never_paired(const Pair& p) const;
  /// max_step over the extended points (step: their motion at α = alpha_max).
  double max_extended_step(const VecX& x, const VecX& step, double alpha_max) const;
  /// Continuous collision detection of the motion x + [0, 1]·step in one piece: the largest admissible fraction.
  double collision_time(const VecX& x, const VecX& step) const;
  /// The distance of pair p at x (exact, nearest features).
  double distance(const Pair& p, const VecX& x) const;
  /// w ψ(d) of pair p at x; gradient and Hessian (12) when non-null; 0 outside the layer.
  double pair_energy(const Pair& p, const VecX& x, Eigen::Matrix<double, 12, 1>* g,
                     Eigen::Matrix<double, 12, 12>* H, bool project_psd) const;
  /// A lower bound of distance(p, x) from the two sides' bounding boxes, an order of magnitude cheaper.
  double lower_bound_distance(const Pair& p, const VecX& x) const;
  /// Per near pair, its distance at x where that is below its layer + δ, a lower bound of it otherwise; computed
  /// once per x.
  const std::vector<double>& near_distances(const VecX& x) const;
  /// Makes the cache of near pairs valid at x.
  void ensure_near(const VecX& x) const;
  /// The points of x farther than δ from their segments [x_b, x_b + s] of the cache, after the common translation c
  /// and segment parameter t that fit x best (both returned).
  std::vector<Index> escaped(const VecX& x, Vec3& c, double& t) const;
  /// Whether every point of x is within δ of its segment of the cache.
  bool near_valid(const VecX& x) const;
  /// The cache at x, for every point within δ of x (step null) or of the segment from x along *step.
  void rebuild_near(const VecX& x, const VecX* step) const;
  /// The cache made valid at x by new bases for the `moved` points (escaped() at x, with its c and t) and a search
  /// for their pairs alone.
  void update_near(const VecX& x, const std::vector<Index>& moved, const Vec3& c, double t) const;
  /// The cache's pairs among m_candidates (those within reach at base x with the cache's step rel), appended.
  void add_near_pairs(const VecX& x, const VecX& rel) const;
  /// Candidate k of c (vertex–triangle ones first) as a pair, its weight and layer set.
  Pair candidate_pair(const collision::Candidates& c, Index k) const;
  /// Beyond this fraction of the points, a local update of the cache costs about as much as a rebuild.
  static constexpr double kLocalUpdateFraction = 0.25;
  /// A pair of one piece nearer than 2r in material space gets this fraction of that distance as its layer.
  static constexpr double kNeighbourLayer = 0.5;
  /// Where the mesh spacing is below r, a cache that reached r + 2δ for every pair held each point's neighbours on
  /// the cloth: 4.4M pairs on the full-size dress, of which 74K were in contact (bench/RESULTS.md). Pairs of one piece
  /// reach their own, narrower layer instead, down to this fraction of r.
  static constexpr double kCacheFloor = 0.5;
  /// The near pairs (indices into m_near) inside their layer at x.
  std::vector<Index> active(const VecX& x) const;
  /// Pair p's energy layer (Pair::layer).
  double material_layer(const Pair& p) const;
  std::vector<std::array<Index, 4>> stencils_at(const VecX& x) const;

  std::vector<ContactSurface> m_surfaces;
  Index m_n;       ///< points of the unknown
  Index m_m = 0;   ///< kinematic points, numbered after them
  Index m_all = 0; ///< m_n + m_m
  VecX m_y;        ///< the kinematic points' positions
  size_t m_cloth_triangles = 0;
  mutable VecX m_extended;
  ClothContactParams m_params;
  collision::SurfaceTopology m_topology;
  std::vector<Index> m_surface_of_point;  ///< per point (kinematic ones too), its surface (-1: none)
  std::vector<Index> m_stitch_first;      ///< per point, the first point of its stitch group (itself if unsewn)
  std::vector<Index> m_seam_point;        ///< m_stitch_first where the seam is closed (close_seams), else itself
  std::vector<Index> m_chart;             ///< per point, its connected piece of triangles (panels are pieces)
  std::vector<Index> m_triangle_start;    ///< first triangle of each surface in m_topology.triangles
  VecX m_point_area, m_edge_area, m_point_r;
  double m_max_r = 0.0, m_min_r = kInf;

  mutable std::unique_ptr<collision::BroadPhase> m_broad;
  mutable collision::Candidates m_candidates;
  mutable std::vector<Pair> m_near;
  mutable VecX m_near_base;  ///< x_b of the cache (empty: none)
  mutable VecX m_near_step;  ///< the step the cache holds for, less its mean displacement (zero: none)
  mutable std::uint64_t m_near_generation = 0;  ///< counts the cache's rebuilds
  mutable VecX m_eval_x;                        ///< the point of m_eval_d
  mutable std::vector<double> m_eval_d;         ///< near_distances(m_eval_x)
  mutable std::uint64_t m_eval_generation = ~std::uint64_t{0};
  mutable ContactTimes m_times;
  double m_delta = 0.0;      ///< δ of the cache
  double m_sweep_length = kInf;  ///< the most a piece of a checked step moves a point relative to the mean

  std::vector<std::array<Index, 4>> m_stencils;  ///< sorted, the pattern's contact stencils
  bool m_stencils_pending = false;               ///< start_step changed them: the next update_stencils says so
  std::vector<std::array<Index, 16>> m_slots;    ///< per stencil, the pattern positions of its 4×4 blocks

 public:
  /// A pair inside the layer as lagged friction freezes it at a step's start (Li et al. 2020, §5): its points, the
  /// weights c of its nearest points (Σ_i c_i x_i is the pair's relative position: the first side's nearest point
  /// less the second's), the contact normal, an orthonormal tangent basis and the normal force.
  struct ContactFrame {
    std::array<Index, 4> v{};       ///< (p, t0, t1, t2) or (a0, a1, b0, b1); kinematic points after the unknown's
    std::array<double, 4> c{};      ///< (1, −β0, −β1, −β2) or (1 − a, a, −(1 − b), −b)
    bool edge_edge = false;
    Vec3 normal = Vec3::Zero();     ///< Σ c_i x_i / d: from the second side towards the first
    Eigen::Matrix<double, 3, 2> tangent = Eigen::Matrix<double, 3, 2>::Zero();  ///< orthonormal, ⟂ normal
    double normal_force = 0.0;      ///< λ = −w ψ'(d) >= 0
    Index surface_a = -1, surface_b = -1;  ///< the two sides' surfaces (indices into surfaces())
  };
  /// The frames of every pair inside the layer at x, sorted by their points (so independent of the cache's history).
  std::vector<ContactFrame> contact_frames(const VecX& x) const;
};

}  // namespace mgcloth::physics
