#pragma once
// The cantilever bending test of textiles (ASTM D1388) in simulation: a cloth strip clamped at one end and bent by its
// own weight, compared with the heavy elastica B θ'' = −w (L − s) cos θ, θ(0) = 0, θ'(L) = 0 (θ the slope below the
// horizontal), which gives the bending rigidity that the discretization realizes (bench/bending_bench.cpp).
#include <mgcloth/core/types.hpp>
#include <mgcloth/mesh/tri_mesh.hpp>
#include <mgcloth/physics/material.hpp>

#include <vector>

namespace mgcloth::studies {

/// The elastica's deflection z(s) ≥ 0 below the clamp at arc lengths `s` (each in [0, L]), for rigidity B (N·m per
/// unit width) and weight w (N/m² : per unit length per unit width). Shooting on θ'(0) with RK4 steps.
std::vector<double> elastica_deflection(double B, double w, double L, const std::vector<double>& s);

/// The rigidity B for which the elastica's mean deflection at arc lengths `s` equals `mean_drop` (bisection in log B).
double elastica_rigidity(double mean_drop, double w, double L, const std::vector<double>& s);

/// A cloth strip in its own frame: material (and initial world) coordinates with s = x along the strip in [0, length]
/// and t = y across it in [0, width]. `angle_deg` is the angle between the strip and the generator's u axis: 0 and 90
/// come straight from the rectangle generator (90 rotated), other angles are cut from a larger rotated rectangle.
struct Strip {
  mesh::TriMesh mesh;
  double length = 0.0, width = 0.0;
};
Strip make_strip(bool unstructured, double angle_deg, Index vertices, double length, double width);

/// Static equilibrium of the strip clamped along s ≤ clamp (the vertices there pinned where they are) under gravity
/// −z, solved by Newton with CHOLMOD; returns the world positions. Throws Error when Newton does not converge.
Mat3X hang_strip(const Strip& strip, const physics::Material& material, double clamp);

/// The strip's triangles whose centroids lie within s ≤ length (the same clamp, a shorter overhang).
Strip truncate_strip(const Strip& strip, double length);

/// Realized rigidity of a clamped strip from the mean deflection of the vertices within `tip` of the free end
/// (compared point by point, so a jagged end is fine), against the elastica. The strip and its copy truncated to half
/// the overhang are both hung: the rigidity B and the position c* where the clamp acts are the pair for which the
/// elastica gives both drops. c* differs from the pinned line by a fraction of an edge, differently per model and
/// mesh (a discretization's boundary layer); with c* fixed at the pins instead, that O(h) offset changes the drop of
/// a tip ∝ L⁴ by ~4 c*/L, which at 3,000 vertices is as large as the 2% to be measured.
struct CantileverResult {
  double rigidity = 0.0;          ///< realized B (with the clamp at c*), to compare with material.bending_stiffness
  double clamp_offset = 0.0;      ///< c* minus the pinned line's s, m
  double rigidity_at_pins = 0.0;  ///< B from the long overhang with the clamp at the pinned line
  double edge_length = 0.0;       ///< mean edge length of the strip
  double drop = 0.0;              ///< mean deflection of the long overhang's tip vertices
  double elastica_drop = 0.0;     ///< the same mean for B = bending_stiffness, clamped at the pins
};
CantileverResult cantilever(const Strip& strip, const physics::Material& material, double clamp, double tip);

}  // namespace mgcloth::studies
