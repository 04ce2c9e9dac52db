"""Errors raise Python exceptions with the CLI's messages, naming the array, row or scene field at fault."""
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import mgcloth
from conftest import hanging


def test_exception_hierarchy():
    assert issubclass(mgcloth.InputError, mgcloth.Error) and issubclass(mgcloth.InputError, ValueError)
    assert issubclass(mgcloth.SolveError, mgcloth.Error)
    assert issubclass(mgcloth.Error, RuntimeError)


@pytest.mark.parametrize("change, message", [
    (lambda V, F: (V[:, :2], F), r"V: expected an \(n, 3\) array of vertex positions, got shape \(64, 2\)"),
    (lambda V, F: (V.ravel(), F), r"V: expected an \(n, 3\) array of vertex positions, got shape \(192,\)"),
    (lambda V, F: (np.where(np.arange(64)[:, None] == 5, np.nan, V), F), r"V: row 5 is not finite \(\[nan, nan, nan\]\)"),
    (lambda V, F: (V.astype(str), F), r"V: expected an \(n, 3\) array of vertex positions \(numbers\), got dtype <U"),
    (lambda V, F: (V, np.where(np.arange(len(F))[:, None] == 3, 64, F)),
     r"F: triangle 3 refers to vertex 64, but V has 64 rows \(indices are 0-based\)"),
    (lambda V, F: (V, -F), r"F: triangle 0 refers to vertex -\d+, but V has 64 rows"),
    (lambda V, F: (V, F.astype(float)),
     r"F: expected an \(m, 3\) array of integer vertex indices, got dtype float64 \(convert whole numbers"),
    (lambda V, F: (V, F[:, :2]), r"F: expected an \(m, 3\) array of vertex indices \(one triangle a row\), got shape"),
    (lambda V, F: (V, F[:0]), r"F: a mesh needs at least one triangle"),
    (lambda V, F: (np.vstack([V, [[9.0, 9.0, 0.0]]]), F),
     r"mesh arrays: vertex 64 is not used by any triangle \(it would have no mass\)"),
    (lambda V, F: (V, np.vstack([[[0, 0, 1]], F])), r"mesh arrays: triangle 0 \(vertices 0, 0, 1\) repeats a vertex"),
    (lambda V, F: (V + np.where(np.arange(64)[:, None] == 9, [0.0, 0.0, 0.2], 0.0), F),
     r"mesh arrays: no material coordinates \(uv\) given and the mesh is not planar"),
])
def test_bad_arrays_raise_naming_the_array(small_grid, change, message):
    V, F = change(*small_grid)
    with pytest.raises(mgcloth.InputError, match=message):
        mgcloth.Cloth(V, F)


def test_bad_uv_and_pins(small_grid):
    V, F = small_grid
    with pytest.raises(mgcloth.InputError, match=r"uv: has 10 rows but V has 64"):
        mgcloth.Cloth(V, F, uv=np.zeros((10, 2)))
    with pytest.raises(ValueError, match=r"uv: row 2 is not finite"):
        mgcloth.Cloth(V, F, uv=np.where(np.arange(64)[:, None] == 2, np.inf, V[:, :2]))
    with pytest.raises(mgcloth.InputError,
                       match=r'scene: cloths\[0\] \("cloth0"\): cloth "cloth0": pins\[0\]: vertex 64 out of range \(the mesh has 64 vert'):
        mgcloth.Simulation(cloths=[mgcloth.Cloth(V, F, pins=[0, 64])])
    sim = hanging(V, F)
    with pytest.raises(mgcloth.InputError, match=r"targets: expected an \(n, 3\) array of pin targets, got shape \(3,\)"):
        sim.set_pin_targets(np.zeros(3))
    with pytest.raises(mgcloth.InputError, match=r'cloth "cloth0": 1 pin targets given for 2 pinned vertices'):
        sim.set_pin_targets(np.zeros((1, 3)))
    with pytest.raises(mgcloth.InputError, match=r"body: index 1 out of range \(the scene has 1 bodies\)"):
        sim.positions(1)
    with pytest.raises(mgcloth.InputError, match=r"body: expected an index or a name, got 0.5"):
        sim.positions(0.5)
    with pytest.raises(mgcloth.InputError, match=r'no body named "skirt" \(the scene has "cloth0"\)'):
        sim.velocities("skirt")
    with pytest.raises(mgcloth.InputError, match=r"cloth: index 1 out of range \(the scene has 1 cloths\)"):
        sim.triangles(1)


