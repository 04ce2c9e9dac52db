#!/usr/bin/env python3
"""Solver defaults against single changed settings (issue 25, deliverable 3).

Each configuration runs the same scenes with `mgcloth run --threads 1`, every step solved to the scene's relative
gradient. Runs are interleaved A c1 .. c4 A c5 .. c8 A ... (A = the first configuration, the solver with no
parameters), the rounds one after another, and each run's CPU time is divided by the mean of the A runs
next to it, so that drift in the load of a shared machine cancels; the table gives the median of these ratios over
the rounds. The accuracy check compares every configuration's last frame with the A run's and with a reference
(A solved to a tighter relative gradient).

  python3 bench/defaults/compare.py --cli build/bin/mgcloth --out /tmp/defaults/fmg \
      --configs fmg,fmg@interleave=true,fmg@adaptive_threshold=0.5
"""
import argparse
import csv
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import time

SCENES = {"hanging": ("scenes/hanging.json", 30), "drape": ("scenes/drape_sphere.json", 12)}


def parse_config(spec):
    """NAME@key=value@key=value, values as JSON where they parse (numbers, booleans), else strings."""
    name, *pairs = spec.split("@")
    params = {}
    for p in pairs:
        k, v = p.split("=", 1)
        try:
            params[k] = json.loads(v)
        except json.JSONDecodeError:
            params[k] = v
    return name, params


def write_scene(src, dst, bending, frames, name, params, rel_grad):
    with open(src) as f:
        s = json.load(f)
    for c in s["cloths"]:
        c["material"]["bending"] = bending
    s["frames"] = frames
    solver = s.setdefault("solver", {})
    solver["name"] = name
    solver["params"] = params
    if rel_grad is not None:
        solver["rel_grad"] = rel_grad
        solver["max_iters"] = 1000
    s["output"] = {"dir": "unused", "every": frames}  # frame 0 and the last frame only
    with open(dst, "w") as f:
        json.dump(s, f, indent=1)


def read_obj(path):
    with open(path) as f:
        return [tuple(map(float, l.split()[1:4])) for l in f if l.startswith("v ")]


def run(cli, scene, out, nice):
    cmd = ["nice", "-n", str(nice), cli, "run", scene, "--threads", "1", "--out", out, "-q"]
    t0 = time.time()
    u0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run(cmd, capture_output=True, text=True)
    u1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    wall = time.time() - t0
    rows = []
    if os.path.exists(os.path.join(out, "stats.csv")):
        with open(os.path.join(out, "stats.csv")) as f:
            rows = list(csv.DictReader(f))
    return {
        "rc": r.returncode,
        "err": r.stderr.strip().splitlines()[-1:] if r.returncode else [],
        "wall": wall,
        # CPU time of the whole run: on a loaded machine the wall time also counts the waits for a core
        "cpu": (u1.ru_utime - u0.ru_utime) + (u1.ru_stime - u0.ru_stime),
        "solve": sum(float(x["solve_ms"]) for x in rows) / 1000.0,
        "iters": sum(int(x["iterations"]) for x in rows),
        "steps": len(rows),
        "bad": sum(x["status"] not in ("converged", "stagnated") for x in rows),
    }


