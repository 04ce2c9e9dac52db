#pragma once
// What a sweep reads off each run's last state (docs/sweeps.md, "measures"): probe positions, energies, and two
// textile measures, the drape coefficient (Cusick's drape tester) and the bending length (Peirce's cantilever).
#include <mgcloth/core/json.hpp>
#include <mgcloth/core/types.hpp>
#include <mgcloth/mesh/tri_mesh.hpp>

#include <string>
#include <vector>

namespace mgcloth::sim {
class Simulator;
}

namespace mgcloth::sweep {

/// One entry of a sweep's "measures": a named quantity of the run's last state, one or more CSV columns.
struct Measure {
  std::string name;
  /// probe | energy | kinetic_energy | drape_coefficient | bending_length
  std::string type;
  std::string cloth;  ///< the cloth it reads (empty: energy and kinetic energy sum over every cloth)
  Index vertex = -1;  ///< probe: by index, or (−1) the vertex nearest to `uv`
  Vec2 uv = Vec2::Zero();
  double support_radius = 0.0;  ///< drape_coefficient: the disc the specimen rests on, m
  int raster = 2048;            ///< drape_coefficient: cells per side of the shadow's raster
  double clamp = 0.0;           ///< bending_length: the clamp's edge, material coordinate along `axis`
  int axis = 0;                 ///< bending_length: 0 = u, 1 = v (the strip's length)

  /// probe: name_x, name_y, name_z; the others: name.
  std::vector<std::string> columns() const;
};

/// Parses one measure; InputError names file and path (`at`: "measures[2]").
Measure parse_measure(JsonReader& r);
Json to_json(const Measure& m);

/// The measure's values at the simulator's state, in columns() order. NaN where it is undefined (a bending length
/// whose tip is not below its clamp). InputError when the measure does not fit the scene (no cloth of that name, a
/// vertex out of range).
std::vector<double> evaluate(const Measure& m, const sim::Simulator& sim);

/// Area of the union of the triangles of `x` projected along `down` (the shadow a light at infinity along `down`
/// casts), by rasterizing the projection on a grid of `raster` × `raster` cells over its bounding box: a cell counts
/// when its centre lies in some triangle. The error is at most about the shadow's perimeter × one cell.
double shadow_area(const Mat3X& x, const std::vector<Tri>& tris, const Vec3& down, int raster);

/// Drape coefficient (Cusick 1968): (A_shadow − A_support) / (A_flat − A_support), 1 for a specimen that stays flat,
/// towards 0 for one that hangs straight down around its support.
double drape_coefficient(double shadow, double flat_area, double support_radius);

/// Peirce's (1930) bending length of a cantilever from its overhang `length` and the angle `theta` (radians) below
/// the horizontal of the chord from the clamp's edge to the tip: c = L (cos(θ/2) / (8 tan θ))^(1/3). For a heavy
/// elastica c³ = B / w (rigidity over weight per area). NaN unless 0 < θ < π/2.
double peirce_bending_length(double length, double theta);

}  // namespace mgcloth::sweep
