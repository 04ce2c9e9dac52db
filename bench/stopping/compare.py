#!/usr/bin/env python3
"""Stopping rules measured step by step (issue 30, deliverable 4).

Runs copies of scenes/hanging.json and scenes/drape_sphere.json with `mgcloth run --threads 1 --check-accuracy`,
each step stopped by `rel_grad` alone (e.g. 1e-3) or by `velocity_tol` alone (rel_grad 1e-8 as a floor). With
--check-accuracy every step's result is compared with its own minimizer (Newton + CHOLMOD solved on from the
result to 1e-8 of the step's initial gradient): stats.csv's true_velocity_error is the largest per-vertex distance
as a velocity (m/s), true_velocity_rms the vertices' RMS. So rules are compared on the error each step leaves,
which does not depend on two runs' trajectories staying together (a cloth sliding off a sphere parts them).

For each run it prints the mean and largest FMG cycles per step, the steps that hit max_iters, the true error's
median, 90th percentile and largest value over the steps, the RMS error's median, and how the solver's own estimate
(velocity_error) compares with the true error (median and smallest ratio). With --reference it also runs rel_grad
1e-8 (max_iters 500) and prints every 10th frame's RMS / largest vertex distance to it.

  /usr/bin/python3 bench/stopping/compare.py --cli build/bin/mgcloth --out /tmp/stopping \\
      --rules rel=1e-3,rel=1e-2,vel=0.1,vel=0.03,vel=0.01

With --solver NAME the rules run with that solver (e.g. one that measures no Newton decrement, which stops by the
gradient's bound under rms=VALUE); --max-iters sets their iteration limit.

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


def run(cli, src, out, name, rule, value, frames, check, solver_name=None, max_iters=200):
    folder = os.path.join(out, name)
    if os.path.exists(os.path.join(folder, f"frame_{frames:05d}.obj")):
        return folder
    with open(src) as f:
        s = json.load(f)
    s["frames"] = frames
    solver = s.setdefault("solver", {})
    solver["rel_grad"] = value if rule == "rel" else 1e-8
    solver["max_iters"] = 500 if rule == "ref" else max_iters
    if solver_name and rule != "ref":
        solver["name"] = solver_name
        solver.pop("params", None)
    if rule == "vel":
        solver["velocity_tol"] = value
    if rule == "rms":
        solver["velocity_rms_tol"] = value
    s["output"] = {"dir": folder}
    scene = os.path.join(out, name + ".json")
    with open(scene, "w") as f:
        json.dump(s, f, indent=1)
    subprocess.run([cli, "run", scene, "--threads", "1", "-q"] + (["--check-accuracy"] if check else []), check=True)
    return folder


def percentile(values, q):
    v = sorted(values)
    return v[min(len(v) - 1, int(q * (len(v) - 1) + 0.5))]


def row(folder, ref, frames):
    with open(os.path.join(folder, "stats.csv")) as f:
        stats = list(csv.DictReader(f))
    its = [int(r["iterations"]) for r in stats]
    maxed = sum(1 for r in stats if r["status"] == "max_iters")
    cells = [f"{statistics.mean(its):.1f}", str(max(its)), str(maxed)]
    true = [float(r["true_velocity_error"]) for r in stats if r.get("true_velocity_error")]
    if true:
        rms = [float(r["true_velocity_rms"]) for r in stats if r.get("true_velocity_rms")]
        ratio = [float(r["velocity_error"]) / float(r["true_velocity_error"]) for r in stats
                 if r.get("true_velocity_error") and r.get("velocity_error") and float(r["true_velocity_error"]) > 0]
        finite = [q for q in ratio if math.isfinite(q)]
        rms_ratio = [float(r["velocity_rms_error"]) / float(r["true_velocity_rms"]) for r in stats
                     if r.get("true_velocity_rms") and r.get("velocity_rms_error") and float(r["true_velocity_rms"]) > 0]
        cells += [f"{statistics.median(true):.2g} / {percentile(true, 0.9):.2g} / {max(true):.2g}",
                  f"{statistics.median(rms):.2g} / {percentile(rms, 0.9):.2g} / {max(rms):.2g}",
                  f"{statistics.median(rms_ratio):.2g} / {min(rms_ratio):.2g}" if rms_ratio else "–",
                  f"{statistics.median(finite):.2g} / {min(finite):.2g} ({len(ratio) - len(finite)} inf)"
                  if finite else "–",
                  f"{len(stats) - len(true)}"]
    if ref:
        for fr in range(10, frames + 1, 10):
            d = np.linalg.norm(read_obj(f"{folder}/frame_{fr:05d}.obj") - read_obj(f"{ref}/frame_{fr:05d}.obj"), axis=1)
            cells.append(f"{1000 * math.sqrt((d ** 2).mean()):.1f} / {1000 * d.max():.0f}")
    return " | ".join(cells)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli", default="build/bin/mgcloth")
    ap.add_argument("--out", required=True)
    ap.add_argument("--scenes", default="hanging,drape")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--rules", default="rel=1e-3,vel=0.01", help="rel=VALUE, vel=VALUE or rms=VALUE (m/s), comma-separated")
    ap.add_argument("--reference", action="store_true", help="also compare frames with a rel_grad 1e-8 run")
    ap.add_argument("--no-check", action="store_true", help="runs without --check-accuracy (frames only)")
    ap.add_argument("--solver", help="run the rules with this solver instead of the scene's (the reference keeps it)")
    ap.add_argument("--max-iters", type=int, default=200, help="the rules' max_iters")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    check = not a.no_check
    for key in a.scenes.split(","):
        ref = run(a.cli, SCENES[key], a.out, f"{key}_ref", "ref", 1e-8, a.frames, False) if a.reference else None
        print(f"\n{key} ({SCENES[key]}, {a.frames} frames)\n")
        head = ["rule", "cycles/step mean", "max", "steps at max_iters"]
        if check:
            head += ["true error (m/s): median / p90 / max", "true RMS error (m/s): median / p90 / max",
                     "RMS estimate / true RMS: median / min",
                     "estimate / true error: median / min", "steps unchecked"]
        if ref:
            head += [f"frame {f}: RMS / max mm" for f in range(10, a.frames + 1, 10)]
        print(" | ".join(head))
        print("|".join(["---"] * len(head)))
        for spec in a.rules.split(","):
            rule, value = spec.split("=")
            prefix = f"{key}_{a.solver}_" if a.solver else f"{key}_"
            folder = run(a.cli, SCENES[key], a.out, f"{prefix}{rule}{value}", rule, float(value), a.frames, check,
                         a.solver, a.max_iters)
            label = {"rel": f"rel_grad {value}", "vel": f"velocity_tol {value} m/s",
                     "rms": f"velocity_rms_tol {value} m/s"}[rule]
            print(f"{label} | {row(folder, ref, a.frames)}", flush=True)


if __name__ == "__main__":
    main()
