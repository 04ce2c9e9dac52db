#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/log.hpp>
#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/sim/checkpoint.hpp>
#include <mgcloth/sim/gltf_export.hpp>
#include <mgcloth/sim/recorder.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

namespace mgcloth::sim {

namespace fs = std::filesystem;

namespace {
constexpr char kFramesMagic[8] = {'M', 'G', 'F', 'R', 'A', 'M', '0', '1'};
constexpr std::size_t kFramesHeaderBytes = sizeof(kFramesMagic) + sizeof(std::uint64_t) + sizeof(std::int64_t);
constexpr const char* kFramesFile = "frames.bin";
constexpr const char* kGlbFile = "animation.glb";
constexpr const char* kCheckpointFile = "checkpoint.bin";
constexpr const char* kSurfacesFile = "surfaces.json";
constexpr const char* kObstaclesFile = "obstacles.json";

template <class T>
void put(std::ostream& o, const T& v) {
  o.write(reinterpret_cast<const char*>(&v), sizeof(T));
}
/// frame_NNNNN.obj
bool is_frame_file(const std::string& name) {
  return name.size() == 15 && name.rfind("frame_", 0) == 0 && name.compare(11, 4, ".obj") == 0;
}
/// obstacles_NNNNN.bin
bool is_obstacle_frame_file(const std::string& name) {
  return name.size() == 19 && name.rfind("obstacles_", 0) == 0 && name.compare(15, 4, ".bin") == 0 &&
         name.find_first_not_of("0123456789", 10) == 15;
}
/// Whether a run writes a file of this name into its folder (so that a temporary for it is one of ours).
bool is_run_output(const std::string& name) {
  for (const char* own : {kCheckpointFile, kFramesFile, kGlbFile, "stats.csv", "trace.csv", "probes.csv", "scene.resolved.json",
                          kSurfacesFile, kObstaclesFile})
    if (name == own) return true;
  return is_frame_file(name) || is_obstacle_frame_file(name);
}
/// Temporaries of the atomic writes of a run that was killed, or that failed on a full disk before the temporaries
/// were removed on failure, would otherwise stay in the folder for good.
void remove_stale_temporaries(const fs::path& dir) {
  for (const auto& file : remove_atomic_temporaries(dir, is_run_output))
    logger().debug("removed {}, left by an earlier run", file.string());
}
}  // namespace

std::uint64_t scene_fingerprint(const Scene& scene) {
  Json j = to_json(scene);
  j.erase("frames");
  j.erase("output");
  j.erase("threads");
  // Off, the velocity tolerances stop solves as every run before the keys existed did: their checkpoints resume.
  for (const char* key : {"velocity_tol", "velocity_rms_tol"})
    if (j["solver"][key] == 0.0) j["solver"].erase(key);
  // Likewise the smoother's double precision, the only one before the key existed.
  if (Json& p = j["solver"]["params"]; p.is_object() && p.value("smoother_precision", "") == "double") p.erase("smoother_precision");
  // The scene names an obstacle mesh by its file: what the file holds is part of the scene too, so that a run does
  // not resume with an edited mesh.
  std::string meshes;
  for (const auto& o : scene.obstacles) {
    if (!o.surface) continue;
    const auto& s = *o.surface;
    const auto add = [&](const void* data, size_t bytes) { meshes.append(static_cast<const char*>(data), bytes); };
    add(s.vertices.data(), sizeof(double) * static_cast<size_t>(s.vertices.size()));
    for (const Mat3X& f : s.frames) add(f.data(), sizeof(double) * static_cast<size_t>(f.size()));
    add(s.tris.data(), sizeof(Tri) * s.tris.size());
    if (const auto& k = s.skin) {
      add(k->rest.data(), sizeof(double) * static_cast<size_t>(k->rest.size()));
      add(k->weights.data(), sizeof(double) * static_cast<size_t>(k->weights.size()));
      add(k->joints.data(), sizeof(int) * static_cast<size_t>(k->joints.size()));
      add(k->placement.data(), sizeof(double) * 16);
      for (size_t j = 0; j < k->tracks.size(); ++j) {
        const auto& t = k->tracks[j];
        const auto& r = k->rest_local[j];
        add(r.translation.data(), sizeof(double) * 3);
        add(r.rotation.coeffs().data(), sizeof(double) * 4);
        add(r.scale.data(), sizeof(double) * 3);
        add(k->inverse_bind[j].data(), sizeof(double) * 16);
        add(t.translation.times.data(), sizeof(double) * t.translation.times.size());
        add(t.translation.values.data(), sizeof(Vec3) * t.translation.values.size());
        add(t.rotation.times.data(), sizeof(double) * t.rotation.times.size());
        add(t.rotation.values.data(), sizeof(Eigen::Vector4d) * t.rotation.values.size());
        add(t.scale.times.data(), sizeof(double) * t.scale.times.size());
        add(t.scale.values.data(), sizeof(Vec3) * t.scale.values.size());
      }
    }
  }
  // Likewise a cloth's OBJ file or sewing pattern.
  for (const auto& c : scene.cloths)
    for (const std::string& file : {c.mesh.file, c.mesh.pattern})
      if (!file.empty()) meshes += read_file(file);
  return fnv1a(j.dump() + meshes);
}

Recorder::Recorder(fs::path dir, const Simulator& sim, bool trace)
    : m_dir(std::move(dir)), m_fingerprint(scene_fingerprint(sim.scene())), m_record_trace(trace) {
  const auto& formats = sim.scene().output.formats;
  m_write_obj = std::find(formats.begin(), formats.end(), "obj") != formats.end();
  m_write_glb = std::find(formats.begin(), formats.end(), "glb") != formats.end();
  // Refused before the run rather than after it, when animation.glb would be written.
  if (m_write_glb && !glb_available())
    throw InputError(fmt::format("{}: output.format: \"glb\" is not available in this build (configured without "
                                 "libtinygltf-dev; install it and re-run cmake)", sim.scene().file));
  m_stats.name = "stats.csv";
  m_stats.header = stats_header();
  m_trace.name = "trace.csv";
  m_trace.header = "frame,step,cloth,iteration,energy,grad_norm,wall_ms,alpha";
  Index offset = 0;
  std::vector<Vec2> u;
  m_surfaces = Json::array();
  for (const auto& body : sim.bodies()) {
    const auto& m = body->surface_mesh();
    const Mat2X uv = body->surface_uv();
    m_surfaces.push_back({{"name", body->name()},
                          {"vertices", {offset, m.num_vertices()}},
                          {"triangles", {static_cast<Index>(m_combined.tris.size()), m.num_triangles()}}});
    for (Index i = 0; i < m.num_vertices(); ++i) u.push_back(uv.col(i));
    for (const auto& t : m.tris) m_combined.tris.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
    offset += m.num_vertices();
    m_record_probes = m_record_probes || body->num_probes() > 0;
  }
  m_probes.name = "probes.csv";
  m_probes.header = "step,load_factor,probe,x,y,z,ux,uy,uz";
  m_probes.step_column = 0;
  m_combined.u.resize(2, offset);
  for (Index i = 0; i < offset; ++i) m_combined.u.col(i) = u[i];
  m_combined.x = Mat3X::Zero(3, offset);
  // The OBJ frames hold the cloths only; the mesh obstacles (a walking body, a sequence, a skin, an OBJ file) get
  // frames of their own beside them (obstacles_NNNNN.bin), for the viewer.
  if (m_write_obj) {
    for (size_t o = 0; o < sim.obstacles().size(); ++o) {
      if (!sim.obstacles()[o].mesh) continue;
      m_mesh_obstacles.push_back(o);
      m_obstacle_vertices += static_cast<Index>(sim.obstacles()[o].mesh->vertices.cols());
    }
  }
  if (m_write_glb) check_glb_size(sim);
}

void Recorder::check_glb_size(const Simulator& sim) const {
  const Scene& scene = sim.scene();
  const std::uint64_t n = static_cast<std::uint64_t>(m_combined.u.cols()), tris = m_combined.tris.size();
  const auto bytes = [&](std::uint64_t frames) { return glb_binary_bytes(n, tris, true, frames, sim.obstacles()); };
  const std::uint64_t frames = static_cast<std::uint64_t>(scene.frames / scene.output.every) + 1;
  if (bytes(frames) <= kGlbMaxBinaryBytes) return;
  std::uint64_t fit = 0, too_many = frames;
  while (too_many - fit > 1) {
    const std::uint64_t mid = fit + (too_many - fit) / 2;
    (bytes(mid) <= kGlbMaxBinaryBytes ? fit : too_many) = mid;
  }
  const std::string advice =
      fit >= 2 ? fmt::format("at most {} frames fit: set output.every to {} or more, or write fewer frames", fit,
                             (static_cast<std::uint64_t>(scene.frames) + fit - 2) / (fit - 1))
               : std::string("the surface is too large for a .glb at all; write the obj format instead");
  constexpr double kGiB = 1u << 30;
  throw InputError(fmt::format(
      "{}: output.format \"glb\": {} frames of {} vertices (frames {} / output.every {}, plus frame 0) need {:.2f} GiB "
      "of data in animation.glb ({:.2f} GiB of morph targets, 12 bytes per vertex and frame, and {:.2f} GiB of "
      "their weights, 4 bytes per frame squared), more than the {:.2f} GiB a .glb can hold (4 GiB with its JSON); {}",
      scene.file, frames, n, scene.frames, scene.output.every, static_cast<double>(bytes(frames)) / kGiB,
      static_cast<double>(12 * n * (frames - 1)) / kGiB, static_cast<double>(4 * frames * (frames - 1)) / kGiB,
      static_cast<double>(kGlbMaxBinaryBytes) / kGiB, advice));
}

std::string Recorder::stats_header() {
  return "frame,step,sim_time,solver,iterations,energy,grad_norm,wall_ms,cloth,rel_grad,status,solve_ms,projected,"
         "contact_pairs,min_distance,intersections,contact_detection_ms,check_ms,obstacle_rounds,seam_gap,velocity_error,"
         "velocity_rms_error,true_velocity_error,true_velocity_rms";
}

std::string Recorder::stats_row(const StepStats& s) {
  const auto& r = s.report;
  // Without cloth contact its columns stay empty (not zero, which would claim a check that did not run).
  const std::string pairs = s.contact_pairs >= 0 ? std::to_string(s.contact_pairs) : "";
  const std::string dmin = std::isnan(s.min_distance) ? "" : fmt::format("{:.6g}", s.min_distance);
  const std::string crossings = s.intersections >= 0 ? std::to_string(s.intersections) : "";
  const auto ms = [](double v) { return std::isnan(v) ? std::string() : fmt::format("{:.3f}", v); };
  const std::string gap = std::isnan(s.seam_gap) ? "" : fmt::format("{:.6g}", s.seam_gap);
  // Infinite where no estimate was possible (fewer than three moving iterations, steps that did not contract).
  const std::string verr = std::isnan(s.velocity_error) ? "" : fmt::format("{:.3e}", s.velocity_error);
  const auto checked = [](double v) { return std::isnan(v) ? std::string() : fmt::format("{:.3e}", v); };
  return fmt::format("{},{},{:.9g},{},{},{:.17g},{:.9g},{:.3f},{},{:.3e},{},{:.3f},{},{},{},{},{},{},{},{},{},{},{},{}", s.frame, s.step,
                     s.sim_time, s.solver, r.iterations, r.energy, r.grad_norm, s.wall_ms, s.body,
                     r.initial_grad_norm > 0 ? r.grad_norm / r.initial_grad_norm : 0.0, r.status, r.wall_ms, s.projected,
                     pairs, dmin, crossings, ms(s.contact_detection_ms), ms(s.check_ms), s.obstacle_rounds, gap, verr,
                     checked(s.velocity_rms_error), checked(s.true_velocity_error), checked(s.true_velocity_rms));
}

fs::path Recorder::frame_path(const fs::path& dir, int frame) { return dir / fmt::format("frame_{:05d}.obj", frame); }

fs::path Recorder::obstacle_frame_path(const fs::path& dir, int frame) {
  return dir / fmt::format("obstacles_{:05d}.bin", frame);
}

nlohmann::ordered_json Recorder::obstacle_meshes(const Simulator& sim) const {
  // In this key order (the indices last), so that the file reads well.
  auto meshes = nlohmann::ordered_json::array();
  Index first = 0;
  for (const size_t o : m_mesh_obstacles) {
    const auto& ob = sim.obstacles()[o];
    const Index n = static_cast<Index>(ob.mesh->vertices.cols());
    std::vector<Index> indices;
    indices.reserve(3 * ob.mesh->tris.size());
    for (const Tri& t : ob.mesh->tris) indices.insert(indices.end(), t.begin(), t.end());
    nlohmann::ordered_json m;
    m["name"] = ob.name;
    m["obstacle"] = o;
    m["vertices"] = {first, n};
    m["triangles"] = ob.mesh->tris.size();
    m["indices"] = indices;
    meshes.push_back(std::move(m));
    first += n;
  }
  nlohmann::ordered_json j;
  j["vertices"] = m_obstacle_vertices;
  j["meshes"] = std::move(meshes);
  return j;
}

void Recorder::write_description(const Simulator& sim) const {
  write_file_atomic(m_dir / "scene.resolved.json", to_json(sim.scene()).dump(2) + "\n");
  write_file_atomic(m_dir / kSurfacesFile, m_surfaces.dump(2) + "\n");
  if (!m_mesh_obstacles.empty()) write_file_atomic(m_dir / kObstaclesFile, obstacle_meshes(sim).dump() + "\n");
}

void Recorder::start(const Simulator& sim) {
  fs::create_directories(m_dir);
  write_description(sim);
  m_stats.rows.clear();
  m_trace.rows.clear();
  m_probes.rows.clear();
  // A fresh run in a folder with an older run must not leave stale frames behind that look like ours.
  for (const auto& entry : fs::directory_iterator(m_dir)) {
    const std::string name = entry.path().filename().string();
    if (is_frame_file(name) || is_obstacle_frame_file(name)) fs::remove(entry.path());
  }
  remove_stale_temporaries(m_dir);
  if (m_mesh_obstacles.empty()) fs::remove(m_dir / kObstaclesFile);
  fs::remove(m_dir / kGlbFile);
  fs::remove(m_dir / kFramesFile);
  if (m_write_glb) reset_frames_file();
  write_logs();
  write_frame(sim);
  write_checkpoint(sim);
}

Mat3X Recorder::surface_positions(const Simulator& sim) const {
  Mat3X x(3, m_combined.u.cols());
  Index offset = 0;
  for (const auto& body : sim.bodies()) {
    const Index n = body->surface_mesh().num_vertices();
    x.middleCols(offset, n) = body->surface_positions();
    offset += n;
  }
  return x;
}

void Recorder::write_frame(const Simulator& sim) const {
  if (sim.frame() % sim.scene().output.every != 0) return;
  const Mat3X x = surface_positions(sim);
  if (m_write_obj) mesh::write_obj(frame_path(m_dir, sim.frame()), m_combined, x, 1.0);
  if (m_write_obj) write_obstacle_frame(sim);
  if (m_write_glb) append_frame(sim.frame(), sim.time(), x);
}

void Recorder::write_obstacle_frame(const Simulator& sim) const {
  if (m_mesh_obstacles.empty()) return;
  static_assert(sizeof(float) == 4 && std::endian::native == std::endian::little, "obstacles_NNNNN.bin is little-endian float32");
  std::vector<float> x;
  x.reserve(3 * static_cast<size_t>(m_obstacle_vertices));
  for (const size_t o : m_mesh_obstacles) {
    // Where the cloth-contact term has the mesh at the end of the frame: its pose and shape at the frame's time.
    const auto& ob = sim.obstacles()[o];
    const VecX p = ob.mesh_positions(sim.time());
    if (p.size() != 3 * ob.mesh->vertices.cols())
      throw_error("obstacle \"{}\": {} vertices at t = {}, {} at the start", ob.name, p.size() / 3, sim.time(),
                  ob.mesh->vertices.cols());
    for (Index i = 0; i < p.size(); ++i) x.push_back(static_cast<float>(p[i]));
  }
  write_file_atomic(
      obstacle_frame_path(m_dir, sim.frame()),
      [&](std::ostream& o) { o.write(reinterpret_cast<const char*>(x.data()), static_cast<std::streamsize>(sizeof(float) * x.size())); },
      true);
}

std::size_t Recorder::frame_record_bytes() const {
  return sizeof(std::int64_t) + sizeof(double) + 3 * sizeof(float) * static_cast<std::size_t>(m_combined.u.cols());
}

void Recorder::reset_frames_file() const {
  write_file_atomic(
      m_dir / kFramesFile,
      [&](std::ostream& o) {
        o.write(kFramesMagic, sizeof(kFramesMagic));
        put(o, m_fingerprint);
        put<std::int64_t>(o, m_combined.u.cols());
      },
      true);
}

void Recorder::append_frame(int frame, double time, const Mat3X& x) const {
  const fs::path file = m_dir / kFramesFile;
  const Eigen::Matrix3Xf xf = x.cast<float>();
  std::ofstream o(file, std::ios::binary | std::ios::app);
  if (!o) throw_error("{}: cannot open for appending", file.string());
  put<std::int64_t>(o, frame);
  put(o, time);
  o.write(reinterpret_cast<const char*>(xf.data()), static_cast<std::streamsize>(sizeof(float) * xf.size()));
  o.flush();
  if (!o) throw_error("{}: write failed (disk full?)", file.string());
}

long Recorder::truncate_frames_file(int frame) const {
  const fs::path file = m_dir / kFramesFile;
  std::ifstream in(file, std::ios::binary);
  std::string problem;
  if (!in) {
    problem = "missing (the earlier run did not write the glb format)";
  } else {
    char magic[8];
    std::uint64_t fingerprint = 0;
    std::int64_t vertices = -1;
    in.read(magic, sizeof(magic));
    in.read(reinterpret_cast<char*>(&fingerprint), sizeof(fingerprint));
    in.read(reinterpret_cast<char*>(&vertices), sizeof(vertices));
    if (!in || !std::equal(magic, magic + 8, kFramesMagic) || fingerprint != m_fingerprint || vertices != m_combined.u.cols())
      problem = "not written by this scene";
  }
  if (!problem.empty()) {
    logger().warn("{}: {}; animation.glb will start at frame {}", file.string(), problem, frame);
    in.close();
    reset_frames_file();
    return -1;
  }
  // Records past the checkpoint belong to the interrupted part, and a record cut short by the interruption is
  // dropped with them; frame numbers must increase, so anything after a repeat is dropped too.
  const std::size_t record = frame_record_bytes(), size = fs::file_size(file);
  std::size_t kept = 0;
  long last = -1;
  while (kFramesHeaderBytes + (kept + 1) * record <= size) {
    in.seekg(static_cast<std::streamoff>(kFramesHeaderBytes + kept * record));
    std::int64_t f = -1;
    in.read(reinterpret_cast<char*>(&f), sizeof(f));
    if (!in || f > frame || f <= last) break;
    last = static_cast<long>(f);
    ++kept;
  }
  in.close();
  fs::resize_file(file, kFramesHeaderBytes + kept * record);
  return last;
}

void Recorder::finish(const Simulator& sim) {
  if (!m_write_glb) return;
  const fs::path file = m_dir / kFramesFile;
  std::ifstream in(file, std::ios::binary);
  char magic[8] = {};
  std::int64_t vertices = -1;
  in.seekg(sizeof(magic) + sizeof(std::uint64_t));
  in.read(reinterpret_cast<char*>(&vertices), sizeof(vertices));
  in.seekg(0);
  in.read(magic, sizeof(magic));
  if (!in || !std::equal(kFramesMagic, kFramesMagic + 8, magic) || vertices != m_combined.u.cols())
    throw_error("{}: not a frame record of this scene ({} vertices)", file.string(), m_combined.u.cols());
  SurfaceAnimation anim;
  anim.tris = m_combined.tris;
  anim.uv = m_combined.u;
  anim.num_vertices = static_cast<Index>(m_combined.u.cols());
  const std::size_t record = frame_record_bytes();
  const std::size_t frames = (fs::file_size(file) - kFramesHeaderBytes) / record;  // a partial record is ignored
  for (std::size_t k = 0; k < frames; ++k) {
    std::int64_t frame = 0;
    double time = 0.0;
    in.seekg(static_cast<std::streamoff>(kFramesHeaderBytes + k * record));
    in.read(reinterpret_cast<char*>(&frame), sizeof(frame));
    in.read(reinterpret_cast<char*>(&time), sizeof(time));
    anim.frame_numbers.push_back(static_cast<int>(frame));
    anim.times.push_back(time);
  }
  if (!in) throw_error("{}: cannot read the frame records", file.string());
  // The frames stay on disk: a long run's animation would not fit in memory.
  const auto read = [&](std::size_t k, float* out) {
    in.seekg(static_cast<std::streamoff>(kFramesHeaderBytes + k * record + sizeof(std::int64_t) + sizeof(double)));
    in.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(record - sizeof(std::int64_t) - sizeof(double)));
    if (!in) throw_error("{}: cannot read frame record {}", file.string(), k);
  };
  write_glb(m_dir / kGlbFile, anim, read, sim.obstacles());
}

