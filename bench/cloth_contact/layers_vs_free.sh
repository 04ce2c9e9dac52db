#!/usr/bin/env bash
# The layered drape (scenes/layers_sphere.json, five sheets) with and without cloth contact, same solver and
# frames, run one after the other on a quiet machine: FMG cycles and wall time per step, and what contact adds.
# Usage: bench/cloth_contact/layers_vs_free.sh VERTICES_PER_SHEET FRAMES THREADS [OUT]
set -euo pipefail
per_sheet=${1:-2000}; frames=${2:-15}; threads=${3:-2}; out=${4:-out/bench_cloth_contact}
cli=${MGCLOTH_CLI:-build/bin/mgcloth}
mkdir -p "$out"
python3 - "$per_sheet" "$frames" "$out" <<'PY'
import json, sys
n, frames, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
d = json.load(open("scenes/layers_sphere.json"))
for c in d["cloths"]: c["mesh"]["vertices"] = n
d["frames"] = frames
json.dump(d, open(f"{out}/with.json", "w"))
d["cloth_contact"]["check_intersections"] = False
json.dump(d, open(f"{out}/unchecked.json", "w"))
del d["cloth_contact"]
json.dump(d, open(f"{out}/without.json", "w"))
PY
for v in without with unchecked; do
  OMP_WAIT_POLICY=passive "$cli" run "$out/$v.json" --out "$out/$v" -q -j "$threads"
done
python3 - "$out" <<'PY'
import csv, sys
out = sys.argv[1]
rows = {v: list(csv.DictReader(open(f"{out}/{v}/stats.csv"))) for v in ("without", "with", "unchecked")}
names = {"without": "no cloth contact", "with": "cloth contact", "unchecked": "cloth contact, no intersection checker"}
def tot(v, k): return sum(float(r[k]) for r in rows[v])
print("| | steps | FMG cycles | wall s | ms per step | ms per cycle |")
print("|---|---|---|---|---|---|")
for v in ("without", "with", "unchecked"):
    s, c, w = len(rows[v]), tot(v, "iterations"), tot(v, "wall_ms") / 1000
    print(f"| {names[v]} | {s} | {c:.0f} | {w:.1f} | {1000*w/s:.0f} | {1000*w/c:.1f} |")
w0, w1 = tot("without", "wall_ms"), tot("with", "wall_ms")
w2 = tot("unchecked", "wall_ms")
print(f"\nwith / without: {w1/w0:.2f}x wall time ({w2/w0:.2f}x without the checker), {tot('with','iterations')/tot('without','iterations'):.2f}x cycles; "
      f"intersections (with): {sum(int(r['intersections']) for r in rows['with'])}, "
      f"smallest min_distance: {min(float(r['min_distance']) for r in rows['with']):.3g} m")
PY
