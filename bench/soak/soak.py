#!/usr/bin/env python3
"""Soak test (issue 25, deliverable 5; not in CI): 10,000 steps of scenes/hanging.json with its own solver on one
thread, then checks of what the run left behind.

    python3 bench/soak/soak.py --cli build/bin/mgcloth --out /tmp/soak [--steps 10000] [--check-only]

The run is `mgcloth run` of the shipped scene with `frames` = --steps (one step per frame) and `output.every` = 500
(20 OBJ frames instead of 10,000), written as OUT/scene.json. Started again on the same OUT it continues with
--resume from the last complete frame (a killed or interrupted soak loses at most the frame in progress; the
resumed frames are bit-identical to an uninterrupted run's). Then it checks, and exits non-zero if any check fails:
the run exited 0; stats.csv has one row per step 1..N in order, every energy and gradient norm finite, every status
converged or stagnated; the last frame's OBJ and checkpoint.bin exist and every position is finite and not far
from the cloth's start (the sheet hangs from its two pinned corners). It prints the steps, the wall time of the
runs, iterations per step (max, mean) and the statuses, for bench/RESULTS.md.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def write_scene(out, steps):
    with open(os.path.join(ROOT, "scenes", "hanging.json")) as f:
        scene = json.load(f)
    scene["frames"] = steps
    scene["threads"] = 1
    scene["output"] = {"dir": out, "every": 500}
    path = os.path.join(out, "scene.json")
    with open(path + ".tmp", "w") as f:
        json.dump(scene, f, indent=2)
    os.replace(path + ".tmp", path)
    return path


def run(cli, out, steps):
    """Runs (or resumes) the soak; returns the exit code and the wall time of this run."""
    resume = os.path.exists(os.path.join(out, "checkpoint.bin"))
    scene = os.path.join(out, "scene.json")
    if not resume:
        write_scene(out, steps)
    cmd = [cli, "run", scene, "--quiet", "--out", out] + (["--resume"] if resume else [])
    print(("resuming: " if resume else "starting: ") + " ".join(cmd), flush=True)
    start = time.monotonic()
    code = subprocess.call(cmd)
    wall = time.monotonic() - start
    with open(os.path.join(out, "soak_runs.txt"), "a") as f:  # every part of a resumed soak, for the total
        f.write(f"{'resume' if resume else 'start'} exit {code} wall {wall:.1f} s\n")
    return code, wall


def check(out, steps):
    failures = []
    with open(os.path.join(out, "stats.csv")) as f:
        header = f.readline().strip().split(",")
        rows = [dict(zip(header, line.rstrip("\n").split(","))) for line in f if line.strip()]
    numbers = [int(r["step"]) for r in rows]
    if numbers != list(range(1, steps + 1)):
        failures.append(f"stats.csv: {len(rows)} rows, steps {numbers[:1]}..{numbers[-1:]}, expected 1..{steps} in order")
    bad = [r["step"] for r in rows if not (math.isfinite(float(r["energy"])) and math.isfinite(float(r["grad_norm"])))]
    if bad:
        failures.append(f"stats.csv: non-finite energy or gradient at steps {bad[:10]}")
    statuses = {}
    for r in rows:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    if set(statuses) - {"converged", "stagnated"}:
        failures.append(f"stats.csv: statuses {statuses}")
    iterations = [int(r["iterations"]) for r in rows]
    solve_ms = [float(r["solve_ms"]) for r in rows]

    written = steps - steps % 500  # the frames output.every writes
    last = os.path.join(out, f"frame_{written:05d}.obj")
    first = os.path.join(out, "frame_00000.obj")
    if not os.path.exists(last) or not os.path.exists(os.path.join(out, "checkpoint.bin")):
        failures.append(f"{last} or checkpoint.bin missing")
        spread = float("nan")
    else:
        def positions(path):
            with open(path) as f:
                return [tuple(map(float, l.split()[1:4])) for l in f if l.startswith("v ")]
        x0, x1 = positions(first), positions(last)
        finite = all(math.isfinite(c) for p in x1 for c in p)
        spread = max(math.dist(a, b) for a, b in zip(x0, x1)) if finite and len(x0) == len(x1) else float("nan")
        lowest = min(p[2] for p in x1) if finite else float("nan")
        if not finite or len(x0) != len(x1):
            failures.append(f"{last}: {len(x1)} vertices (start {len(x0)}), finite: {finite}")
        elif not spread < 2.0:  # a 1 m sheet pinned at two corners moves less than its diagonal
            failures.append(f"{last}: a vertex moved {spread:.3f} m from its start")
        print(f"last frame: {len(x1)} vertices, all finite: {finite}, largest displacement {spread:.4f} m, "
              f"lowest z {lowest:.4f} m")
    print(f"steps: {len(rows)}; iterations per step: max {max(iterations)}, mean {sum(iterations) / len(iterations):.2f}; "
          f"solve time per step: max {max(solve_ms):.0f} ms, mean {sum(solve_ms) / len(solve_ms):.1f} ms; "
          f"statuses {statuses}")
    runs = open(os.path.join(out, "soak_runs.txt")).read() if os.path.exists(os.path.join(out, "soak_runs.txt")) else ""
    print("runs:\n" + runs, end="")
    return failures


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cli", default=os.path.join(ROOT, "build", "bin", "mgcloth"))
    ap.add_argument("--out", required=True)
    ap.add_argument("--steps", type=int, default=10000)
    ap.add_argument("--check-only", action="store_true", help="check an earlier soak's folder without running")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    code = 0
    if not a.check_only:
        code, _ = run(a.cli, a.out, a.steps)
        if code != 0:
            print(f"soak: mgcloth exited with {code}" + (" (interrupted; run again to resume)" if code == 130 else ""))
    failures = check(a.out, a.steps)
    for f in failures:
        print("FAILED:", f)
    print("soak: " + ("passed" if code == 0 and not failures else "FAILED"))
    return 0 if code == 0 and not failures else 1


if __name__ == "__main__":
    sys.exit(main())
