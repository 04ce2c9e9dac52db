#pragma once
#include <mgcloth/physics/element_term.hpp>

namespace mgcloth::physics {

/// Stitched seams of a garment as stiff zero-length springs: E = Σ_(i,j) k/2 |x_i − x_j|² over the stitched pairs.
/// A panel's vertices keep their own material coordinates (the two sides of a seam may have different rest
/// lengths, as sewing patterns with ease do), so a seam cannot be one shared vertex; the springs hold it closed
/// to within |force| / k.
class SeamTerm final : public ElementTerm<2> {
 public:
  /// `groups`: the stitch groups (Topology::stitch_groups); each member is tied to the group's first vertex.
  /// `stiffness` in N/m, positive.
  SeamTerm(const std::vector<std::vector<Index>>& groups, double stiffness, Index num_vertices);
  std::string name() const override { return "seam"; }
  double element(Index e, const Local& xe, Local* g, LocalHessian* H) const override;
  double stiffness() const { return m_stiffness; }

 private:
  double m_stiffness;
};

}  // namespace mgcloth::physics