void Recorder::write_checkpoint(const Simulator& sim) const {
  Checkpoint c;
  c.fingerprint = m_fingerprint;
  c.frame = sim.frame();
  c.step = sim.step_count();
  for (size_t k = 0; k < sim.bodies().size(); ++k)
    c.bodies.push_back({sim.bodies()[k]->x(), sim.bodies()[k]->v(), sim.solver_state(k)});
  const std::string bytes = encode_checkpoint(c);
  write_file_atomic(m_dir / kCheckpointFile, [&](std::ostream& o) { o.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); }, true);
}

void Recorder::CsvLog::write(const fs::path& dir) const {
  write_file_atomic(dir / name, [&](std::ostream& o) {
    o << header << '\n';
    for (const auto& r : rows) o << r << '\n';
  });
}

void Recorder::CsvLog::load_up_to_step(const fs::path& dir, long step) {
  rows.clear();
  std::ifstream in(dir / name);
  std::string line;
  std::getline(in, line);
  // A run started by an older mgcloth may have other columns: its rows are rewritten under this header by column
  // name, with the columns it did not have left empty, so that the file stays one table.
  const auto split = [](const std::string& s) {
    std::vector<std::string> cells;
    std::size_t a = 0;
    for (std::size_t b; (b = s.find(',', a)) != std::string::npos; a = b + 1) cells.push_back(s.substr(a, b - a));
    cells.push_back(s.substr(a));
    return cells;
  };
  std::vector<int> source;  // for each column of `header`, its index in the file's header (−1: absent)
  if (!line.empty() && line != header) {
    const auto old_cols = split(line);
    for (const auto& c : split(header)) {
      const auto it = std::find(old_cols.begin(), old_cols.end(), c);
      source.push_back(it == old_cols.end() ? -1 : static_cast<int>(it - old_cols.begin()));
    }
  }
  while (std::getline(in, line)) {
    // Rows past the checkpoint's step belong to the interrupted part.
    std::size_t start = 0;
    for (int c = 0; c < step_column && start != std::string::npos; ++c) {
      start = line.find(',', start);
      if (start != std::string::npos) ++start;
    }
    if (line.empty() || start == std::string::npos) continue;
    if (std::stol(line.substr(start)) > step) continue;
    if (source.empty()) {
      rows.push_back(line);
      continue;
    }
    const auto cells = split(line);
    std::string row;
    for (size_t c = 0; c < source.size(); ++c) {
      if (c) row += ',';
      if (source[c] >= 0 && static_cast<size_t>(source[c]) < cells.size()) row += cells[source[c]];
    }
    rows.push_back(std::move(row));
  }
}

