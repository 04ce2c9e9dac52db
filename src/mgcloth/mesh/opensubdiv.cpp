#include <mgcloth/core/error.hpp>
#include <mgcloth/mesh/opensubdiv.hpp>

#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

namespace mgcloth::mesh {

TopologyRefinerPtr make_topology_refiner(const QuadMesh& mesh) {
  using namespace OpenSubdiv;
  std::vector<int> sizes(mesh.quads.size(), 4);
  std::vector<int> indices;
  indices.reserve(4 * mesh.quads.size());
  for (const Quad& q : mesh.quads)
    for (Index v : q) indices.push_back(v);
  Far::TopologyDescriptor desc;
  desc.numVertices = mesh.num_vertices();
  desc.numFaces = mesh.num_faces();
  desc.numVertsPerFace = sizes.data();
  desc.vertIndicesPerFace = indices.data();
  Sdc::Options sdc;
  sdc.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_ONLY);
  sdc.SetFVarLinearInterpolation(Sdc::Options::FVAR_LINEAR_ALL);
  using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
  Factory::Options options(Sdc::SCHEME_CATMARK, sdc);
  options.validateFullTopology = true;
  Far::TopologyRefiner* refiner = Factory::Create(desc, options);
  if (!refiner) throw_input_error("OpenSubdiv rejected the quad control mesh ({} points, {} quads): invalid topology",
                                  mesh.num_vertices(), mesh.num_faces());
  return TopologyRefinerPtr(refiner);
}

}  // namespace mgcloth::mesh
