#pragma once
#include <mgcloth/hierarchy/reverse_subdivision.hpp>
#include <mgcloth/hierarchy/subdivision_hierarchy.hpp>
#include <mgcloth/mesh/limit_surface.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/physics/shell.hpp>
#include <mgcloth/physics/shell_samples.hpp>
#include <mgcloth/bodies/body.hpp>
#include <mgcloth/bodies/shell_spec.hpp>

#include <map>
#include <memory>

namespace mgcloth::bodies {

/// One subdivision Kirchhoff-Love shell (Kopaničáková 2019): its control-mesh hierarchy, the objective of one
/// step on the finest level (shell energy, penalty boundary conditions, loads), and its state (control points and
/// their velocities). The unknowns are the finest control points, ghost points included. For multilevel solvers
/// the same step is also rediscretized on every coarser control mesh (§6: boundary conditions and loads are
/// distributed to every level), with the transfer operators between levels.
class ShellBody final : public Body {
 public:
  /// `source` names the scene file in messages.
  ShellBody(const ShellSpec& spec, const Vec3& gravity, const std::string& source);
  ~ShellBody();

  const std::string& name() const override { return m_spec.name; }
  std::string kind() const override { return "shell"; }
  std::string size_text() const override;
  const ShellSpec& spec() const { return m_spec; }
  bool is_static() const override { return m_spec.analysis == "static"; }
  const hierarchy::SubdivisionHierarchy& hierarchy() const { return m_hierarchy; }
  const mesh::LimitSurface& surface() const { return *finest().surface; }
  /// β of the penalty on the finest level (h^-σ unless given).
  double penalty() const { return finest().beta; }
  /// Mesh size h: the mean material length of the real faces' edges on the finest level.
  double mesh_size() const { return finest().h; }

  VecX& x() override { return m_x; }
  VecX& v() override { return m_v; }
  const VecX& x() const override { return m_x; }
  const VecX& v() const override { return m_v; }

  /// Sets the objective of the step ending at t_next (dynamic: implicit Euler with step h, start y = x + h v;
  /// static: equilibrium at load factor `load_factor`, start x), on the finest level and on every coarse level
  /// built so far (their inertia targets are y projected by reverse subdivision). Returns the solve's start point.
  VecX prepare_step(double t_next, double h, double load_factor);
  VecX prepare_step(const StepTime& step) override { return prepare_step(step.t + step.h, step.h, step.load_factor); }
  physics::Objective& objective() override { return *finest().objective; }
  const physics::ShellTerm& shell_term() const { return *finest().shell; }
  /// Accepts the solve's result: v = (x_new − x) / h (dynamic; zero in static runs), x = x_new.
  void finish_step(VecX& x_new, double h) override;

  /// Levels of the hierarchy (level 0 the coarsest, num_levels() − 1 the finest).
  int num_levels() const { return m_hierarchy.num_levels(); }
  /// The step's objective rediscretized on `level`: shell energy on that level's limit surface, the same boundary
  /// conditions and loads with that level's penalty β_l = h_l^-σ. Coarse levels are built on first use and then
  /// kept in step with the finest by prepare_step().
  physics::Objective& level_objective(int level);
  /// Q of §5.3.2 from `level` + 1 to `level` (Q S = I), or null where reverse subdivision has no rule for some point
  /// of the mesh (then only the least-squares projection exists). Built on first use.
  const linalg::StencilTable* reverse_subdivision(int level);
  /// The least-squares projection of eq. 5.18 from `level` + 1 to `level`, built on first use.
  const hierarchy::LeastSquaresProjection& least_squares(int level);
  /// Smoothing patches of `level`: every control point with its one-ring (the points of the faces around it).
  const std::vector<std::vector<Index>>& patches(int level);
  /// Projects an iterate of `level` + 1 to `level`: reverse subdivision where it exists, least squares otherwise.
  void project(int level, const VecX& fine, VecX& coarse);

  /// The hierarchy as a solver sees it (solvers::Problem::hierarchy), finest first: problem level k is hierarchy
  /// level num_levels() − 1 − k. Prolongations (S) always; with `rediscretized` also the step's objective on every
  /// level, the projections of iterates (reverse subdivision where it exists, and least squares) and the patches.
  hierarchy::Hierarchy solver_hierarchy(bool rediscretized) override;

