"""Summarizes bench/table1/run.sh OUT: Wang 2018's Table 1 columns per scene, measured on this machine.

Per scene: cloth vertices and triangles and smoother colors per level (from `mgcloth hierarchy`), then from the
run's stats.csv: FMG cycles per step (min to max, mean), ms per cycle (the solve's time over its cycles, contact
energy and its detection inside the cycle included), ms per frame (every step's wall time, the intersection
checker excluded), and the contact share: collision detection's part of the step (broad phase, distances, CCD).
Sewn garments also get the widest seam gap after their first 5 frames (stats.csv's seam_gap, written since 9374e7c;
rows that older binaries wrote leave it empty).
"""
import csv, json, pathlib, sys

out = pathlib.Path(sys.argv[1])
paper = {"funnel": "120K / 238K, 6–13 colors, 100 ms/cycle, 200 ms/step",
         "dress": "132K / 264K, 5–14 colors, 111 ms/cycle, 333 ms/step",
         "gown": "104K / 208K, 5–12 colors, 84 ms/cycle, 252 ms/step"}
print("| scene | vertices | triangles | colors (levels) | steps | FMG cycles/step min–max (mean) | ms/cycle | "
      "ms/frame | contact share | checker ms/step | intersections | widest seam gap after frame 5 | "
      "Wang 2018 (GTX 1080, no collisions) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for d in sorted(p for p in out.iterdir() if (p / "run" / "stats.csv").exists()):
    levels = []
    for h in sorted((d / "hierarchy").glob("*/hierarchy.json")):
        levels += json.load(open(h))["levels"]
    verts = sum(l["vertices"] for l in levels if l["level"] == 0)
    tris = sum(l["triangles"] for l in levels if l["level"] == 0)
    colors = [l["colors"] for l in levels]
    rows = list(csv.DictReader(open(d / "run" / "stats.csv")))
    if not rows:
        continue  # a run interrupted in its first frame
    its = [int(r["iterations"]) for r in rows]
    solve = sum(float(r["solve_ms"]) for r in rows)
    wall = sum(float(r["wall_ms"]) for r in rows)
    check = sum(float(r["check_ms"]) for r in rows)
    detect = sum(float(r["contact_detection_ms"]) for r in rows)
    frames = len({r["frame"] for r in rows})
    inter = sum(int(r["intersections"]) for r in rows)
    gaps = [float(r["seam_gap"]) for r in rows if int(r["frame"]) > 5 and r.get("seam_gap")]
    gap = f"{1000 * max(gaps):.2f} mm ({len(gaps)} steps)" if gaps else "–"
    print(f"| {d.name} | {verts:,} | {tris:,} | {min(colors)}–{max(colors)} ({len(colors)}) | {len(rows)} | "
          f"{min(its)}–{max(its)} ({sum(its) / len(rows):.1f}) | {solve / max(sum(its), 1):.0f} | "
          f"{(wall - check) / frames:.0f} | {detect / max(wall - check, 1e-9):.0%} | {check / len(rows):.0f} | {inter} | {gap} | "
          f"{paper.get(d.name, '')} |")
