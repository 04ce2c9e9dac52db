// sim::Simulator with its optional sim::Recorder, as the Python class mgcloth._mgcloth.Simulator.
#include "bindings.hpp"

#include <mgcloth/core/parallel.hpp>
#include <mgcloth/mesh/obj_io.hpp>
#include <mgcloth/sim/recorder.hpp>
#include <mgcloth/sim/simulator.hpp>
#include <mgcloth/sim/solver_fit.hpp>

#include <pybind11/stl.h>

#include <filesystem>
#include <omp.h>

namespace mgcloth::python {

namespace fs = std::filesystem;
using namespace pybind11::literals;

int default_threads() {
  static const int n = omp_get_max_threads();
  return n;
}

namespace {

/// An index given as any integer (Python's, NumPy's): what operator.index accepts.
long long index_of(py::handle which, const char* what) {
  PyObject* i = PyNumber_Index(which.ptr());
  if (!i) {
    PyErr_Clear();
    throw_input_error("{}: expected an index or a name, got {}", what, py::repr(which).cast<std::string>());
  }
  return py::reinterpret_steal<py::int_>(i).cast<long long>();
}

std::string fspath(py::handle p) { return py::module_::import("os").attr("fspath")(p).cast<std::string>(); }

class PySimulator {
 public:
  PySimulator(py::handle scene, py::list meshes, const std::string& file, const std::string& base_dir, py::handle out,
              bool trace, bool resume) {
    (void)default_threads();
    Json j;
    try {
      j = to_json(scene, "");
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}", file, e.what()));
    }
    if (!out.is_none()) m_out = fspath(out);
    if (j.is_object()) {
      place_meshes(j, meshes, file);
      if (!m_out.empty() && (!j.contains("output") || j["output"].is_null())) j["output"] = Json::object();
      if (!m_out.empty() && j["output"].is_object()) j["output"]["dir"] = m_out.string();
    }
    if (resume && m_out.empty()) throw_input_error("resume: needs out, the folder of the run to continue");
    m_sim = std::make_unique<sim::Simulator>(sim::parse_scene(j, file, base_dir), m_meshes);
    sim::check_solver_fits(*m_sim);
    m_sim->set_record_trace(trace);
    if (m_out.empty()) return;
    fs::create_directories(m_out);
    // The resolved scene names these files, so that `mgcloth run OUT/scene.resolved.json` runs the same cloth.
    for (size_t i = 0; i < m_meshes.size(); ++i)
      if (m_meshes[i]) mesh::write_obj(mesh_file(i), *m_meshes[i], m_meshes[i]->x, 1.0);
    m_recorder = std::make_unique<sim::Recorder>(m_out, *m_sim, trace);
    if (resume)
      m_recorder->resume(*m_sim);
    else
      m_recorder->start(*m_sim);
  }

  sim::Simulator& sim() { return *m_sim; }
  const sim::Simulator& sim() const { return *m_sim; }
  const fs::path& out() const { return m_out; }

  std::vector<sim::StepStats> step(int frames) {
    if (frames < 0) throw_input_error("frames: must be >= 0 (got {})", frames);
    std::vector<sim::StepStats> all;
    py::gil_scoped_release release;
    for (int f = 0; f < frames; ++f) {
      set_num_threads(m_sim->scene().threads > 0 ? m_sim->scene().threads : default_threads());
      auto stats = m_sim->advance_frame();
      if (m_recorder) m_recorder->record_frame(*m_sim, stats);
      all.insert(all.end(), std::make_move_iterator(stats.begin()), std::make_move_iterator(stats.end()));
      // Ctrl-C ends a long call after the frame in progress, which is complete and recorded.
      py::gil_scoped_acquire acquire;
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    }
    return all;
  }

  void finish() {
    if (!m_recorder) return;
    py::gil_scoped_release release;
    m_recorder->finish(*m_sim);
  }

