#pragma once
#include <mgcloth/hierarchy/subdivision_hierarchy.hpp>
#include <mgcloth/mesh/limit_surface.hpp>
#include <mgcloth/physics/objective.hpp>
#include <mgcloth/physics/shell.hpp>
#include <mgcloth/physics/shell_samples.hpp>
#include <mgcloth/sim/shell_scene.hpp>

#include <memory>

namespace mgcloth::sim {

/// One probe reading: the limit-surface position of a material point and its displacement from the rest state.
struct ProbeReading {
  Vec2 at;
  Vec3 x, u;
};

/// One subdivision Kirchhoff-Love shell (Kopaničáková 2019): its control-mesh hierarchy, the objective of one
/// step on the finest level (shell energy, penalty boundary conditions, loads), and its state (control points and
/// their velocities). The unknowns are the finest control points, ghost points included.
class ShellBody {
 public:
  /// `source` names the scene file in messages.
  ShellBody(const ShellSpec& spec, const Vec3& gravity, const std::string& source);

  const std::string& name() const { return m_spec.name; }
  const ShellSpec& spec() const { return m_spec; }
  bool is_static() const { return m_spec.analysis == "static"; }
  const hierarchy::SubdivisionHierarchy& hierarchy() const { return m_hierarchy; }
  const mesh::LimitSurface& surface() const { return *m_surface; }
  /// β of the penalty on the finest level (h^-σ unless given).
  double penalty() const { return m_beta; }
  /// Mesh size h: the mean material length of the real faces' edges on the finest level.
  double mesh_size() const { return m_h; }

  VecX& x() { return m_x; }
  VecX& v() { return m_v; }
  const VecX& x() const { return m_x; }
  const VecX& v() const { return m_v; }

  /// Sets the objective of the step ending at t_next (dynamic: implicit Euler with step h, start y = x + h v;
  /// static: equilibrium at load factor `load_factor`, start x). Returns the solve's start point.
  VecX prepare_step(double t_next, double h, double load_factor);
  physics::Objective& objective() { return *m_objective; }
  const physics::ShellTerm& shell_term() const { return *m_shell; }
  /// Accepts the solve's result: v = (x_new − x) / h (dynamic; zero in static runs), x = x_new.
  void finish_step(const VecX& x_new, double h);

  /// The display mesh of the limit surface (material coordinates as vt) and its positions for the current state.
  const mesh::TriMesh& display_mesh() const { return m_display.mesh; }
  Mat3X display_positions() const { return m_display.positions(as_columns(m_x)); }
  std::vector<ProbeReading> probes() const;

 private:
  /// A sample's rest position and the scaling that follows the load factor or ramp.
  struct Driven {
    Index sample;
    Vec3 rest, vector;  ///< target: rest + factor · vector (penalties); load: factor · vector
    double ramp_time;
  };
  void build_boundary();
  void build_loads();
  /// Boundary segments (face, edge) of the selection.
  std::vector<std::pair<Index, int>> select_segments(const ShellSelection& sel, const std::string& what) const;
  /// Gauss samples along a boundary segment: stencil, quadrature weight times reference length, cross derivative.
  struct EdgeSample {
    mesh::LimitStencil stencil;
    double ds;
    int cross;  ///< stencil column of the derivative across the boundary
  };
  std::vector<EdgeSample> edge_samples(Index face, int k) const;
  mesh::LimitStencil locate(const Vec2& u, const std::string& what) const;
  static double factor(double t, double ramp_time, bool is_static, double load_factor);

  ShellSpec m_spec;
  std::string m_source;
  hierarchy::SubdivisionHierarchy m_hierarchy;
  std::unique_ptr<mesh::LimitSurface> m_surface;
  std::unique_ptr<physics::Objective> m_objective;
  physics::ShellTerm* m_shell = nullptr;
  physics::ShellSampleTerm* m_samples = nullptr;
  std::vector<Driven> m_targets, m_loads;
  double m_beta = 0.0, m_h = 0.0;
  VecX m_x, m_v;
  mesh::LimitSurface::Tessellation m_display;
  std::vector<mesh::LimitStencil> m_probe_stencils;
  std::vector<Vec3> m_probe_rest;
};

}  // namespace mgcloth::sim