  /// The display mesh of the limit surface (material coordinates as vt) and its positions for the current state.
  const mesh::TriMesh& display_mesh() const { return m_display.mesh; }
  Mat3X display_positions() const { return m_display.positions(as_columns(m_x)); }
  const mesh::TriMesh& surface_mesh() const override { return display_mesh(); }
  Mat2X surface_uv() const override { return display_mesh().u; }
  Mat3X surface_positions() const override { return display_positions(); }
  std::size_t num_probes() const override { return m_spec.probes.size(); }
  std::vector<ProbeReading> probes() const override;

 private:
  /// A sample's rest position and the scaling that follows the load factor or ramp.
  struct Driven {
    Index sample;
    Vec3 rest, vector;  ///< target: rest + factor · vector (penalties); load: factor · vector
    double ramp_time;
  };
  /// One level's discretization of the step.
  struct Level {
    int index = 0;
    std::unique_ptr<mesh::LimitSurface> surface;
    std::unique_ptr<physics::Objective> objective;
    physics::ShellTerm* shell = nullptr;
    physics::ShellSampleTerm* samples = nullptr;
    std::vector<Driven> targets, loads;
    double beta = 0.0, h = 0.0;
    const mesh::QuadMesh& mesh(const ShellBody& b) const { return b.m_hierarchy.mesh(index); }
  };
  const Level& finest() const { return *m_levels.back(); }
  std::unique_ptr<Level> build_level(int index) const;
  /// Boundary conditions and loads of `lv`, sampled on the surface of `geo` (lv itself, or the finest level, whose
  /// samples are then restricted to lv's control points through the composed S).
  void build_boundary(const Level& geo, Level& lv) const;
  void build_loads(const Level& geo, Level& lv) const;
  physics::ShellSample sample_on(const Level& geo, const Level& lv, const mesh::LimitStencil& st, int column,
                                 std::map<Index, std::vector<std::pair<Index, double>>>& rows) const;
  /// Sets targets, loads, inertia and gravity of one level for the step (y: the level's inertial prediction).
  void prepare_level(Level& lv, double t_next, double h, double load_factor, const VecX& x, const VecX& y);
  /// Boundary segments (face, edge) of the selection on the level.
  std::vector<std::pair<Index, int>> select_segments(const Level& lv, const ShellSelection& sel, const std::string& what) const;
  /// Gauss samples along a boundary segment: stencil, quadrature weight times reference length, cross derivative.
  struct EdgeSample {
    mesh::LimitStencil stencil;
    double ds;
    int cross;  ///< stencil column of the derivative across the boundary
  };
  std::vector<EdgeSample> edge_samples(const Level& lv, Index face, int k) const;
  mesh::LimitStencil locate(const Level& lv, const Vec2& u, const std::string& what) const;
  /// Finest control point v as a combination of `level`'s control points (a row of the composed S).
  std::vector<std::pair<Index, double>> control_point_on_level(Index v, int level) const;
  static double factor(double t, double ramp_time, bool is_static, double load_factor);

  ShellSpec m_spec;
  std::string m_source;
  Vec3 m_gravity;
  hierarchy::SubdivisionHierarchy m_hierarchy;
  /// m_levels[l] for l = 0..L-1; coarse entries null until level_objective() builds them.
  std::vector<std::unique_ptr<Level>> m_levels;
  std::vector<std::unique_ptr<linalg::StencilTable>> m_reverse;
  std::vector<char> m_reverse_tried;
  std::vector<std::unique_ptr<hierarchy::LeastSquaresProjection>> m_lsq;
  std::vector<std::vector<std::vector<Index>>> m_patches;
  /// The last prepare_step()'s arguments, so that levels built later join the current step.
  double m_t_next = 0.0, m_step_h = 0.0, m_load_factor = 0.0;
  bool m_prepared = false;
  VecX m_y;
  VecX m_x, m_v;
  mesh::LimitSurface::Tessellation m_display;
  std::vector<mesh::LimitStencil> m_probe_stencils;
  std::vector<Vec3> m_probe_rest;
};

}  // namespace mgcloth::bodies
