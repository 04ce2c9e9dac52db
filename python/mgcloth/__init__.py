"""mgcloth: cloth simulation by nonlinear multigrid, from Python.

A thin layer over the C++ library: a scene (a scene file, a dict in the same format, or keyword arguments with
NumPy meshes) is parsed by the same parser as `mgcloth run`, stepped by the same simulator, and recorded, when
asked, into the same output folder. Positions and velocities come back as read-only NumPy views without copies.

    import mgcloth, numpy as np
    V, F = mgcloth.grid(1.0, 1.0, 2500)
    sim = mgcloth.Simulation(cloths=[mgcloth.Cloth(V, F, pins=[0, 49])],
                             obstacles=[mgcloth.Sphere(0.3, center=(0.5, 0.5, -0.5))], dt=1 / 30, rel_grad=1e-3)
    for _ in range(30):
        sim.step()
    sim.x  # (2500, 3) positions

Errors raise mgcloth.InputError (also a ValueError), mgcloth.SolveError, mgcloth.OutOfMemoryError (also a
MemoryError) or mgcloth.Error (a RuntimeError) with the messages the CLI prints.
"""

import os as _os
from collections.abc import Mapping as _Mapping

from . import _mgcloth
from ._mgcloth import (
    ConvergenceResult,
    Error,
    InputError,
    Mesh,
    OutOfMemoryError,
    SolveError,
    StepStats,
    __version__,
    grid,
    material_presets,
    num_threads,
    set_log_level,
    solver_names,
)

__all__ = [
    "Body", "Box", "Capsule", "Cloth", "ConvergenceResult", "Error", "InputError", "Mesh", "MeshObstacle", "OutOfMemoryError",
    "Plane",
    "Simulation", "SolveError", "Sphere", "StepStats", "convergence", "grid", "load_scene", "material_presets", "num_threads",
    "run_sweep", "set_log_level", "solver_names",
]

# The label of scenes given as dicts or keywords in messages, where a file name would be.
_DICT_LABEL = "scene"


def load_scene(path):
    """A scene file as a dict (mgcloth's JSON reader: syntax errors name the file, line and column)."""
    return _mgcloth.load_json(_os.fspath(path))


def _vec(v):
    return [float(c) for c in v]


class Cloth:
    """A cloth made from arrays: a scene's cloth whose mesh is given in memory.

    V, F: vertex positions (n, 3) and triangles (m, 3, 0-based), or an mgcloth.Mesh as V (then no F, uv).
    uv: material (rest) coordinates (n, 2) in metres; without it the mesh must be planar and is flattened.
    pins: vertex indices pinned to where they start (one pin group of stiffness pin_stiffness, N/m), and/or pin
        dicts in the scene format ({"vertices": [...], "motion": {...}}, {"region": ...}).
    material: a preset name ("cotton", "silk", "denim", "leather") or a scene-format material dict.
    Everything else is the scene format's cloth field of the same name (docs/scene-format.md); None leaves the
    scene's default. Arrays are checked here: a bad shape, NaN or an out-of-range index raises InputError.
    """

    def __init__(self, V, F=None, *, uv=None, name=None, pins=None, pin_stiffness=None, material=None,
                 initial_velocity=None, translation=None, rotation_deg=None, seam_stiffness=None):
        if isinstance(V, Mesh):
            if F is not None or uv is not None:
                raise InputError("Cloth: give a Mesh alone, or V and F (and uv) arrays")
            self.mesh = V
        else:
            if F is None:
                raise InputError("Cloth: F (the triangles) is missing")
            self.mesh = Mesh(V, F, uv)
        entry = {}
        if name is not None:
            entry["name"] = name
        pin_list = []
        indices = []
        for p in [] if pins is None else pins:
            if isinstance(p, _Mapping):
                pin_list.append(dict(p))
            else:
                indices.append(p)
        if indices:
            group = {"vertices": indices}
            if pin_stiffness is not None:
                group["stiffness"] = pin_stiffness
            pin_list.insert(0, group)
        elif pin_stiffness is not None:
            raise InputError("Cloth: pin_stiffness is given but no pinned vertex indices")
        if pin_list:
            entry["pins"] = pin_list
        if material is not None:
            entry["material"] = {"preset": material} if isinstance(material, str) else dict(material)
        if initial_velocity is not None:
            entry["initial_velocity"] = _vec(initial_velocity)
        if translation is not None or rotation_deg is not None:
            entry["transform"] = {}
            if translation is not None:
                entry["transform"]["translation"] = _vec(translation)
            if rotation_deg is not None:
                entry["transform"]["rotation_deg"] = _vec(rotation_deg)
        if seam_stiffness is not None:
            entry["seam_stiffness"] = seam_stiffness
        self.entry = entry

    def scene_entry(self):
        """The cloth's scene-format dict, without "mesh" (the mesh goes to the simulator as arrays)."""
        return dict(self.entry)

    def __repr__(self):
        return f"<mgcloth.Cloth {self.entry.get('name', '(unnamed)')}: {self.mesh!r}>"


