#pragma once
#include <mgcloth/core/types.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace mgcloth::sim {

/// The state a run continues from (`checkpoint.bin`, written by sim::Recorder after every frame).
struct Checkpoint {
  /// What one body (a cloth or a shell) needs to take its next step as the uninterrupted run would.
  struct Body {
    VecX x, v;
    /// What the body's solver carries from one step into the next (Simulator::solver_state), opaque here;
    /// empty when it carries nothing.
    std::string solver_state;
  };
  std::uint64_t fingerprint = 0;  ///< scene_fingerprint() of the scene that wrote it
  std::int64_t frame = 0, step = 0;
  std::vector<Body> bodies;  ///< every cloth, then every shell, in scene order
};

/// The format version that encode_checkpoint writes and decode_checkpoint reads: 01 had no checksum, 02 no
/// solver state.
inline constexpr int kCheckpointVersion = 3;

/// checkpoint.bin, version 03, in the host's byte order: "MGCKPT03"; fingerprint (u64), frame, step and body count
/// (i64); per body: its dof count n (i64), x and v (n doubles each), the length of its solver state (i64) and its
/// bytes; then the 64-bit FNV-1a hash of everything before it.
std::string encode_checkpoint(const Checkpoint& checkpoint);
/// Reads what encode_checkpoint wrote. Throws InputError naming `file` and what is wrong: not a checkpoint, a
/// format version this mgcloth does not read, a checksum mismatch (a damaged or truncated file), or sizes that do
/// not add up. Never reads or allocates past `bytes`.
Checkpoint decode_checkpoint(std::string_view bytes, const std::filesystem::path& file);

/// 64-bit FNV-1a: the checkpoint's checksum and the scene fingerprint.
std::uint64_t fnv1a(std::string_view bytes);

}  // namespace mgcloth::sim
