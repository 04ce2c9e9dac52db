#pragma once
// The cantilever bending test of textiles (ASTM D1388) in simulation: a cloth strip clamped at one end and bent by its
// own weight, compared with the heavy elastica B θ'' = −w (L − s) cos θ, θ(0) = 0, θ'(L) = 0 (θ the slope below the
// horizontal), which gives the bending rigidity that the discretization realizes (bench/bending_bench.cpp).
#include <mgcloth/core/types.hpp>
#include <mgcloth/mesh/tri_mesh.hpp>
#include <mgcloth/physics/material.hpp>

#include <vector>

namespace mgcloth::sim {

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

/// Realized rigidity of a clamped strip: B such that the elastica of the free length L − clamp has the mean
/// deflection of the strip's vertices within `tip` of its free end (so a jagged end is compared point by point).
struct CantileverResult {
  double rigidity = 0.0;  ///< realized B, to compare with material.bending_stiffness
  double drop = 0.0;      ///< mean deflection of the tip vertices
  double elastica_drop = 0.0;  ///< the same mean for B = bending_stiffness
};
CantileverResult cantilever(const Strip& strip, const physics::Material& material, double clamp, double tip);

}  // namespace mgcloth::sim
