"""A Python run writes the output folder `mgcloth run` writes, bit for bit (same scene, solver and threads)."""
import json

import numpy as np
import pytest

import mgcloth

# The drape of scenes/drape_sphere.json at 144 vertices and 6 frames, on one thread.
SCENE = {
    "time_step": 1 / 30,
    "frames": 6,
    "threads": 1,
    "cloths": [{
        "name": "cloth",
        "mesh": {"generator": "rectangle", "width": 1.0, "height": 1.0, "vertices": 144},
        "transform": {"translation": [-0.5, -0.5, 0.3]},
    }],
    "obstacles": [{"name": "sphere", "shape": {"type": "sphere", "radius": 0.25}, "friction": 0.3}],
    "solver": {"name": "fmg", "rel_grad": 1e-3, "max_iters": 200},
}
# stats.csv columns that hold wall times
TIMING = {"wall_ms", "solve_ms", "contact_detection_ms", "check_ms"}


def stats_without_timing(path):
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    keep = [i for i, name in enumerate(header) if name not in TIMING]
    return [[row.split(",")[i] for i in keep] for row in lines]


def frames(folder):
    return sorted(p.name for p in folder.glob("frame_*.obj"))


def obj_positions(path):
    return np.array([[float(t) for t in line.split()[1:4]] for line in path.read_text().splitlines()
                     if line.startswith("v ")])


def assert_same_run(a, b, same_checkpoint_header):
    assert frames(a) == frames(b) and len(frames(a)) == SCENE["frames"] + 1
    for name in frames(a):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert stats_without_timing(a / "stats.csv") == stats_without_timing(b / "stats.csv")
    ca, cb = (a / "checkpoint.bin").read_bytes(), (b / "checkpoint.bin").read_bytes()
    # magic (8 bytes), then the scene's fingerprint (8), which names the mesh source; then the state; then the
    # checksum of all of it (8), which differs with the fingerprint
    assert (ca if same_checkpoint_header else ca[16:-8]) == (cb if same_checkpoint_header else cb[16:-8])


@pytest.mark.parametrize("solver", ["fmg", "newton-direct"])
def test_drape_from_arrays_matches_the_cli_bit_for_bit(tmp_path, cli, solver):
    scene = json.loads(json.dumps(SCENE))
    scene["solver"]["name"] = solver
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    cli("run", tmp_path / "scene.json", "--out", tmp_path / "cli", "--quiet")

    # The same cloth as NumPy arrays: the generator's mesh, passed in memory.
    V, F = mgcloth.grid(1.0, 1.0, 144)
    sim = mgcloth.Simulation(
        cloths=[mgcloth.Cloth(V, F, name="cloth", translation=(-0.5, -0.5, 0.3))],
        obstacles=[mgcloth.Sphere(0.25, name="sphere", friction=0.3)],
        dt=1 / 30, frames=6, threads=1, solver=solver, rel_grad=1e-3, max_iters=200, out=tmp_path / "py")
    stats = sim.run()
    assert len(stats) == 6 and sim.frame == 6
    assert_same_run(tmp_path / "cli", tmp_path / "py", same_checkpoint_header=False)
    assert np.array_equal(sim.x, obj_positions(tmp_path / "py" / "frame_00006.obj"))
    energies = [float(row[5]) for row in stats_without_timing(tmp_path / "py" / "stats.csv")[1:]]
    assert energies == [s.energy for s in stats]


def test_scene_file_run_writes_the_cli_folder(tmp_path, cli):
    (tmp_path / "scene.json").write_text(json.dumps(SCENE))
    cli("run", tmp_path / "scene.json", "--out", tmp_path / "cli", "--quiet")
    mgcloth.Simulation(tmp_path / "scene.json", out=tmp_path / "py").run()
    assert_same_run(tmp_path / "cli", tmp_path / "py", same_checkpoint_header=True)
    a = json.loads((tmp_path / "cli" / "scene.resolved.json").read_text())
    b = json.loads((tmp_path / "py" / "scene.resolved.json").read_text())
    assert a.pop("output")["dir"] != b.pop("output")["dir"]
    assert a == b


def test_the_resolved_scene_of_an_arrays_run_runs_in_the_cli(tmp_path, cli):
    V, F = mgcloth.grid(1.0, 1.0, 144)
    sim = mgcloth.Simulation(SCENE | {"cloths": [mgcloth.Cloth(V, F, translation=(-0.5, -0.5, 0.3))]},
                             out=tmp_path / "py")
    sim.run()
    resolved = json.loads((tmp_path / "py" / "scene.resolved.json").read_text())
    assert resolved["cloths"][0]["mesh"]["file"] == str(tmp_path / "py" / "cloth0_mesh.obj")
    cli("run", tmp_path / "py" / "scene.resolved.json", "--out", tmp_path / "cli", "--quiet")
    # The OBJ reader parses decimals to within a few ulps, so the CLI's start differs by rounding only.
    x = obj_positions(tmp_path / "cli" / "frame_00006.obj")
    assert np.abs(x - sim.x).max() < 1e-9


def test_resume_continues_an_arrays_run_as_if_uninterrupted(tmp_path):
    V, F = mgcloth.grid(1.0, 1.0, 144)

    def simulation(out, resume=False):
        cloth = mgcloth.Cloth(V, F, name="cloth", translation=(-0.5, -0.5, 0.3))
        return mgcloth.Simulation(SCENE | {"cloths": [cloth]}, out=out, resume=resume)

    simulation(tmp_path / "whole").run()
    first = simulation(tmp_path / "parts")
    first.run(3)
    del first
    second = simulation(tmp_path / "parts", resume=True)
    assert second.frame == 3
    second.run()
    # The fingerprints differ: the scenes name their mesh files in their own folders.
    assert_same_run(tmp_path / "whole", tmp_path / "parts", same_checkpoint_header=False)
