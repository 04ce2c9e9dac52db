#pragma once
#include <mgcloth/geometry/sdf_kernels.hpp>
#include <mgcloth/linalg/stencil_table.hpp>
#include <mgcloth/linalg/block_matrix.hpp>
#include <mgcloth/physics/objective.hpp>

#include <string>
#include <vector>

namespace mgcloth::cuda {

/// A scalar CSR table (prolongation rows, or their transpose) in flat arrays.
struct CsrTable {
  std::vector<Index> offsets, indices;
  std::vector<double> weights;
};

/// One level of the device hierarchy, on the host, in the level's device numbering: vertices renumbered so that
/// every color of the level's block graph is a contiguous range of rows (a Gauss-Seidel color is then one launch
/// over consecutive rows).
struct LevelLayout {
  Index n = 0;                      ///< block rows (vertices)
  linalg::BlockMatrix3 pattern;     ///< BSR pattern of the level's matrix, device numbering
  std::vector<Index> color_offsets; ///< color c is rows [color_offsets[c], color_offsets[c+1])
  std::vector<Index> perm;          ///< device row r is vertex perm[r] of the level in the problem's numbering
  // To the next coarser level (empty on the coarsest): prolongation rows (fine device rows → coarse device rows),
  // its transpose (restriction), and the symbolic Galerkin map of every coarse block (Wang 2018 §3.1,
  // A_{l+1} = Pᵀ A_l P, one gather per coarse block).
  CsrTable P, Pt;
  std::vector<Index> rap_offsets, rap_blocks;
  std::vector<double> rap_weights;
};

/// Elements of one kind (triangles or hinges) with K vertices each, in device numbering, grouped by color so that no
/// two elements of one color share a vertex: assembly writes its blocks and gradient entries without atomics.
struct ElementGroup {
  int arity = 0;
  std::vector<Index> vertices;      ///< arity per element, element order = color order
  std::vector<Index> color_offsets; ///< color c is elements [color_offsets[c], color_offsets[c+1])
  std::vector<Index> slots;         ///< arity² block positions per element in the level-0 pattern (row-major a, b)
  std::vector<Index> source;        ///< the element's index in its CPU term
  Index size() const { return arity ? static_cast<Index>(vertices.size()) / arity : 0; }
};

/// The triangle-cloth objective (Wang 2018 eq. 2) as flat arrays for the device pipeline: inertia, gravity, StVK
/// membrane, any of the bending models, attachments and the cubic obstacle penalty; the same terms and element
/// math (physics/element_kernels.hpp) as the CPU physics::Objective it is built from.
struct ObjectiveLayout {
  Index n = 0;
  std::vector<double> mass;  ///< inertia and gravity (lumped masses)
  double gravity[3] = {0.0, 0.0, 0.0};
  bool has_gravity = false;
  // Membrane (StVK): Dm⁻¹ row-major (4 per triangle) and area·thickness.
  ElementGroup tris;
  std::vector<double> tri_dm_inv, tri_at;
  double mu = 0.0, lambda = 0.0;
  // Hinge bending: weights c per hinge; Bergou's quadratic bending also the cotangent weights K (4 per hinge).
  ElementGroup hinges;
  bool quadratic_bending = false;
  std::vector<double> hinge_c, hinge_k;
  // Consistent quadratic bending (physics::IsometricBending): its scalar matrix K by device rows with the level-0
  // block of every entry (gradient K x and Hessian K ⊗ I₃ row by row, no races), and each triangle's curvature
  // weights (S_xx, S_xy, S_yy per vertex) with k_b·A_T, for the energy as a sum of squares as on the CPU.
  bool isometric_bending = false;
  std::vector<Index> bend_offsets, bend_cols, bend_slots;
  std::vector<double> bend_values;
  std::vector<Index> curv_offsets, curv_vertices;
  std::vector<double> curv_weights, curv_kb_area;
  // Pins, grouped by vertex (several pins may share one): pin_offsets[i]..pin_offsets[i+1] are vertex i's.
  std::vector<Index> pin_offsets;
  std::vector<double> pin_k;
  std::vector<Index> pin_source;  ///< the pin's index in the AttachmentTerm (for its target each step)
  // Obstacle contact: k_i = stiffness · A_i per vertex (empty: no contact term), thickness d.
  std::vector<double> contact_k;
  double thickness = 0.0;
};

/// What changes from one time step to the next: the inertial prediction, the pin targets and the obstacle poses.
struct StepData {
  std::vector<double> y;         ///< device numbering
  double inv_h2 = 0.0;
  std::vector<double> targets;   ///< 3 per pin, in pin_offsets order
  std::vector<hd::ObstacleData> obstacles;
};

/// The device numbering and arrays of a problem: its objective and the hierarchy of prolongations (finest first).
struct Layout {
  ObjectiveLayout objective;
  std::vector<LevelLayout> levels;  ///< finest first
};

/// A scalar CSR matrix (32-bit indices, as cuSPARSE takes them): the form in which a general sparse library sees the
/// hierarchy, for the comparison of the Galerkin gather with a general SpGEMM (FmgSettings::compare_spgemm).
struct ScalarCsr {
  int rows = 0, cols = 0;
  std::vector<int> offsets, indices;
  std::vector<double> values;
};
/// The BSR matrix with the given row-major 3x3 blocks, entry by entry.
ScalarCsr expand_blocks(const linalg::BlockMatrix3& pattern, const std::vector<double>& blocks);
/// The vertex table (rows × cols weights) as the 3rows × 3cols matrix table ⊗ I₃.
ScalarCsr expand_table(const CsrTable& table, Index cols);
/// max |C − A| over C's entries and A's blocks, relative to max |A|: how far a general SpGEMM's Pᵀ A P (C, scalar)
/// is from the gather's (A, blocks in `pattern`). Entries of C outside the pattern count in full.
double relative_difference(const ScalarCsr& C, const linalg::BlockMatrix3& pattern, const std::vector<double>& blocks);

/// Builds the layout of `objective` (which must be finalized) and its hierarchy. Throws InputError naming a term
/// that the device pipeline does not implement (seams, mass-spring membrane, Projective Dynamics terms).
Layout build_layout(const physics::Objective& objective, const std::vector<const linalg::StencilTable*>& prolongations);

/// The objective's current step data in the layout's numbering.
StepData step_data(const physics::Objective& objective, const Layout& layout);

/// x in the problem's numbering (3n, xyz interleaved) ↔ the device numbering of level 0.
void to_device_order(const Layout& layout, const VecX& x, std::vector<double>& out);
void from_device_order(const Layout& layout, const std::vector<double>& in, VecX& x);

}  // namespace mgcloth::cuda