  size_t cloth(py::handle which) const {
    const auto& cloths = m_sim->cloths();
    if (py::isinstance<py::str>(which)) {
      const auto name = which.cast<std::string>();
      for (size_t c = 0; c < cloths.size(); ++c)
        if (cloths[c]->name() == name) return c;
      std::vector<std::string> names;
      for (const auto& c : cloths) names.push_back(c->name());
      throw_input_error("cloth: no cloth named \"{}\" (the scene has: {})", name, fmt::join(names, ", "));
    }
    const auto c = index_of(which, "cloth");
    if (c < 0 || c >= static_cast<long long>(cloths.size()))
      throw_input_error("cloth: index {} out of range (the scene has {} cloths)", c, cloths.size());
    return static_cast<size_t>(c);
  }

  /// A body (cloth or shell) by name or by index in bodies() order (the cloths first, so a cloth's index is the same).
  size_t body(py::handle which) const {
    const auto& bodies = m_sim->bodies();
    if (py::isinstance<py::str>(which)) return m_sim->body_index(which.cast<std::string>());
    const auto b = index_of(which, "body");
    if (b < 0 || b >= static_cast<long long>(bodies.size()))
      throw_input_error("body: index {} out of range (the scene has {} bodies)", b, bodies.size());
    return static_cast<size_t>(b);
  }

  size_t obstacle(py::handle which) const {
    const auto& obstacles = m_sim->obstacles();
    if (py::isinstance<py::str>(which)) {
      const auto name = which.cast<std::string>();
      for (size_t o = 0; o < obstacles.size(); ++o)
        if (obstacles[o].name == name) return o;
      std::vector<std::string> names;
      for (const auto& o : obstacles) names.push_back(o.name);
      throw_input_error("obstacle: no obstacle named \"{}\" (the scene has: {})", name, fmt::join(names, ", "));
    }
    const auto o = index_of(which, "obstacle");
    if (o < 0 || o >= static_cast<long long>(obstacles.size()))
      throw_input_error("obstacle: index {} out of range (the scene has {} obstacles)", o, obstacles.size());
    return static_cast<size_t>(o);
  }

  /// The resolved scene; a cloth given as arrays shows them as {"arrays": ...} unless a recorded run wrote them to
  /// a file (then the file, as in OUT/scene.resolved.json).
  py::object scene() const {
    Json j = sim::to_json(m_sim->scene());
    if (m_out.empty())
      for (size_t i = 0; i < m_meshes.size(); ++i)
        if (m_meshes[i])
          j["cloths"][i]["mesh"] = {{"arrays", {{"vertices", m_meshes[i]->num_vertices()},
                                                {"triangles", m_meshes[i]->num_triangles()}}}};
    return from_json(j);
  }

 private:
  fs::path mesh_file(size_t i) const { return m_out / fmt::format("cloth{}_mesh.obj", i); }

  /// Cloths given as arrays: the scene names a file for each (written with the outputs; never read back here),
  /// and the simulator gets the mesh itself.
  void place_meshes(Json& j, py::list meshes, const std::string& file) {
    for (size_t i = 0; i < meshes.size(); ++i) {
      if (meshes[i].is_none()) {
        m_meshes.push_back(nullptr);
        continue;
      }
      if (!py::isinstance<mesh::TriMesh>(meshes[i]))
        throw_input_error("meshes[{}]: expected an mgcloth.Mesh or None, got {}", i,
                          py::str(py::type::of(meshes[i]).attr("__name__")).cast<std::string>());
      m_meshes.push_back(meshes[i].cast<std::shared_ptr<mesh::TriMesh>>());
      if (!j.contains("cloths") || !j["cloths"].is_array() || j["cloths"].size() <= i)
        throw_input_error("{}: meshes[{}]: the scene has no cloths[{}]", file, i, i);
      Json& cloth = j["cloths"][i];
      if (!cloth.is_object()) continue;  // the parser says what is wrong with it
      if (cloth.contains("mesh") && !cloth["mesh"].is_null())
        throw_input_error("{}: cloths[{}].mesh: the cloth's mesh is given as arrays; leave \"mesh\" out", file, i);
      const fs::path path = m_out.empty() ? fs::path(fmt::format("<arrays of cloths[{}]>", i)) : mesh_file(i);
      cloth["mesh"] = {{"file", path.string()}};
    }
  }

