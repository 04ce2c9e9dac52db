#!/usr/bin/env python3
"""Calibrate a cloth's bending stiffness from a cantilever measurement: a sweep, then a fit.

A strip of the cloth (0.1 m x 0.02 m, clamped along its first 0.05 m: scenes/strip_cantilever.json) droops under its
own weight; its tip drop was measured (--target-drop, metres below the clamp). A sweep over bending_stiffness
(log-spaced, mgcloth.run_sweep) gives the drop as a function of the stiffness; the drop falls monotonically with the
stiffness, so the fit interpolates log(stiffness) against log(drop) between the two sweep runs that bracket the
target, then corrects that estimate by secant steps in log-log with single simulations until the simulated drop is
within --tolerance of the target. Prints the table, the fitted stiffness and the bending length c = (B / w)^(1/3).

    PYTHONPATH=build/python python3 examples/calibrate_bending.py --target-drop 0.03 --out out/calibrate_bending

docs/sweeps.md explains the sweep; `mgcloth sweep scenes/sweeps/strip_bending.json --out DIR` (or under
`mpirun -np N`) runs the same kind of sweep from the command line.
"""
import argparse
import math
import os
import sys

import mgcloth

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "scenes", "strip_cantilever.json")
TIP = [0.1, 0.01]  # the free end's middle, in material coordinates (m)


def simulated_drop(stiffness, threads):
    """The strip's tip drop (m) at this bending stiffness, from the scene's quasi-static steps run in memory (the probe
    is the sweep's: the vertex nearest to TIP in material coordinates), and the strip's weight per area (N/m^2)."""
    scene = mgcloth.load_scene(SCENE)
    scene["cloths"][0]["material"]["bending_stiffness"] = stiffness
    scene.pop("output", None)
    sim = mgcloth.Simulation(scene, threads=threads)
    sim.run()
    uv = sim.material_coordinates("strip")
    tip = min(range(len(uv)), key=lambda i: (uv[i][0] - TIP[0]) ** 2 + (uv[i][1] - TIP[1]) ** 2)
    mesh = scene["cloths"][0]["mesh"]
    weight = float(sum(sim.masses("strip"))) * 9.81 / (mesh["width"] * mesh["height"])
    return -float(sim.x[tip][2]), weight


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--target-drop", type=float, default=0.03, help="measured tip drop below the clamp, m")
    ap.add_argument("--out", default="out/calibrate_bending", help="the sweep's folder")
    ap.add_argument("--runs", type=int, default=8, help="sweep runs, log-spaced over [--min, --max]")
    ap.add_argument("--min", type=float, default=1e-6, help="smallest bending stiffness of the sweep, N m")
    ap.add_argument("--max", type=float, default=1e-4, help="largest bending stiffness of the sweep, N m")
    ap.add_argument("--tolerance", type=float, default=1e-4, help="accepted |simulated - target| drop, m")
    ap.add_argument("--threads", type=int, default=1, help="threads per run")
    ap.add_argument("--resume", action="store_true", help="continue the sweep already in --out")
    args = ap.parse_args()
    if not (args.target_drop > 0):
        sys.exit("calibrate_bending: --target-drop must be > 0 (metres below the clamp)")

    sweep = {
        "scene": SCENE,
        "parameters": [{"path": "/cloths/0/material/bending_stiffness", "name": "bending_stiffness",
                        "range": {"start": args.min, "stop": args.max, "count": args.runs, "scale": "log"}}],
        "measures": [{"name": "tip", "type": "probe", "cloth": "strip", "uv": TIP}],
        "frames": "last",
    }
    rows = mgcloth.run_sweep(sweep, args.out, resume=args.resume, threads=args.threads)
    points = []
    print(f"{'bending_stiffness':>18} {'tip drop (m)':>13}  status")
    for r in rows:
        B = r["values"]["bending_stiffness"]
        drop = -r["measures"]["tip_z"] if r["status"] == "ok" else float("nan")
        print(f"{B:18.4e} {drop:13.5f}  {r['status']} {r['message']}")
        if r["status"] == "ok" and drop > 0:
            points.append((B, drop))
    points.sort()
    drops = [d for _, d in points]
    if not points or not (min(drops) <= args.target_drop <= max(drops)):
        sys.exit(f"calibrate_bending: the target drop {args.target_drop} m is outside the sweep's "
                 f"[{min(drops, default=float('nan')):.4f}, {max(drops, default=float('nan')):.4f}] m: widen --min/--max")
    # Bracket and interpolate in log-log (the drop is smooth and monotone in log B).
    for (B0, d0), (B1, d1) in zip(points, points[1:]):
        if min(d0, d1) <= args.target_drop <= max(d0, d1):
            break
    logB = lambda d: math.log(B0) + (math.log(args.target_drop) - math.log(d0)) * \
        (math.log(B1) - math.log(B0)) / (math.log(d1) - math.log(d0))
    B = math.exp(logB(None))
    # Secant steps on log(drop) - log(target) in log B, from the bracket's nearer end.
    prev = (B0, d0) if abs(math.log(d0 / args.target_drop)) < abs(math.log(d1 / args.target_drop)) else (B1, d1)
    for it in range(6):
        d, w = simulated_drop(B, args.threads)
        print(f"fit {it}: bending_stiffness {B:.5e} N m -> drop {d:.5f} m (target {args.target_drop:.5f})")
        if abs(d - args.target_drop) <= args.tolerance:
            break
        slope = (math.log(d) - math.log(prev[1])) / (math.log(B) - math.log(prev[0]))
        prev = (B, d)
        B = math.exp(math.log(B) + (math.log(args.target_drop) - math.log(d)) / slope)
    else:
        sys.exit("calibrate_bending: the fit did not reach the tolerance in 6 simulations")
    print(f"fitted bending_stiffness = {B:.5e} N m (bending length c = (B/w)^(1/3) = {(B / w) ** (1 / 3) * 1e3:.2f} mm "
          f"for the strip's weight per area w = {w:.4f} N/m^2)")


if __name__ == "__main__":
    main()
