#!/usr/bin/env python3
"""One objective over several bodies against one solve per body (issue 27, deliverable 2).

    python3 bench/joint_solve/compare.py --cli build/bin/mgcloth [--out /tmp/joint] [--frames 20] [--reps 3]
        [--solvers fmg,newton-direct]

Scenes: copies of scenes/hanging.json side by side, of different resolutions (the bodies' hierarchies then differ in
depth), solved with "solve_bodies": "jointly" and "separately", each run by `mgcloth run --threads 1`, the modes
interleaved and repeated; the solve time is the sum of stats.csv's wall_ms (median over the repetitions). Also the
largest distance between the two modes' last frames (both solve the same decoupled problems, to the same rel_grad
of each solve, so they differ by the solves' tolerance only). Prints a Markdown table for bench/RESULTS.md.
"""
import argparse
import csv
import json
import os
import statistics
import subprocess

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

SCENES = {
    "two cloths (4,000 + 1,000 vertices)": [4000, 1000],
    "four cloths (4,000 + 2,000 + 1,000 + 500 vertices)": [4000, 2000, 1000, 500],
}


def scene(vertices, solver, frames, jointly):
    with open(os.path.join(ROOT, "scenes", "hanging.json")) as f:
        base = json.load(f)
    cloth = base["cloths"][0]
    cloths = []
    for k, n in enumerate(vertices):
        c = json.loads(json.dumps(cloth))
        c["name"] = f"cloth{k}"
        c["mesh"]["vertices"] = n
        c["transform"]["translation"][0] += 1.5 * k
        cloths.append(c)
    base["cloths"] = cloths
    base["frames"] = frames
    base["threads"] = 1
    base["solver"]["name"] = solver
    base["solve_bodies"] = "jointly" if jointly else "separately"
    return base


def run(cli, out, s):
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, "scene.json")
    with open(path, "w") as f:
        json.dump(s, f)
    subprocess.run([cli, "run", path, "-q", "--out", out], check=True)
    with open(os.path.join(out, "stats.csv")) as f:
        rows = list(csv.DictReader(f))
    ms = sum(float(r["wall_ms"]) for r in rows)
    iters = sum(int(r["iterations"]) for r in rows)
    frame = s["frames"]
    with open(os.path.join(out, f"frame_{frame:05d}.obj")) as f:
        verts = [tuple(map(float, line.split()[1:4])) for line in f if line.startswith("v ")]
    return ms, iters, verts, rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", default=os.path.join(ROOT, "build", "bin", "mgcloth"))
    ap.add_argument("--out", default="/tmp/joint_solve")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--solvers", default="fmg,newton-direct")
    a = ap.parse_args()
    print("| scene | solver | jointly: solve time, iterations | separately: solve time, iterations | jointly / separately | largest distance between the modes' last frames |")
    print("|---|---|---|---|---|---|")
    for name, vertices in SCENES.items():
        for solver in a.solvers.split(","):
            times = {True: [], False: []}
            result = {}
            for rep in range(a.reps):
                for jointly in (True, False):
                    out = os.path.join(a.out, f"{len(vertices)}_{solver}_{'joint' if jointly else 'separate'}")
                    ms, iters, verts, rows = run(a.cli, out, scene(vertices, solver, a.frames, jointly))
                    times[jointly].append(ms)
                    result[jointly] = (iters, verts, rows)
            dist = max(sum((p - q) ** 2 for p, q in zip(u, w)) ** 0.5 for u, w in zip(result[True][1], result[False][1]))
            tj, ts = statistics.median(times[True]), statistics.median(times[False])
            print(f"| {name} | {solver} | {tj / 1000:.2f} s, {result[True][0]} | {ts / 1000:.2f} s, {result[False][0]} "
                  f"| {tj / ts:.2f} | {dist:.2e} m |", flush=True)


if __name__ == "__main__":
    main()