def dist(a, b):
    """RMS and largest vertex distance."""
    d = [math.dist(p, q) for p, q in zip(a, b)]
    return math.sqrt(sum(x * x for x in d) / len(d)), max(d)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli", default="build/bin/mgcloth")
    ap.add_argument("--out", required=True)
    ap.add_argument("--configs", required=True, help="comma-separated; the first is the baseline A")
    ap.add_argument("--scenes", default="hanging,drape")
    ap.add_argument("--frames", default="", help="e.g. hanging=30,drape=12 (default: those)")
    ap.add_argument("--bending", default="quadratic")
    ap.add_argument("--rel-grad", type=float, default=None, help="override the scenes' rel_grad (1e-3)")
    ap.add_argument("--reference-rel-grad", type=float, default=1e-5, help="0: no reference run")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--group", type=int, default=4, help="configurations between two baseline runs")
    ap.add_argument("--nice", type=int, default=10)
    a = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    frames = {k: v[1] for k, v in SCENES.items()}
    for kv in filter(None, a.frames.split(",")):
        k, v = kv.split("=")
        frames[k] = int(v)
    configs = a.configs.split(",")
    base, others = configs[0], configs[1:]
    os.makedirs(a.out, exist_ok=True)
    table = []
    for sc in a.scenes.split(","):
        src = os.path.join(root, SCENES[sc][0])
        paths = {}
        for i, c in enumerate(configs):
            paths[c] = os.path.join(a.out, f"{sc}_{i}.json")
            write_scene(src, paths[c], a.bending, frames[sc], *parse_config(c), a.rel_grad)
        last = f"frame_{frames[sc]:05d}.obj"
        ref_x = None
        if a.reference_rel_grad > 0:  # the baseline solver to a tighter relative gradient
            ref_scene = os.path.join(a.out, f"{sc}_ref.json")
            write_scene(src, ref_scene, a.bending, frames[sc], *parse_config(base), a.reference_rel_grad)
            ref_out = os.path.join(a.out, f"{sc}_ref")
            ref = run(a.cli, ref_scene, ref_out, a.nice)
            ref_x = read_obj(os.path.join(ref_out, last))
            print(f"# {sc}: reference {base} to rel_grad {a.reference_rel_grad}: {ref['solve']:.1f} s", file=sys.stderr)
        runs = {c: [] for c in configs}
        seq = [base]  # A c1 .. cg A c(g+1) .. A, the rounds one after the other, sharing the A between them
        for _ in range(a.reps):
            for g in range(0, len(others), a.group):
                seq.extend(others[g:g + a.group])
                seq.append(base)
        results = []
        for k, c in enumerate(seq):
            out = os.path.join(a.out, f"{sc}_{configs.index(c)}_{k}")
            r = run(a.cli, paths[c], out, a.nice)
            r["x"] = read_obj(os.path.join(out, last)) if r["rc"] == 0 else None
            results.append((c, r))
            print(f"# {sc} run {k} {c}: {r['cpu']:.2f} s CPU, {r['solve']:.2f} s solve, {r['iters']} iterations,"
                  f" rc {r['rc']}", file=sys.stderr)
        for i, (c, r) in enumerate(results):
            if c == base:
                r["ratio"] = r["wall_ratio"] = 1.0
            else:
                prev = next(rr for cc, rr in reversed(results[:i]) if cc == base)
                nxt = next(rr for cc, rr in results[i + 1:] if cc == base)
                r["ratio"] = r["cpu"] / ((prev["cpu"] + nxt["cpu"]) / 2)
                r["wall_ratio"] = r["solve"] / ((prev["solve"] + nxt["solve"]) / 2)
            runs[c].append(r)
        base_x = runs[base][0]["x"]
        for c in configs:
            rs = runs[c]
            ok = [r for r in rs if r["rc"] == 0]
            table.append({
                "scene": sc, "config": c,
                "cpu": statistics.median(r["cpu"] for r in rs),
                "wall_ratio": statistics.median(r["wall_ratio"] for r in rs),
                "ratio": statistics.median(r["ratio"] for r in rs),
                "ratios": [r["ratio"] for r in rs],
                "iters": statistics.median(r["iters"] for r in rs),
                "bad": max(r["bad"] for r in rs),
                "failed": len(rs) - len(ok),
                "d_base": dist(ok[0]["x"], base_x) if ok else (math.nan, math.nan),
                "d_ref": dist(ok[0]["x"], ref_x) if ok and ref_x else (math.nan, math.nan),
                "err": next((r["err"] for r in rs if r["err"]), []),
            })
    print(f"bending {a.bending}, rel_grad {a.rel_grad or 'of the scene'}, {a.reps} rounds, frames {frames}")
    print("| scene | configuration | CPU s (median) | CPU time / default (median) | per round"
          " | solve wall time / default (median) | iterations | unconverged steps"
          " | last frame vs default (RMS, max) | vs reference (RMS) |")
    print("|---|---|---:|---:|---|---:|---:|---:|---:|---:|")
    for t in table:
        rounds = "–" if t["config"] == base else " ".join(f"{x:.2f}" for x in t["ratios"])
        fail = f" ({t['failed']} runs failed: {t['err']})" if t["failed"] else ""
        print(f"| {t['scene']} | `{t['config']}` | {t['cpu']:.2f} | {t['ratio']:.2f} | {rounds} |"
              f" {t['wall_ratio']:.2f} | {t['iters']:.0f} | {t['bad']} |"
              f" {t['d_base'][0]:.1e}, {t['d_base'][1]:.1e} m | {t['d_ref'][0]:.1e} m |{fail}")


if __name__ == "__main__":
    main()