class _Obstacle:
    """An obstacle in the scene format: a shape placed at `position` (the shape's centre) rotated by XYZ Euler
    angles `rotation_deg`, with Coulomb `friction` and an optional scene-format `motion` dict."""

    def __init__(self, shape, position, rotation_deg, friction, name, motion):
        entry = {"position": _vec(position), "friction": float(friction)}
        if shape is not None:
            entry["shape"] = shape
        if rotation_deg is not None:
            entry["rotation_deg"] = _vec(rotation_deg)
        if name is not None:
            entry["name"] = name
        if motion is not None:
            entry["motion"] = dict(motion)
        self.entry = entry

    def scene_entry(self):
        """The obstacle's scene-format dict."""
        return dict(self.entry)

    def __repr__(self):
        return f"<mgcloth.{type(self).__name__} {self.entry}>"


class Sphere(_Obstacle):
    """A sphere of `radius` (m) centred at `center`."""

    def __init__(self, radius, center=(0.0, 0.0, 0.0), *, friction=0.0, name=None, motion=None):
        super().__init__({"type": "sphere", "radius": float(radius)}, center, None, friction, name, motion)


class Plane(_Obstacle):
    """The ground: the plane z = 0 moved to `point` and rotated by `rotation_deg`; cloth stays on its +z side."""

    def __init__(self, point=(0.0, 0.0, 0.0), rotation_deg=None, *, friction=0.0, name=None, motion=None):
        super().__init__({"type": "plane"}, point, rotation_deg, friction, name, motion)


class Box(_Obstacle):
    """A box with `half_extents` (m) centred at `center`, rotated by `rotation_deg`."""

    def __init__(self, half_extents, center=(0.0, 0.0, 0.0), rotation_deg=None, *, friction=0.0, name=None,
                 motion=None):
        super().__init__({"type": "box", "half_extents": _vec(half_extents)}, center, rotation_deg, friction, name,
                         motion)


class Capsule(_Obstacle):
    """A capsule of `radius` around a segment of half length `half_length` along its local z axis."""

    def __init__(self, radius, half_length, center=(0.0, 0.0, 0.0), rotation_deg=None, *, friction=0.0, name=None,
                 motion=None):
        super().__init__({"type": "capsule", "radius": float(radius), "half_length": float(half_length)}, center,
                         rotation_deg, friction, name, motion)


class MeshObstacle(_Obstacle):
    """A triangle mesh from an OBJ `file` (relative paths from the scene's folder), in its own frame placed at
    `position` and rotated by `rotation_deg`. Cloth touches it through cloth contact (the scene needs
    "cloth_contact", e.g. Simulation(..., cloth_contact={})), penetration-free. A file name with %d or %0Nd is a
    sequence of files deforming the mesh at `rate` files per second (from number `first`, repeated with `loop`).
    `contact_thickness` (m): the mesh's side of the contact layer (default: the cloths')."""

    def __init__(self, file, position=(0.0, 0.0, 0.0), rotation_deg=None, *, friction=0.0, name=None, motion=None,
                 contact_thickness=None, rate=None, first=None, loop=None, gltf_mesh=None, gltf_animation=None,
                 gltf_y_up=None):
        super().__init__(None, position, rotation_deg, friction, name, motion)
        self.entry["mesh"] = _os.fspath(file)
        for key, value in (("contact_thickness", contact_thickness), ("mesh_rate", rate), ("mesh_first", first),
                           ("mesh_loop", loop), ("gltf_mesh", gltf_mesh), ("gltf_animation", gltf_animation),
                           ("gltf_y_up", gltf_y_up)):
            if value is not None:
                self.entry[key] = value