@pytest.mark.parametrize("scene, message", [
    ({"time_stpe": 0.01}, r"scene: time_stpe: unknown key"),
    ({"frames": "ten"}, r'scene: frames: expected an integer, got "ten"'),
    ({"time_step": 0.0}, r"scene: time_step: must be in \[1e-06, 10\], got 0"),
    ({"obstacles": [{"shape": {"type": "sphere", "radius": 0.1, "colour": "red"}}]},
     r"scene: obstacles\[0\].shape.colour: unknown key"),
    ({"solver": {"name": "fmg", "params": {"smoothr": 3}}}, r"solver.params.smoothr"),
    ({"frames": object()}, r"scene: frames: cannot use a object here"),
])
def test_bad_scene_dict_keys_raise_with_the_field(small_grid, scene, message):
    V, F = small_grid
    with pytest.raises(mgcloth.InputError, match=message):
        mgcloth.Simulation(scene, cloths=[mgcloth.Cloth(V, F)])


def test_bad_cloth_fields_and_mesh_conflicts(small_grid):
    V, F = small_grid
    with pytest.raises(mgcloth.InputError, match=r"scene: cloths\[0\].material.youngs_modulos: unknown key"):
        mgcloth.Simulation(cloths=[mgcloth.Cloth(V, F, material={"youngs_modulos": 1e6})])
    with pytest.raises(mgcloth.InputError, match=r"scene: cloths\[0\].mesh: the cloth's mesh is given as arrays"):
        mgcloth._mgcloth.Simulator({"cloths": [{"mesh": {"generator": "rectangle"}}]}, [mgcloth.Mesh(V, F)])
    with pytest.raises(mgcloth.InputError, match=r"scene: cloths: a scene needs at least one cloth or shell"):
        mgcloth.Simulation({})


def test_scene_file_errors_match_the_cli(tmp_path, cli):
    scene = {"cloths": [{"mesh": {"generator": "rectangle", "vertices": 50, "bogus": 1}}]}
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(scene))
    with pytest.raises(mgcloth.InputError) as python_error:
        mgcloth.Simulation(path)
    assert str(python_error.value) == f"{path}: cloths[0].mesh.bogus: unknown key"
    r = cli("run", path, "--out", tmp_path / "out", check=False)
    assert r.returncode == 1 and r.stderr.strip() == f"mgcloth: error: {python_error.value}"
    path.write_text("{\n  \"frames\": 3,\n}")
    with pytest.raises(mgcloth.InputError) as python_error:
        mgcloth.Simulation(path)
    r = cli("run", path, check=False)
    assert r.stderr.strip() == f"mgcloth: error: {python_error.value}"
    with pytest.raises(mgcloth.InputError, match="no such scene file"):
        mgcloth.Simulation(tmp_path / "missing.json")


def test_solver_that_cannot_work_on_the_cloth_fails_at_construction(small_grid):
    V, F = small_grid
    with pytest.raises(mgcloth.InputError, match=r'cloths\[0\] \("cloth0"\): solver rmtr needs a mesh hierarchy of at '
                                                 r'least two levels, but the cloth\'s 64 vertices'):
        mgcloth.Simulation({"solver": {"name": "rmtr"}}, cloths=[mgcloth.Cloth(V, F)])


@pytest.mark.parametrize("vertices", [10**9, 10**12, 5_000_001, 3, -1])
def test_grid_has_the_scenes_vertex_range(vertices):
    # 10**9 used to allocate until the kernel killed the process.
    with pytest.raises(mgcloth.InputError, match=rf"grid: vertices must be in \[4, 5000000\], got {vertices}"):
        mgcloth.grid(1.0, 1.0, vertices)


@pytest.mark.parametrize("width, height", [(0.0, 1.0), (1.0, -2.0), (float("nan"), 1.0), (1.0, float("inf"))])
def test_grid_needs_a_positive_finite_size(width, height):
    with pytest.raises(mgcloth.InputError, match=r"grid: width and height must be positive and finite"):
        mgcloth.grid(width, height, 100)


def test_out_of_memory_names_what_was_built():
    assert issubclass(mgcloth.OutOfMemoryError, mgcloth.Error) and issubclass(mgcloth.OutOfMemoryError, MemoryError)
    # In a child process whose address space may grow by 300 MB only: 5 million vertices need more.
    code = textwrap.dedent("""
        import resource
        import mgcloth
        size = int(next(l for l in open("/proc/self/status") if l.startswith("VmSize")).split()[1]) * 1024
        resource.setrlimit(resource.RLIMIT_AS, (size + 300 * 2**20, resource.RLIM_INFINITY))
        try:
            mgcloth.grid(1.0, 1.0, 5_000_000)
        except mgcloth.OutOfMemoryError as e:
            print("raised:", e)
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "raised: out of memory building a rectangle mesh of about 5000000 vertices" in r.stdout, r.stdout + r.stderr
