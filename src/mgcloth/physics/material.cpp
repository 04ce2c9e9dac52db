#include <mgcloth/physics/material.hpp>

namespace mgcloth::physics {
std::string to_string(MembraneModel m) { return m == MembraneModel::StVK ? "stvk" : "mass_spring"; }
std::string to_string(BendingModel m) {
  switch (m) {
    case BendingModel::Hinge: return "hinge";
    case BendingModel::Quadratic: return "quadratic";
    case BendingModel::QuadraticBergou: return "quadratic-bergou";
    default: return "none";
  }
}
}  // namespace mgcloth::physics