class Body(_Obstacle):
    """The generated mannequin (docs/scene-format.md, "The walking body"): `height` (m), `build` (girth factor),
    `resolution` (edge length, m), `arm_abduction` (degrees); `walk` is None (it stands), True (the default walk)
    or a dict of the scene's "walk" keys (period, stand, ramp, duration, key_rate, forward, arm_swing). It faces +x
    with its soles at `position`. Like MeshObstacle it needs cloth contact."""

    def __init__(self, height=1.75, build=1.0, *, resolution=None, arm_abduction=None, walk=None,
                 position=(0.0, 0.0, 0.0), rotation_deg=None, friction=0.0, name=None, motion=None,
                 contact_thickness=None):
        super().__init__(None, position, rotation_deg, friction, name, motion)
        body = {"height": float(height), "build": float(build)}
        if resolution is not None:
            body["resolution"] = float(resolution)
        if arm_abduction is not None:
            body["arm_abduction"] = float(arm_abduction)
        if walk is True:
            body["walk"] = {}
        elif walk:
            body["walk"] = dict(walk)
        self.entry["body"] = body
        if contact_thickness is not None:
            self.entry["contact_thickness"] = contact_thickness


def _resolve_scene(scene):
    """(dict, file label, base dir) of a scene given as None, a path or a dict."""
    if scene is None:
        return {}, _DICT_LABEL, "."
    if isinstance(scene, (str, bytes, _os.PathLike)):
        path = _os.fspath(scene)
        if isinstance(path, bytes):
            path = _os.fsdecode(path)
        if not _os.path.exists(path):
            raise InputError(f"{path}: no such scene file")
        return load_scene(path), path, _os.path.dirname(path) or "."
    if isinstance(scene, _Mapping):
        return dict(scene), _DICT_LABEL, "."
    raise InputError(f"scene: expected a scene file path or a dict, got {type(scene).__name__}")


def _split_cloths(entries):
    """Scene cloth entries (dicts or Cloth objects) as (dicts, meshes): a Mesh for each Cloth, None for dicts."""
    dicts, meshes = [], []
    for c in entries:
        if isinstance(c, Cloth):
            dicts.append(c.scene_entry())
            meshes.append(c.mesh)
        else:
            dicts.append(c)
            meshes.append(None)
    return dicts, meshes


class Simulation(_mgcloth.Simulator):
    """A cloth simulation: a scene, stepped frame by frame, optionally recorded like `mgcloth run`.

    scene: a scene file path, a scene dict (docs/scene-format.md; its cloths and obstacles may also be Cloth and
        obstacle objects), or None to build the scene from the keywords alone.
    cloths, obstacles: Cloth objects (or scene dicts) and Sphere/Plane/Box/Capsule/MeshObstacle objects (or dicts), added after
        the scene's own.
    dt: seconds per frame (the scene's "time_step"); substeps: implicit-Euler steps per frame; frames: the length
        of run(); gravity: (3,) m/s^2; threads: worker threads (0: all cores).
    solver: a name from mgcloth.solver_names() (a different name than the scene's drops the scene's solver params,
        as `mgcloth run --solver` does); solver_params: its parameters; rel_grad, velocity_tol (m/s),
        velocity_rms_tol (m/s), max_iters: its stop criterion.
    energy_form: "elastic" or "projective", the form of the cloth energy the steps minimize (the pd-* solvers need
        "projective").
    contact, cloth_contact, hierarchy: scene-format dicts of those blocks (cloth_contact={} turns cloth contact on
        with its defaults: cloths collide with themselves, each other and MeshObstacles).
    out: record into this folder as `mgcloth run --out` does (True: the scene's output.dir); formats: the output
        formats ("obj", "glb"); trace: keep every solver iteration (StepStats.trace, trace.csv); resume: continue
        the run recorded in `out` from its checkpoint (pass the same scene and arrays).
    Keywords left at None keep the scene's values (or the scene format's defaults).
    """

    def __init__(self, scene=None, *, cloths=(), obstacles=(), dt=None, substeps=None, frames=None, gravity=None,
                 threads=None, solver=None, solver_params=None, rel_grad=None, velocity_tol=None,
                 velocity_rms_tol=None, max_iters=None, contact=None, cloth_contact=None, hierarchy=None,
                 energy_form=None, out=None, formats=None, trace=False, resume=False):
        d, file, base_dir = _resolve_scene(scene)
        if not isinstance(d.get("cloths", []), (list, tuple)) or not isinstance(d.get("obstacles", []), (list, tuple)):
            # The parser names what is wrong; nothing to merge into.
            super().__init__(d, [], file=file, base_dir=base_dir)
            self._built = True
            return
        scene_cloths, meshes = _split_cloths(list(d.get("cloths", [])) + list(cloths))
        if scene_cloths or "cloths" in d:
            d["cloths"] = scene_cloths
        all_obstacles = [o.scene_entry() if isinstance(o, _Obstacle) else o
                         for o in list(d.get("obstacles", [])) + list(obstacles)]
        if all_obstacles or "obstacles" in d:
            d["obstacles"] = all_obstacles
        for key, value in (("time_step", dt), ("substeps", substeps), ("frames", frames), ("threads", threads),
                           ("contact", contact), ("cloth_contact", cloth_contact), ("hierarchy", hierarchy),
                           ("energy_form", energy_form)):
            if value is not None:
                d[key] = value
        if gravity is not None:
            d["gravity"] = _vec(gravity)
        if any(v is not None for v in (solver, solver_params, rel_grad, velocity_tol, velocity_rms_tol, max_iters)):
            block = dict(d.get("solver") or {})
            if solver is not None:
                if solver != block.get("name"):
                    block.pop("params", None)
                block["name"] = solver
            if solver_params is not None:
                block["params"] = dict(solver_params)
            if rel_grad is not None:
                block["rel_grad"] = rel_grad
            if velocity_tol is not None:
                block["velocity_tol"] = velocity_tol
            if velocity_rms_tol is not None:
                block["velocity_rms_tol"] = velocity_rms_tol
            if max_iters is not None:
                block["max_iters"] = max_iters
            d["solver"] = block
        if formats is not None:
            d["output"] = dict(d.get("output") or {})
            d["output"]["format"] = [formats] if isinstance(formats, str) else list(formats)
        if out is True:
            out = (d.get("output") or {}).get("dir", "out")
        elif out is False:
            out = None
        super().__init__(d, meshes, file=file, base_dir=base_dir, out=out, trace=trace, resume=resume)
        self._built = True

    def __repr__(self):
        # A traceback shows the object whose __init__ raised: its C++ part does not exist.
        if not self.__dict__.get("_built"):
            return "<mgcloth.Simulation (not built)>"
        return (f"<mgcloth.Simulation {len(self.cloth_names)} cloths, {len(self.obstacle_names)} obstacles, "
                f"solver {self.solver}, frame {self.frame}, t = {self.time:.4g} s>")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        # Leaves a viewable animation (glb) however the block ends.
        self.finish()
        return False


