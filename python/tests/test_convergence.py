"""The convergence benchmark from Python: its trace as arrays, its files as the CLI writes them."""
import numpy as np
import pytest

import mgcloth

SCENE = {
    "time_step": 1 / 30,
    "threads": 1,
    "cloths": [{"mesh": {"generator": "rectangle", "vertices": 100}, "transform": {"translation": [-0.5, -0.5, 0.3]}}],
    "obstacles": [{"shape": {"type": "sphere", "radius": 0.25}}],
    "solver": {"name": "fmg", "rel_grad": 1e-3, "max_iters": 200},
}


def test_convergence_returns_arrays(tmp_path):
    r = mgcloth.convergence(SCENE, ["newton-direct", "fmg@matrix_update=step"], step=2, max_iters=15, budget=5,
                            out=tmp_path)
    assert r.solvers == ["newton-direct", "fmg@matrix_update=step"] and r.vertices == 100 and r.step == 2
    for label in r.solvers:
        t = r.trace(label)
        assert set(t) == {"iteration", "wall_s", "energy", "grad_norm", "rel_energy_error"}
        n = len(t["iteration"])
        assert n >= 2 and all(len(a) == n for a in t.values())
        assert t["iteration"].dtype.kind == "i" and t["energy"].dtype == np.float64
        np.testing.assert_array_equal(t["iteration"], np.arange(n))
        assert t["rel_energy_error"][0] == 1.0 and t["rel_energy_error"][-1] < 1e-2
        assert np.all(np.diff(t["wall_s"]) >= 0)
    summary = r.summary
    assert [s["solver"] for s in summary["solvers"]] == r.solvers
    assert (tmp_path / "convergence.csv").read_text() == r.csv()
    assert (tmp_path / "convergence.json").exists()
    rows = r.csv().splitlines()[1:]
    assert len(rows) == sum(len(t["iteration"]) for t in r.traces.values())


def test_convergence_rejects_bad_solvers_and_arrays(small_grid):
    with pytest.raises(mgcloth.InputError, match=r'solvers: "fmg" is listed twice'):
        mgcloth.convergence(SCENE, "fmg,fmg")
    with pytest.raises(mgcloth.InputError, match=r"solvers: .*nope"):
        mgcloth.convergence(SCENE, ["nope"])
    V, F = small_grid
    with pytest.raises(mgcloth.InputError, match=r"cloths given as arrays are not supported"):
        mgcloth.convergence({"cloths": [mgcloth.Cloth(V, F)]}, ["fmg"])
