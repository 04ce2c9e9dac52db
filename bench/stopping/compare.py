#!/usr/bin/env python3
"""Stopping rules against a tightly converged run (issue 30, deliverable 4).

Runs copies of scenes/hanging.json and scenes/drape_sphere.json with `mgcloth run --threads 1`, each step stopped by
`rel_grad` alone (e.g. 1e-3, the shipped scenes' rule) or by `velocity_tol` alone (rel_grad 1e-8 as a floor), and
one reference run at rel_grad 1e-8 (max_iters 500). For each run it prints the mean and largest FMG cycles per step,
the steps that hit max_iters, the median of stats.csv's velocity_error (the solver's own estimate; inf where none
was possible), and every 10th frame's RMS and largest vertex distance to the reference.

  /usr/bin/python3 bench/stopping/compare.py --cli build/bin/mgcloth --out /tmp/stopping \\
      --rules rel=1e-3,rel=1e-2,vel=0.1,vel=0.03,vel=0.01

Needs numpy. Runs already in --out are reused (delete a folder to redo it).
"""
import argparse
import csv
import json
import math
import os
import statistics
import subprocess

import numpy as np

SCENES = {"hanging": "scenes/hanging.json", "drape": "scenes/drape_sphere.json"}


def read_obj(path):
    with open(path) as f:
        return np.array([[float(t) for t in line.split()[1:4]] for line in f if line.startswith("v ")])


def run(cli, src, out, name, rule, value, frames):
    folder = os.path.join(out, name)
    if os.path.exists(os.path.join(folder, f"frame_{frames:05d}.obj")):
        return folder
    with open(src) as f:
        s = json.load(f)
    s["frames"] = frames
    solver = s.setdefault("solver", {})
    solver["rel_grad"] = value if rule == "rel" else 1e-8
    solver["max_iters"] = 500 if rule == "ref" else 200
    if rule == "vel":
        solver["velocity_tol"] = value
    s["output"] = {"dir": folder}
    scene = os.path.join(out, name + ".json")
    with open(scene, "w") as f:
        json.dump(s, f, indent=1)
    subprocess.run([cli, "run", scene, "--threads", "1", "-q"], check=True)
    return folder


def row(folder, ref, frames):
    with open(os.path.join(folder, "stats.csv")) as f:
        stats = list(csv.DictReader(f))
    its = [int(r["iterations"]) for r in stats]
    # Empty in runs of binaries before the column existed.
    errors = [float(r["velocity_error"]) for r in stats if r.get("velocity_error")]
    verr = f"{statistics.median(errors):.3g}" if errors else "–"
    dist = []
    for fr in range(10, frames + 1, 10):
        d = np.linalg.norm(read_obj(f"{folder}/frame_{fr:05d}.obj") - read_obj(f"{ref}/frame_{fr:05d}.obj"), axis=1)
        dist.append(f"{1000 * math.sqrt((d ** 2).mean()):.1f} / {1000 * d.max():.0f}")
    maxed = sum(1 for r in stats if r["status"] == "max_iters")
    return f"{statistics.mean(its):.1f} | {max(its)} | {maxed} | {verr} | " + " | ".join(dist)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli", default="build/bin/mgcloth")
    ap.add_argument("--out", required=True)
    ap.add_argument("--scenes", default="hanging,drape")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--rules", default="rel=1e-3,vel=0.01", help="rel=VALUE or vel=VALUE (m/s), comma-separated")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    for key in a.scenes.split(","):
        ref = run(a.cli, SCENES[key], a.out, f"{key}_ref", "ref", 1e-8, a.frames)
        print(f"\n{key} ({SCENES[key]}, {a.frames} frames)\n")
        print("rule | cycles/step mean | max | steps at max_iters | median velocity_error (m/s) | "
              + " | ".join(f"frame {f}: RMS / max mm" for f in range(10, a.frames + 1, 10)))
        print("---|" * (4 + a.frames // 10) + "---")
        print(f"reference rel_grad 1e-8 | {row(ref, ref, a.frames)}")
        for spec in a.rules.split(","):
            rule, value = spec.split("=")
            folder = run(a.cli, SCENES[key], a.out, f"{key}_{rule}{value}", rule, float(value), a.frames)
            label = f"rel_grad {value}" if rule == "rel" else f"velocity_tol {value} m/s"
            print(f"{label} | {row(folder, ref, a.frames)}", flush=True)


if __name__ == "__main__":
    main()
