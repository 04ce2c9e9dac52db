#pragma once
#include <mgcloth/core/types.hpp>
#include <mgcloth/geometry/obstacle.hpp>

#include <filesystem>
#include <vector>

namespace mgcloth::sim {

/// The deformable surfaces of a run (all cloths, then every shell's display surface, merged as in the OBJ frames)
/// at each written frame.
struct SurfaceAnimation {
  std::vector<Tri> tris;
  Mat2X uv;                      ///< per vertex, in the OBJ frames' vt units; empty: no TEXCOORD_0
  Index num_vertices = 0;
  std::vector<double> times;     ///< simulated time of each frame, s, strictly increasing
  std::vector<int> frame_numbers;  ///< the simulation frame of each frame (names the morph targets); empty: 0, 1, …
  std::vector<float> positions;  ///< frame-major: vertex i of frame k at [3 (k·num_vertices + i)], world, m
  Index num_frames() const { return static_cast<Index>(times.size()); }
};

/// Writes one binary glTF 2.0 file (atomically) holding the whole animation:
/// - the surface as one mesh whose base positions are frame 0 and whose morph target k−1 holds the POSITION
///   offsets of frame k, driven by a "weights" channel with STEP interpolation (frame k: weight 1 on target k−1,
///   0 elsewhere), which three.js and Blender import as morph targets / shape keys;
/// - every obstacle as a node with its shape tessellated in the local frame (a plane as a finite quad sized to
///   cover the surface), with translation and rotation channels sampled at the frame times when it moves.
/// Everything sits under one root node that turns mgcloth's z-up world into glTF's y-up, so the file's vertex
/// data and channels are in simulation coordinates. Throws Error when the animation is empty or inconsistent, or
/// when the file would exceed the 4 GiB a .glb can address.
void write_glb(const std::filesystem::path& path, const SurfaceAnimation& surface,
               const std::vector<geometry::Obstacle>& obstacles);

/// Whether this build can write glb (it was configured with tinygltf); without it write_glb throws Error.
bool glb_available();

}  // namespace mgcloth::sim