  fs::path m_out;
  std::vector<std::shared_ptr<const mesh::TriMesh>> m_meshes;
  std::unique_ptr<sim::Simulator> m_sim;
  std::unique_ptr<sim::Recorder> m_recorder;
};

py::dict trace_arrays(const solvers::Trace& trace) {
  const auto n = static_cast<py::ssize_t>(trace.size());
  py::array_t<int> iteration(n);
  py::array_t<double> energy(n), grad_norm(n), wall_ms(n), step(n);
  for (py::ssize_t i = 0; i < n; ++i) {
    iteration.mutable_at(i) = trace[i].iteration;
    energy.mutable_at(i) = trace[i].energy;
    grad_norm.mutable_at(i) = trace[i].grad_norm;
    wall_ms.mutable_at(i) = trace[i].wall_ms;
    step.mutable_at(i) = trace[i].step;
  }
  py::dict d;
  d["iteration"] = iteration;
  d["energy"] = energy;
  d["grad_norm"] = grad_norm;
  d["wall_ms"] = wall_ms;
  d["step"] = step;
  return d;
}

Eigen::Quaterniond rotation_from_matrix(py::handle R) {
  const py::array a = py::module_::import("numpy").attr("asarray")(R, "dtype"_a = "float64");
  if (a.ndim() != 2 || a.shape(0) != 3 || a.shape(1) != 3)
    throw_input_error("rotation: expected a 3 x 3 rotation matrix, got an array of {} dimensions", a.ndim());
  const auto r = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a).unchecked<2>();
  Mat3 M;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) M(i, k) = r(i, k);
  if (!M.allFinite() || (M.transpose() * M - Mat3::Identity()).norm() > 1e-6 || M.determinant() < 0.0)
    throw_input_error("rotation: not a rotation matrix (it must be orthonormal with determinant 1)");
  return Eigen::Quaterniond(M).normalized();
}

Vec3 vec3(py::handle v, const std::string& name) {
  const py::array a = py::module_::import("numpy").attr("asarray")(v);
  if (a.ndim() != 1 || a.shape(0) != 3 || (a.dtype().kind() != 'f' && a.dtype().kind() != 'i' && a.dtype().kind() != 'u'))
    throw_input_error("{}: expected 3 numbers, got {}", name, py::repr(v).cast<std::string>());
  const auto d = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  const Vec3 x(d.at(0), d.at(1), d.at(2));
  if (!x.allFinite()) throw_input_error("{}: must be finite, got [{}, {}, {}]", name, x.x(), x.y(), x.z());
  return x;
}

}  // namespace