def run_sweep(sweep, out, *, resume=False, retry_failed=False, threads=0):
    """A parameter sweep (docs/sweeps.md) run one run after another in this process, as `mgcloth sweep` without
    MPI: each run's folder runs/NNNNN/ and summary.csv go to `out`.

    sweep: a sweep file path, or a dict in the same format (its relative "scene" path is the current folder's).
    resume: continue a sweep in `out` (finished runs are kept, partial ones continue from their checkpoints);
    retry_failed: with resume, run the failed runs again. threads: per run (0: the sweep's, else the scene's).
    Returns a list with one dict per run: run, status ("ok", "failed"), message, values (column -> the run's
    parameter value), measures (column -> number; NaN where undefined), wall_s, last_frame, steps, iterations,
    unconverged_steps, resumed_from and folder (relative to out). A failed run is a row, not an exception; a bad
    sweep raises InputError before any run.
    """
    if not isinstance(sweep, _Mapping):
        sweep = _os.fspath(sweep)
    return _mgcloth.run_sweep(sweep, _os.fspath(out), resume, retry_failed, threads)


def convergence(scene, solvers, *, step=1, budget=10.0, max_iters=10000, threads=0, vertices=None, state_cache=None,
                reference_seconds=600.0, out=None, body=None):
    """The convergence benchmark of `mgcloth bench convergence` (Wang 2018, Fig. 4): simulates the scene's first
    step - 1 steps with newton-direct, freezes step `step`'s objective of `body` (a cloth or shell by name; None:
    the first) and runs every solver of `solvers`
    from the same start point for `budget` seconds or `max_iters` iterations, recording (E_k - E*)/(E_0 - E*).

    scene: a scene file path or dict whose meshes are files or generators (cloths given as arrays are not
        supported: the benchmark builds its own simulators from the scene). solvers: a list of specs (or one
        comma-separated string) "NAME" or "NAME@key=value@...". vertices: resize every generated cloth.
    state_cache: a file caching the start state and E*. out: also write convergence.csv and convergence.json there.
    Returns a ConvergenceResult: result.trace("fmg") -> dict of arrays, result.summary -> convergence.json's dict.
    """
    d, file, base_dir = _resolve_scene(scene)
    for c in d.get("cloths", []) if isinstance(d.get("cloths"), (list, tuple)) else []:
        if isinstance(c, Cloth):
            raise InputError("convergence: cloths given as arrays are not supported; give the mesh as a file "
                             "(Mesh.write_obj) or a generator in the scene")
    if isinstance(solvers, str):
        solvers = [s for s in solvers.split(",")]
    return _mgcloth._convergence(d, file, base_dir, list(solvers), step, budget, max_iters, threads, vertices,
                                 "" if state_cache is None else _os.fspath(state_cache), reference_seconds, out,
                                 "" if body is None else body)
