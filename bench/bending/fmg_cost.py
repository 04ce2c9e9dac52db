#!/usr/bin/env python3
"""What the consistent bending model's wider stencil costs the FMG solve: each shipped scene run with its cloth's
`bending` set to each model, the models interleaved (A B A B ...) so that load on a shared machine falls on both;
prints per model the median over repeats of the total solve time, the FMG cycles, and ms per cycle.

    python3 bench/bending/fmg_cost.py [--mgcloth build/bin/mgcloth] [--repeats 3] [--threads 1]
"""
import argparse, csv, json, os, statistics, subprocess, sys, tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ap = argparse.ArgumentParser()
ap.add_argument("--mgcloth", default=os.path.join(ROOT, "build", "bin", "mgcloth"))
ap.add_argument("--repeats", type=int, default=3)
ap.add_argument("--threads", type=int, default=1)
ap.add_argument("--models", default="hinge,quadratic")
ap.add_argument("--scenes", default="hanging.json:60,drape_sphere.json:30")
a = ap.parse_args()
models = a.models.split(",")

tmp = tempfile.mkdtemp(prefix="fmg_cost_")
print(f"{'scene':18} {'model':10} {'solve s':>9} {'cycles':>7} {'ms/cycle':>9}  (median of {a.repeats})")
for item in a.scenes.split(","):
    name, frames = item.split(":")
    scene = json.load(open(os.path.join(ROOT, "scenes", name)))
    results = {m: [] for m in models}
    for rep in range(a.repeats):
        for m in models:
            s = json.loads(json.dumps(scene))
            for c in s["cloths"]:
                c.setdefault("material", {})["bending"] = m
            path = os.path.join(tmp, f"{m}.json")
            json.dump(s, open(path, "w"))
            out = os.path.join(tmp, f"out_{m}")
            subprocess.run([a.mgcloth, "run", path, "--frames", frames, "--threads", str(a.threads), "--out", out,
                            "--quiet"], check=True)
            rows = list(csv.DictReader(open(os.path.join(out, "stats.csv"))))
            solve = sum(float(r["solve_ms"]) for r in rows) / 1e3
            cycles = sum(int(r["iterations"]) for r in rows)
            if any(r["status"] not in ("converged", "stagnated") for r in rows):
                print(f"  {name} {m}: statuses {sorted(set(r['status'] for r in rows))}", file=sys.stderr)
            results[m].append((solve, cycles))
    for m in models:
        solve = statistics.median(r[0] for r in results[m])
        cycles = statistics.median(r[1] for r in results[m])
        print(f"{name:18} {m:10} {solve:9.2f} {cycles:7.0f} {1e3 * solve / cycles:9.1f}")
    base = statistics.median(r[0] for r in results[models[0]])
    for m in models[1:]:
        print(f"{'':18} {m} / {models[0]}: {statistics.median(r[0] for r in results[m]) / base:.2f}x solve time")
