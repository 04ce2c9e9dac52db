#pragma once
#include <mgcloth/sim/simulator.hpp>

#include <filesystem>

namespace mgcloth::sim {

/// Writes a run to its output folder: frame_NNNNN.obj (format "obj": all cloths, then the limit surface of every
/// shell sampled for display; world positions with the material vt), animation.glb (format "glb", see finish()),
/// probes.csv for shells with probes, stats.csv (one row per step and cloth), scene.resolved.json (every default
/// filled in), surfaces.json (which vertices and triangles of the frames belong to which body: a list of
/// {"name", "vertices": [first, count], "triangles": [first, count]}, so that a viewer or script can tell the
/// cloths apart), with format "obj" and mesh obstacles obstacles.json (their triangles, once) and
/// obstacles_NNNNN.bin (their posed vertices in each written frame, float32; see write_obstacle_frame) and
/// checkpoint.bin (sim::Checkpoint after the last complete frame). Every file is written
/// atomically, so an interrupted run leaves only complete files, and `resume()` continues it from its last
/// checkpoint. The one exception is frames.bin, the glb format's record of the frames so far: it is only appended
/// to (a long run must not rewrite every earlier frame each frame), and resume() cuts it back to the checkpoint.
class Recorder {
 public:
  /// With `trace`, also trace.csv: one row per solver iteration (frame, step, cloth, iteration, energy,
  /// gradient norm, wall time, line-search step).
  Recorder(std::filesystem::path dir, const Simulator& sim, bool trace = false);

  const std::filesystem::path& dir() const { return m_dir; }
  /// Starts a fresh run: writes the resolved scene and frame 0.
  void start(const Simulator& sim);
  /// Loads checkpoint.bin into the simulator and keeps the stats rows up to it. Throws InputError, before
  /// changing anything in the folder, when it has no checkpoint, a damaged one (decode_checkpoint) or one written
  /// for a different scene.
  void resume(Simulator& sim);
  /// Records the stats of the steps of a frame, then the frame (when due) and the checkpoint.
  void record_frame(const Simulator& sim, const std::vector<StepStats>& stats);
  /// Ends recording (after the last frame, or when a run stops early): with the glb format, writes animation.glb
  /// from every frame recorded so far in frames.bin, read from there a frame at a time (write_glb in
  /// gltf_export.hpp). Calling it again rewrites it.
  void finish(const Simulator& sim);

  static std::string stats_header();
  static std::string stats_row(const StepStats& s);
  static std::filesystem::path frame_path(const std::filesystem::path& dir, int frame);
  /// obstacles_NNNNN.bin: the mesh obstacles' vertices at frame `frame` (written with frame_path's OBJ).
  static std::filesystem::path obstacle_frame_path(const std::filesystem::path& dir, int frame);

 private:
  /// With the glb format: InputError when the scene's frames would not fit in a .glb (glb_binary_bytes), so that
  /// a run is refused before it starts rather than after it ends.
  void check_glb_size(const Simulator& sim) const;
  /// Positions of m_combined's vertices: every cloth, then every shell's display surface.
  Mat3X surface_positions(const Simulator& sim) const;
  /// scene.resolved.json and surfaces.json: what the run is, written by start() and again by resume().
  void write_description(const Simulator& sim) const;
  void write_frame(const Simulator& sim) const;
  /// obstacles.json: per mesh obstacle (in scene order) its name, its index in the scene's obstacles, its range
  /// of the vertices of the obstacle frames, its number of triangles and their vertex indices (3 each, into its
  /// own vertices).
  nlohmann::ordered_json obstacle_meshes(const Simulator& sim) const;
  /// obstacles_NNNNN.bin: the world positions of every mesh obstacle's vertices at the simulator's time, meshes
  /// in obstacles.json's order, as little-endian float32 x, y, z per vertex and nothing else.
  void write_obstacle_frame(const Simulator& sim) const;
  /// frames.bin: a header (magic, scene fingerprint, vertex count), then per written frame its number, its time
  /// and the float32 positions of m_combined's vertices.
  void reset_frames_file() const;
  void append_frame(int frame, double time, const Mat3X& x) const;
  /// Keeps the frames up to `frame` (the checkpoint's); returns the last one kept, −1 when none (or no valid file).
  long truncate_frames_file(int frame) const;
  std::size_t frame_record_bytes() const;
  void write_checkpoint(const Simulator& sim) const;
  void write_logs() const;

  std::filesystem::path m_dir;
  std::uint64_t m_fingerprint = 0;
  mesh::TriMesh m_combined;  ///< all cloths in one mesh for frame files (vt in each cloth's UV units)
  Json m_surfaces;           ///< surfaces.json: each body's range of m_combined's vertices and triangles
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
  bool m_write_obj = false, m_write_glb = false;  ///< output.format
  std::vector<size_t> m_mesh_obstacles;  ///< indices into sim.obstacles() of the mesh obstacles
  Index m_obstacle_vertices = 0;         ///< their vertices, all together
};

/// FNV-1a hash of the physical content of a scene (everything but frame count and output settings), so that a
/// checkpoint is only resumed by the scene that wrote it.
std::uint64_t scene_fingerprint(const Scene& scene);

}  // namespace mgcloth::sim
