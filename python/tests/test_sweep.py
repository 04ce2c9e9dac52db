"""mgcloth.run_sweep: a sweep from a dict, a failing run among good ones, resuming; and the calibration example
(examples/calibrate_bending.py) run as a user runs it."""
import os
import subprocess
import sys

import pytest

import mgcloth

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
STRIP = os.path.join(ROOT, "scenes", "strip_cantilever.json")


def strip_sweep(densities):
    return {
        "scene": STRIP,
        "parameters": [{"path": "/cloths/0/material/density", "name": "density", "values": densities},
                       {"path": "/frames", "values": [6]}],
        "measures": [{"name": "tip", "type": "probe", "cloth": "strip", "uv": [0.1, 0.01]},
                     {"name": "E", "type": "energy"}],
        "threads": 1,
    }


def test_a_sweep_from_a_dict_records_failures_and_resumes(tmp_path):
    out = tmp_path / "sweep"
    rows = mgcloth.run_sweep(strip_sweep([300, -1, 600]), out)
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    assert "density" in rows[1]["message"]
    assert rows[0]["values"] == {"density": 300, "frames": 6}
    assert rows[0]["last_frame"] == 6 and rows[0]["folder"] == os.path.join("runs", "00000")
    assert rows[0]["measures"]["tip_z"] < 0 and rows[2]["measures"]["tip_z"] < rows[0]["measures"]["tip_z"]
    assert (out / "summary.csv").exists() and (out / "runs" / "00002" / "frame_00006.obj").exists()
    first = (out / "runs" / "00000" / "result.json").read_bytes()
    again = mgcloth.run_sweep(strip_sweep([300, -1, 600]), out, resume=True)
    assert [r["measures"] for r in again] == [r["measures"] for r in rows]
    assert (out / "runs" / "00000" / "result.json").read_bytes() == first  # not run again
    with pytest.raises(mgcloth.InputError, match="--resume"):
        mgcloth.run_sweep(strip_sweep([300, -1, 600]), out)
    with pytest.raises(mgcloth.InputError, match=r"parameters\[0\]"):
        mgcloth.run_sweep({"scene": STRIP, "parameters": [{"path": "/cloths/0/material/densty", "values": [1]}]},
                          tmp_path / "bad")
    with pytest.raises(mgcloth.InputError, match="retry_failed"):
        mgcloth.run_sweep(strip_sweep([300]), tmp_path / "x", retry_failed=True)


def test_the_calibration_example_fits_the_target_drop(tmp_path):
    env = dict(os.environ)
    r = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "calibrate_bending.py"), "--target-drop", "0.03",
                        "--runs", "5", "--out", str(tmp_path / "cal")], env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    last_fit = [line for line in r.stdout.splitlines() if line.startswith("fit ")][-1]
    drop = float(last_fit.split("-> drop ")[1].split()[0])
    assert abs(drop - 0.03) <= 1e-4
    assert "fitted bending_stiffness" in r.stdout
    # Out of the sweep's range: a clear message and a non-zero exit.
    r = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "calibrate_bending.py"), "--target-drop", "0.2",
                        "--runs", "3", "--out", str(tmp_path / "far")], env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode != 0 and "outside the sweep's" in r.stderr


def test_ctrl_c_stops_a_sweep_after_its_frame_and_resume_continues(tmp_path):
    import signal
    import threading

    out = tmp_path / "interrupted"
    sweep = strip_sweep([300, 200, 150, 400, 500, 600, 250, 350])
    sweep["parameters"][1]["values"] = [20]  # ~0.5 s a run: the signal lands inside the sweep
    timer = threading.Timer(0.8, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            mgcloth.run_sweep(sweep, out)
    finally:
        timer.join()
    rows = mgcloth.run_sweep(sweep, out, resume=True)
    assert [r["status"] for r in rows] == ["ok"] * 8
    assert any(r["resumed_from"] >= 0 for r in rows)  # the run the signal stopped went on from its checkpoint
