#pragma once
#include <string>
#include <vector>

namespace mgcloth::physics {

/// Which form of the cloth energy a scene's step objective takes (the scene's "energy_form"): the elastic one (StVK
/// or mass-spring membrane, the material's bending model, the cubic contact penalty), or the Projective Dynamics one
/// (Liu 2013, Bouaziz 2014: strain constraints, quadratic bending and contact constraints, physics/projective.hpp),
/// whose Hessian is the constant PD matrix. Their energies are not comparable with each other.
enum class EnergyForm { Elastic, Projective };

inline std::string energy_form_name(EnergyForm form) { return form == EnergyForm::Projective ? "projective" : "elastic"; }
inline std::vector<std::string> energy_form_names() { return {"elastic", "projective"}; }
/// The form of a name from energy_form_names() (anything else is the elastic form: names are validated on parsing).
inline EnergyForm energy_form_of(const std::string& name) {
  return name == "projective" ? EnergyForm::Projective : EnergyForm::Elastic;
}

}  // namespace mgcloth::physics
