#pragma once
#include <mgcloth/mesh/quad_mesh.hpp>

#include <opensubdiv/far/topologyRefiner.h>

#include <memory>

namespace mgcloth::mesh {

using TopologyRefinerPtr = std::unique_ptr<OpenSubdiv::Far::TopologyRefiner>;

/// An OpenSubdiv topology refiner for the control mesh: Catmull-Clark, boundary vertices smoothed by the curve
/// rule of Kopaničáková 2019 App. A (eq. A.2, corners included: VTX_BOUNDARY_EDGE_ONLY), no creases. Throws
/// InputError when OpenSubdiv rejects the topology (e.g. a non-manifold edge).
TopologyRefinerPtr make_topology_refiner(const QuadMesh& mesh);

}  // namespace mgcloth::mesh
