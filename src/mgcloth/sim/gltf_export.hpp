#pragma once
#include <mgcloth/core/types.hpp>
#include <mgcloth/geometry/obstacle.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
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
  /// Frame-major: vertex i of frame k at [3 (k·num_vertices + i)], world, m. Unused (may be empty) when
  /// write_glb reads the frames through a FrameReader.
  std::vector<float> positions;
  Index num_frames() const { return static_cast<Index>(times.size()); }
};

/// Puts the 3 num_vertices positions of frame k into `out`; write_glb reads each frame twice, in order.
using FrameReader = std::function<void(size_t k, float* out)>;

/// The binary data a .glb holds at most: its chunks have 32-bit lengths, and 64 MiB are left for its JSON (about
/// 200 bytes per frame).
inline constexpr std::uint64_t kGlbMaxBinaryBytes = 0xFFFFFFFFull - (64ull << 20);

/// The bytes of binary data that write_glb writes for `frames` frames of a surface of `vertices` vertices and
/// `triangles` triangles (with texture coordinates when `uv`) and `obstacles`, counting the channels of every
/// obstacle with a motion (so at most that when one does not move): 12 bytes per vertex and frame for the morph
/// targets of the surface and of every mesh sequence obstacle, 4 · frames · (frames − 1) for their weights (which
/// they share), 4 per key value of a skinned obstacle's tracks (a key per frame when it loops), and the rest, which
/// does not grow with the frames.
std::uint64_t glb_binary_bytes(std::uint64_t vertices, std::uint64_t triangles, bool uv, std::uint64_t frames,
                               const std::vector<geometry::Obstacle>& obstacles);

/// Writes one binary glTF 2.0 file (atomically) holding the whole animation:
/// - the surface as one mesh whose base positions are frame 0 and whose morph target k−1 holds the POSITION
///   offsets of frame k, driven by a "weights" channel with STEP interpolation (frame k: weight 1 on target k−1,
///   0 elsewhere), which three.js and Blender import as morph targets / shape keys;
/// - every obstacle as a node with its shape tessellated in the local frame (a plane as a finite quad sized to
///   cover the surface), with translation and rotation channels sampled at the frame times when it moves;
/// - a mesh obstacle as its mesh on that node: a sequence (TriangleSurface::frames) with a morph target per frame
///   after the first like the surface's, driven by the same weights; a skinned mesh (TriangleSurface::skin) as a
///   glTF skin whose joints hang from the node (through a node holding its placement), with its tracks as channels
///   at their own keys and interpolation (sampled at the frame times, STEP, when the surface loops), and its mesh's
///   node at the top of the scene, untransformed, as glTF skinning wants.
/// Everything but skinned meshes' nodes sits under one root node that turns mgcloth's z-up world into glTF's y-up, so
/// the file's vertex data and channels are in simulation coordinates (a skinned mesh's vertex data is its bind pose
/// as the file shows it). Throws Error when the animation is empty or inconsistent, when
/// a skinned obstacle's skin does not validate, or when the file would exceed the 4 GiB a .glb can address.
void write_glb(const std::filesystem::path& path, const SurfaceAnimation& surface,
               const std::vector<geometry::Obstacle>& obstacles);
/// The same file from frames read one at a time through `read` (surface.positions unused), so that memory holds a
/// few frames, not the animation: the morph targets and their weights are written to the file as they are made.
void write_glb(const std::filesystem::path& path, const SurfaceAnimation& surface, const FrameReader& read,
               const std::vector<geometry::Obstacle>& obstacles);

/// Whether this build can write glb (it was configured with tinygltf); without it write_glb throws Error.
bool glb_available();

}  // namespace mgcloth::sim