void Recorder::write_logs() const {
  m_stats.write(m_dir);
  if (m_record_trace) m_trace.write(m_dir);
  if (m_record_probes) m_probes.write(m_dir);
}

void Recorder::record_frame(const Simulator& sim, const std::vector<StepStats>& stats) {
  for (const auto& s : stats) {
    m_stats.rows.push_back(stats_row(s));
    for (size_t p = 0; p < s.probes.size(); ++p) {
      const auto& r = s.probes[p];
      m_probes.rows.push_back(fmt::format("{},{:.9g},{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}", s.step,
                                          s.load_factor, s.first_probe + p, r.x.x(), r.x.y(), r.x.z(),
                                          r.u.x(), r.u.y(), r.u.z()));
    }
    for (const auto& t : s.trace)
      m_trace.rows.push_back(fmt::format("{},{},{},{},{:.17g},{:.9g},{:.3f},{:.6g}", s.frame, s.step, s.body, t.iteration,
                                         t.energy, t.grad_norm, t.wall_ms, t.step));
  }
  write_frame(sim);
  write_logs();
  // The checkpoint goes last: when it exists, everything it refers to is complete.
  write_checkpoint(sim);
}

void Recorder::resume(Simulator& sim) {
  const fs::path file = m_dir / kCheckpointFile;
  if (!fs::exists(file))
    throw InputError(fmt::format("{}: no checkpoint to resume from (was the run started with --out {}?)", file.string(), m_dir.string()));
  const Checkpoint c = decode_checkpoint(read_file(file), file);
  if (c.fingerprint != m_fingerprint)
    throw InputError(fmt::format("{}: written by a different scene (physics, cloths or solver changed); start a new run instead of --resume", file.string()));
  const size_t bodies = sim.bodies().size();
  if (c.bodies.size() != bodies)
    throw InputError(fmt::format("{}: has {} bodies, the scene has {}", file.string(), c.bodies.size(), bodies));
  std::vector<VecX> xs, vs;
  for (const auto& b : c.bodies) {
    xs.push_back(b.x);
    vs.push_back(b.v);
  }
  const int frame = static_cast<int>(c.frame);
  const long step = static_cast<long>(c.step);
  try {
    sim.set_state(frame, step, xs, vs);
    for (size_t k = 0; k < bodies; ++k) sim.set_solver_state(k, c.bodies[k].solver_state);
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", file.string(), e.what()));
  }
  remove_stale_temporaries(m_dir);
  if (m_write_glb) {
    // The checkpoint's frame is normally the last record kept; it is missing when frames.bin was, or when
    // output.every changed, and the animation needs its state as the base or the next frame.
    const long last = truncate_frames_file(static_cast<int>(frame));
    if (last < frame && (last < 0 || frame % sim.scene().output.every == 0))
      append_frame(static_cast<int>(frame), sim.time(), surface_positions(sim));
  }
  m_stats.load_up_to_step(m_dir, step);
  if (m_record_trace) m_trace.load_up_to_step(m_dir, step);
  if (m_record_probes) m_probes.load_up_to_step(m_dir, step);
  write_description(sim);
  write_logs();
}

}  // namespace mgcloth::sim
