"""Summarizes bench/obstacle_rounds/run.sh: per run, steps, FMG cycles, re-solves, wall time, intersections."""
import csv, pathlib, sys

out = pathlib.Path(sys.argv[1])
print("| run | steps | FMG cycles | cycles/step (max) | re-solves | steps with re-solves | re-solves/step (max) | wall s | s per frame | intersections | min distance mm |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for d in sorted(p for p in out.iterdir() if p.is_dir() and (p / "stats.csv").exists()):
    rows = list(csv.DictReader(open(d / "stats.csv")))
    its = [int(r["iterations"]) for r in rows]
    rounds = [int(r["obstacle_rounds"]) for r in rows]
    wall = sum(float(r["wall_ms"]) for r in rows) / 1e3
    frames = max(int(r["frame"]) for r in rows)
    inter = sum(int(r["intersections"]) for r in rows)
    dmin = min(float(r["min_distance"]) for r in rows)
    print(f"| {d.name} | {len(rows)} | {sum(its)} | {sum(its)/len(rows):.1f} ({max(its)}) | {sum(rounds)} | "
          f"{sum(1 for r in rounds if r)} | {sum(rounds)/len(rows):.2f} ({max(rounds)}) | {wall:.1f} | {wall/frames:.2f} | {inter} | {1e3*dmin:.2f} |")
