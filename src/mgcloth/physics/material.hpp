#pragma once
#include <string>

namespace mgcloth::physics {

enum class MembraneModel { StVK, MassSpring };
/// Quadratic (the default): the consistent isometric model (IsometricBending), whose realized rigidity is k_b on
/// any mesh and in any direction; Hinge: discrete shells (dihedral angles); QuadraticBergou: Bergou et al. 2006's
/// per-hinge quadratic form. bench/RESULTS.md measures each one's realized rigidity per mesh and direction.
enum class BendingModel { Hinge, Quadratic, QuadraticBergou, None };

/// Cloth material in SI units. Defaults: a medium-weight plain-woven cotton (about 150 g/m²): in-plane
/// stiffness E·t = 500 N/m, bending rigidity 5e-6 N·m (≈ 0.05 gf·cm²/cm in Kawabata units).
struct Material {
  double youngs_modulus = 1.0e6;    ///< Pa
  double poisson_ratio = 0.3;       ///< in [0, 0.5)
  double thickness = 5.0e-4;        ///< m
  double density = 300.0;           ///< kg/m³ (areal density = density · thickness)
  double bending_stiffness = 5e-6;  ///< N·m
  MembraneModel membrane = MembraneModel::StVK;
  BendingModel bending = BendingModel::Quadratic;
  /// Projective Dynamics form only (PDStrainMembrane): the range the strain constraint clamps the deformation
  /// gradient's singular values to (Bouaziz et al. 2014 §5); [1, 1] is as-rigid-as-possible.
  double pd_strain_min = 1.0;
  double pd_strain_max = 1.0;

  double areal_density() const { return density * thickness; }
  /// Plane-stress Lamé parameters of the membrane (per unit volume; multiplied by thickness in the energy).
  double mu() const { return youngs_modulus / (2.0 * (1.0 + poisson_ratio)); }
  double lambda_plane_stress() const {
    return youngs_modulus * poisson_ratio / (1.0 - poisson_ratio * poisson_ratio);
  }
};

std::string to_string(MembraneModel m);
std::string to_string(BendingModel m);

}  // namespace mgcloth::physics
