#pragma once
#include <mgcloth/sim/simulator.hpp>

#include <filesystem>

namespace mgcloth::sim {

/// Writes a run to its output folder: frame_NNNNN.obj (all cloths, then the limit surface of every shell sampled
/// for display; world positions with the material vt), probes.csv for shells with probes,
/// stats.csv (one row per step and cloth), scene.resolved.json (every default filled in) and checkpoint.bin
/// (x and v of every cloth after the last complete frame). Every file is written atomically, so an interrupted run
/// leaves only complete files, and `resume()` continues it from its last checkpoint.
class Recorder {
 public:
  /// With `trace`, also trace.csv: one row per solver iteration (frame, step, cloth, iteration, energy,
  /// gradient norm, wall time, line-search step).
  Recorder(std::filesystem::path dir, const Simulator& sim, bool trace = false);

  const std::filesystem::path& dir() const { return m_dir; }
  /// Starts a fresh run: writes the resolved scene and frame 0.
  void start(const Simulator& sim);
  /// Loads checkpoint.bin into the simulator and keeps the stats rows up to it. Throws InputError when the folder
  /// has no checkpoint or one written for a different scene.
  void resume(Simulator& sim);
  /// Records the stats of the steps of a frame, then the frame (when due) and the checkpoint.
  void record_frame(const Simulator& sim, const std::vector<StepStats>& stats);

  static std::string stats_header();
  static std::string stats_row(const StepStats& s);
  static std::filesystem::path frame_path(const std::filesystem::path& dir, int frame);

 private:
  void write_frame(const Simulator& sim) const;
  void write_checkpoint(const Simulator& sim) const;
  void write_logs() const;

  std::filesystem::path m_dir;
  std::uint64_t m_fingerprint = 0;
  mesh::TriMesh m_combined;  ///< all cloths in one mesh for frame files (vt in each cloth's UV units)
  /// A CSV file kept in memory and rewritten atomically, so that it always matches the checkpoint.
  struct CsvLog {
    std::string name, header;
    int step_column = 1;  ///< which column holds the step (rows past the checkpoint's step are dropped on resume)
    std::vector<std::string> rows;
    void load_up_to_step(const std::filesystem::path& dir, long step);
    void write(const std::filesystem::path& dir) const;
  };
  CsvLog m_stats, m_trace, m_probes;
  bool m_record_probes = false;
  bool m_record_trace;
};

/// FNV-1a hash of the physical content of a scene (everything but frame count and output settings), so that a
/// checkpoint is only resumed by the scene that wrote it.
std::uint64_t scene_fingerprint(const Scene& scene);

}  // namespace mgcloth::sim