void bind_simulator(py::module_& m) {
  py::class_<sim::StepStats>(m, "StepStats", "Statistics of one implicit-Euler step of one cloth or shell.")
      .def_readonly("frame", &sim::StepStats::frame, "The frame the step belongs to (1-based).")
      .def_readonly("step", &sim::StepStats::step, "The step number (1-based; frames x substeps in all).")
      .def_readonly("time", &sim::StepStats::sim_time, "Simulated time at the end of the step, in seconds.")
      .def_readonly("body", &sim::StepStats::body, "Name of the body (cloth or shell).")
      .def_readonly("cloth", &sim::StepStats::body, "The same as body (the name of stats.csv's column).")
      .def_readonly("solver", &sim::StepStats::solver, "Name of the solver that minimized the step's objective.")
      .def_property_readonly("iterations", [](const sim::StepStats& s) { return s.report.iterations; },
                             "Solver iterations of the step.")
      .def_property_readonly("converged", [](const sim::StepStats& s) { return s.report.converged; },
                             "Whether the solve met the stopping criterion.")
      .def_property_readonly("status", [](const sim::StepStats& s) { return s.report.status; },
                             "How the solve ended: converged, max_iters, time_limit, stalled, ...")
      .def_property_readonly("energy", [](const sim::StepStats& s) { return s.report.energy; },
                             "The incremental potential at the solve's final iterate (J).")
      .def_property_readonly("grad_norm", [](const sim::StepStats& s) { return s.report.grad_norm; },
                             "Norm of its gradient at the final iterate (N).")
      .def_property_readonly("initial_grad_norm", [](const sim::StepStats& s) { return s.report.initial_grad_norm; },
                             "Gradient norm at the start point.")
      .def_readonly("wall_ms", &sim::StepStats::wall_ms, "Wall time of the whole step (set-up, solve, contact), ms.")
      .def_property_readonly("solve_ms", [](const sim::StepStats& s) { return s.report.wall_ms; },
                             "Wall time of the solve alone, ms.")
      .def_readonly("projected", &sim::StepStats::projected, "Vertices pushed out of obstacles after the solve.")
      .def_readonly("load_factor", &sim::StepStats::load_factor, "Shells: the load factor of the step.")
      .def_readonly("obstacle_rounds", &sim::StepStats::obstacle_rounds,
                    "Mesh obstacles: solves after the first because a mesh was still short of its pose.")
      .def_readonly("seam_gap", &sim::StepStats::seam_gap,
                    "Sewn cloths: the largest distance between two points sewn together at the end of the step (m; "
                    "NaN: no seams).")
      .def_readonly("velocity_error", &sim::StepStats::velocity_error,
                    "The solver's estimate of the largest per-vertex velocity error at the end of the step (m/s; inf: "
                    "no estimate possible, NaN: none made).")
      .def_readonly("velocity_rms_error", &sim::StepStats::velocity_rms_error,
                    "The mass-weighted RMS velocity error that the solver's Newton decrement estimates, "
                    "sqrt(lambda^2 / M) (m/s); for solvers that measure no decrement, the gradient's bound of it, "
                    "h |grad E| / sqrt(m_min M).")
      .def_readonly("true_velocity_error", &sim::StepStats::true_velocity_error,
                    "With check_accuracy on: the largest per-vertex distance between the step's result and its own "
                    "minimizer (Newton + CHOLMOD solved on from the result), over the time step (m/s; NaN: not "
                    "checked, or the check did not converge).")
      .def_readonly("true_velocity_rms", &sim::StepStats::true_velocity_rms,
                    "With check_accuracy on: the RMS over the vertices of that distance, over the time step (m/s).")
      .def_readonly("contact_pairs", &sim::StepStats::contact_pairs,
                    "Cloth contact: pairs inside the contact layer at the end of the step (-1: no cloth contact).")
      .def_readonly("min_distance", &sim::StepStats::min_distance,
                    "Cloth contact: the smallest distance between primitives within reach at the end of the step (m).")
      .def_readonly("intersections", &sim::StepStats::intersections,
                    "Cloth contact: triangle pairs the exact checker found intersecting at the end of the step "
                    "(cloths with cloths and with obstacle meshes; -1: not checked).")
      .def_property_readonly(
          "counters",
          [](const sim::StepStats& s) {
            py::dict d;
            for (const auto& [k, v] : s.report.counters) d[py::str(k)] = v;
            return d;
          },
          "The solver's counters of the step (time per phase, line-search evaluations, ...).")
      .def_property_readonly(
          "trace",
          [](const sim::StepStats& s) -> py::object {
            if (s.trace.empty()) return py::none();
            return trace_arrays(s.trace);
          },
          "Per-iteration arrays (iteration, energy, grad_norm, wall_ms, step) when the simulation records traces "
          "(trace=True), else None.")
      .def("__repr__", [](const sim::StepStats& s) {
        return fmt::format("<mgcloth.StepStats frame {} step {} body \"{}\": {} {} iterations, {}, energy {:.9g}>",
                           s.frame, s.step, s.body, s.solver, s.report.iterations, s.report.status, s.report.energy);
      });

  py::class_<PySimulator>(
      m, "Simulator",
      "The simulator of one parsed scene (sim::Simulator), with the recorder of `mgcloth run` when given an output "
      "folder. mgcloth.Simulation is the friendlier front end; this class takes the scene as a dict.")
      .def(py::init<py::handle, py::list, const std::string&, const std::string&, py::handle, bool, bool>(),
           py::arg("scene"), py::arg("meshes") = py::list(), py::kw_only(), py::arg("file") = "scene",
           py::arg("base_dir") = ".", py::arg("out") = py::none(), py::arg("trace") = false, py::arg("resume") = false,
           "Parses `scene` (a dict in the scene-file format, docs/scene-format.md) with the scene-file parser: unknown "
           "keys, wrong types and out-of-range values raise InputError naming `file` and the JSON path. `meshes`: per "
           "cloth, an mgcloth.Mesh that replaces the cloth's \"mesh\" (then left out of the dict), or None. "
           "`base_dir` resolves relative mesh files. With `out`, the run is recorded there exactly as `mgcloth run "
           "--out` does (frames, stats.csv, scene.resolved.json, checkpoint.bin; meshes given as arrays are written "
           "as clothN_mesh.obj and named in the resolved scene); `resume` continues the run recorded there from its "
           "checkpoint. `trace` keeps every solver iteration (StepStats.trace, and trace.csv when recording).")
      .def("step", &PySimulator::step, py::arg("frames") = 1,
           "Advances `frames` frames (each the scene's time_step: `substeps` implicit-Euler steps of every cloth), "
           "recording each when recording. Returns the StepStats of every step. Releases the GIL while it runs; "
           "Ctrl-C (KeyboardInterrupt) stops it after the frame in progress.")
      .def(
          "run",
          [](PySimulator& s, std::optional<int> frames) {
            const int total = frames.value_or(s.sim().scene().frames);
            auto stats = s.step(std::max(0, total - s.sim().frame()));
            s.finish();
            return stats;
          },
          py::arg("frames") = py::none(),
          "Runs to frame `frames` (default: the scene's \"frames\") and finishes the recording, as `mgcloth run` "
          "does. Returns the StepStats of the steps taken.")
      .def_property(
          "check_accuracy", [](const PySimulator& s) { return s.sim().accuracy_check(); },
          [](PySimulator& s, bool on) { s.sim().set_accuracy_check(on); },
          "Whether every step is measured against its own minimizer (`mgcloth run --check-accuracy`): "
          "StepStats.true_velocity_error and true_velocity_rms, at the price of a Newton solve per step.")
      .def("finish", &PySimulator::finish,
           "Ends the recording: writes animation.glb when the scene's output.format asks for it (run() calls it). "
           "Calling it again rewrites it; recording may go on after it.")
      .def(
          "positions",
          [](py::object self, py::handle cloth) {
            auto& s = self.cast<PySimulator&>();
            const VecX& x = s.sim().bodies()[s.body(cloth)]->x();
            return readonly_view(x.data(), x.size() / 3, 3, 3, self);
          },
          py::arg("cloth") = 0,
          "World positions of a body's points (a cloth's vertices, a shell's control points; the body by index in "
          "body_names or by name): a read-only (n, 3) float64 view, no copy. It is live: later steps change it; copy "
          "it (np.array(...)) to keep a frame.")
      .def(
          "velocities",
          [](py::object self, py::handle cloth) {
            auto& s = self.cast<PySimulator&>();
            const VecX& v = s.sim().bodies()[s.body(cloth)]->v();
            return readonly_view(v.data(), v.size() / 3, 3, 3, self);
          },
          py::arg("cloth") = 0, "Velocities of a body's points (m/s): a live read-only (n, 3) float64 view.")
      .def_property_readonly(
          "x",
          [](py::object self) {
            auto& s = self.cast<PySimulator&>();
            if (s.sim().bodies().size() != 1)
              throw_input_error("x: the scene has {} bodies; use positions(cloth)", s.sim().bodies().size());
            const VecX& x = s.sim().bodies()[0]->x();
            return readonly_view(x.data(), x.size() / 3, 3, 3, self);
          },
          "Positions of the scene's one body: a live read-only (n, 3) view (positions(cloth) for several).")
      .def_property_readonly(
          "v",
          [](py::object self) {
            auto& s = self.cast<PySimulator&>();
            if (s.sim().bodies().size() != 1)
              throw_input_error("v: the scene has {} bodies; use velocities(cloth)", s.sim().bodies().size());
            const VecX& v = s.sim().bodies()[0]->v();
            return readonly_view(v.data(), v.size() / 3, 3, 3, self);
          },
          "Velocities of the scene's one body: a live read-only (n, 3) view (velocities(cloth) for several).")
      .def(
          "triangles",
          [](py::object self, py::handle cloth) {
            auto& s = self.cast<PySimulator&>();
            const auto& tris = s.sim().cloths()[s.cloth(cloth)]->mesh().tris;
            return readonly_view(tris[0].data(), static_cast<py::ssize_t>(tris.size()), 3, 3, self);
          },
          py::arg("cloth") = 0, "A cloth's triangles: a read-only (m, 3) int32 view of 0-based vertex indices.")
      .def(
          "material_coordinates",
          [](py::object self, py::handle cloth) {
            auto& s = self.cast<PySimulator&>();
            const auto& u = s.sim().cloths()[s.cloth(cloth)]->mesh().u;
            return readonly_view(u.data(), u.cols(), 2, 2, self);
          },
          py::arg("cloth") = 0, "A cloth's material (rest) coordinates in metres: a read-only (n, 2) view.")
      .def(
          "masses",
          [](py::object self, py::handle cloth) {
            auto& s = self.cast<PySimulator&>();
            const VecX& mass = s.sim().cloths()[s.cloth(cloth)]->mass();
            return readonly_view(mass.data(), mass.size(), self);
          },
          py::arg("cloth") = 0, "Lumped vertex masses of a cloth (kg): a read-only (n,) view.")
      .def(
          "pinned_vertices",
          [](py::object self, py::handle cloth) {
            auto& s = self.cast<PySimulator&>();
            const auto& p = s.sim().cloths()[s.cloth(cloth)]->pinned_vertices();
            return readonly_view(p.data(), static_cast<py::ssize_t>(p.size()), self);
          },
          py::arg("cloth") = 0,
          "A cloth's pinned vertices, in the order of pin_targets() and set_pin_targets(): a read-only int32 view.")
      .def(
          "pin_targets",
          [](PySimulator& s, py::handle cloth) {
            const auto targets = s.sim().cloths()[s.cloth(cloth)]->pin_targets(s.sim().time());
            py::array_t<double> a({static_cast<py::ssize_t>(targets.size()), py::ssize_t{3}});
            for (size_t p = 0; p < targets.size(); ++p)
              for (int k = 0; k < 3; ++k) a.mutable_at(p, k) = targets[p][k];
            return a;
          },
          py::arg("cloth") = 0, "Where a cloth's pins pull now: a (k, 3) array, one row per pinned vertex.")
      .def(
          "set_pin_targets",
          [](PySimulator& s, py::handle targets, py::handle cloth) {
            const size_t c = s.cloth(cloth);
            const auto a = float_rows(targets, "targets", 3, "pin targets");
            std::vector<Vec3> t(a.shape(0));
            for (size_t p = 0; p < t.size(); ++p) t[p] = Vec3(a.at(p, 0), a.at(p, 1), a.at(p, 2));
            s.sim().set_pin_targets(c, t);
          },
          py::arg("targets"), py::arg("cloth") = 0,
          "Scripted or interactive animation: the pins of a cloth pull towards `targets` ((k, 3), one row per "
          "pinned vertex in pinned_vertices() order), reached at the end of the next frame, moving linearly from "
          "where they pull now; they stay there until set again. The scene's pin motion no longer applies. Not kept "
          "in checkpoints.")
      .def(
          "obstacle_pose",
          [](PySimulator& s, py::handle obstacle) {
            const auto& ob = s.sim().obstacles()[s.obstacle(obstacle)];
            const geometry::Pose p = ob.motion ? ob.motion->pose(s.sim().time()) : geometry::Pose{};
            py::array_t<double> position(3), rotation({3, 3});
            const Mat3 R = p.rotation.toRotationMatrix();
            for (int i = 0; i < 3; ++i) {
              position.mutable_at(i) = p.translation[i];
              for (int k = 0; k < 3; ++k) rotation.mutable_at(i, k) = R(i, k);
            }
            return py::make_tuple(position, rotation);
          },
          py::arg("obstacle"),
          "An obstacle's pose now (by index or name): (position (3,), rotation matrix (3, 3)); world = R p + "
          "position.")
      .def(
          "set_obstacle_pose",
          [](PySimulator& s, py::handle obstacle, py::handle position, py::handle rotation_deg, py::handle rotation) {
            const size_t o = s.obstacle(obstacle);
            const auto& ob = s.sim().obstacles()[o];
            geometry::Pose p = ob.motion ? ob.motion->pose(s.sim().time()) : geometry::Pose{};
            if (!rotation_deg.is_none() && !rotation.is_none())
              throw_input_error("set_obstacle_pose: give rotation_deg or rotation, not both");
            if (!position.is_none()) p.translation = vec3(position, "position");
            if (!rotation_deg.is_none()) {
              sim::Transform t;
              t.rotation_deg = vec3(rotation_deg, "rotation_deg");
              p.rotation = t.rotation();
            }
            if (!rotation.is_none()) p.rotation = rotation_from_matrix(rotation);
            s.sim().set_obstacle_pose(o, p);
          },
          py::arg("obstacle"), py::arg("position") = py::none(), py::arg("rotation_deg") = py::none(),
          py::arg("rotation") = py::none(),
          "Scripted or interactive animation: the obstacle (index or name) moves to this pose over the next frame "
          "(linearly, rotations by slerp; friction sees that velocity) and stays there until set again; the scene's "
          "motion no longer applies. position: (3,); rotation_deg: XYZ Euler angles in degrees as in scene files, or "
          "rotation: a 3 x 3 matrix; what is not given keeps its current value. Not kept in checkpoints.")
      .def_property_readonly("time", [](const PySimulator& s) { return s.sim().time(); }, "Simulated time (s).")
      .def_property_readonly("frame", [](const PySimulator& s) { return s.sim().frame(); }, "Frames completed.")
      .def_property_readonly("step_count", [](const PySimulator& s) { return s.sim().step_count(); },
                             "Implicit-Euler steps completed (frames x substeps).")
      .def_property_readonly("dt", [](const PySimulator& s) { return s.sim().scene().frame_time; },
                             "Seconds per frame (the scene's time_step): what one step() advances.")
      .def_property_readonly("step_size", [](const PySimulator& s) { return s.sim().scene().step_size(); },
                             "Seconds per implicit-Euler step: dt / substeps.")
      .def_property_readonly("solver", [](const PySimulator& s) { return s.sim().scene().solver.name; },
                             "Name of the scene's solver.")
      .def_property_readonly(
          "cloth_names",
          [](const PySimulator& s) {
            std::vector<std::string> names;
            for (const auto& c : s.sim().cloths()) names.push_back(c->name());
            return names;
          },
          "Names of the cloths, in scene order (index = position in this list).")
      .def_property_readonly(
          "body_names",
          [](const PySimulator& s) {
            std::vector<std::string> names;
            for (const auto& b : s.sim().bodies()) names.push_back(b->name());
            return names;
          },
          "Names of every body: the cloths, then the shells, in scene order (index = position in this list).")
      .def_property_readonly(
          "obstacle_names",
          [](const PySimulator& s) {
            std::vector<std::string> names;
            for (const auto& o : s.sim().obstacles()) names.push_back(o.name);
            return names;
          },
          "Names of the obstacles, in scene order.")
      .def_property_readonly(
          "out", [](const PySimulator& s) -> py::object {
            if (s.out().empty()) return py::none();
            return py::str(s.out().string());
          },
          "The output folder when recording, else None.")
      .def_property_readonly("scene", &PySimulator::scene,
                             "The resolved scene as a dict: every field with its value, defaults included (what "
                             "scene.resolved.json holds).");
}

}  // namespace mgcloth::python
