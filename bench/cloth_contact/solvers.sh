#!/usr/bin/env bash
# FMG against Newton + CHOLMOD and Newton + PCG/BoomerAMG on one frozen step of the layered drape with cloth
# contact (scenes/layers_sphere.json: five sheets, solved jointly with the contact term; issue 28, deliverable 6):
# `mgcloth bench convergence` from the same start point for each, then the time to a relative energy error of 1e-3
# and its ratio to FMG's, as a markdown table. Every solver's end is checked by the exact intersection checker.
# STEP must be one where the sheets touch (at 30 fps they lie on each other from about step 5; 8 is well into it).
# Run it on a quiet machine: the times are wall times.
# Usage: bench/cloth_contact/solvers.sh VERTICES_PER_SHEET STEP THREADS [OUT]
# Environment: BUDGET (seconds per solver, default 60), SOLVERS (default fmg,newton-direct,newton-amg; the first is
# the one the ratios are to), MGCLOTH_CLI (default build/bin/mgcloth).
set -euo pipefail
if [[ $# -lt 3 ]]; then
  echo "usage: $0 VERTICES_PER_SHEET STEP THREADS [OUT]" >&2
  exit 2
fi
per_sheet=$1; step=$2; threads=$3; out=${4:-out/bench_cloth_contact_solvers_${per_sheet}_step${step}}
budget=${BUDGET:-60}
solvers=${SOLVERS:-fmg,newton-direct,newton-amg}
cli=${MGCLOTH_CLI:-build/bin/mgcloth}
mkdir -p "$out"
# The state at the start of the step and E* are cached next to the results: a rerun (another budget, another
# solver) skips the simulated steps and the reference solve.
OMP_WAIT_POLICY=passive "$cli" bench convergence scenes/layers_sphere.json --step "$step" --vertices "$per_sheet" \
  --solvers "$solvers" --budget "$budget" -j "$threads" --state-cache "$out/state.bin" --out "$out" -q \
  > "$out/summary.txt" || { cat "$out/summary.txt" >&2; exit 1; }
python3 - "$out" <<'PY'
import csv, json, sys
out = sys.argv[1]
j = json.load(open(f"{out}/convergence.json"))
rows = list(csv.DictReader(open(f"{out}/convergence.csv")))
ref = j["references"][0]
x0 = j.get("contact_at_x0") or {}
print(f"{j['scene']}, step {j['step']}: {len(j['bodies'])} sheets solved jointly, {j['vertices']} vertices in all, "
      f"{j['options']['threads']} threads, budget {j['options']['budget_seconds']:g} s per solver")
dist0 = x0.get("min_distance")
print(f"at x0: {x0.get('contact_pairs')} contact pairs, min distance {'-' if dist0 is None else f'{dist0:.4g}'} m, "
      f"{x0.get('intersections')} intersections; E* = {ref['energy']:.12e} by {ref['solver']} "
      f"({ref['iterations']} iterations, relative gradient {ref['rel_grad']:.1e})")
print()
def first_iteration(solver, level):
    for r in rows:
        if r["solver"] == solver and float(r["rel_energy_error"]) <= level:
            return int(r["iteration"])
    return None
base = j["solvers"][0]
t_base = base["time_to"]["1e-03"]
print("| solver | time to 1e-3 (s) | ratio to " + base["solver"] + " | iterations to 1e-3 | final error | status "
      "| intersections at end | min distance at end (m) |")
print("|---|---|---|---|---|---|---|---|")
for s in j["solvers"]:
    t = s["time_to"]["1e-03"]
    if t is None:
        time, ratio = f"not reached in {s['seconds']:.1f}", (f"> {s['seconds'] / t_base:.1f}" if t_base else "-")
    else:
        time, ratio = f"{t:.3f}", (f"{t / t_base:.2f}" if t_base else "-")
    it = first_iteration(s["solver"], 1e-3)
    end = s.get("contact_at_end") or {}
    err, dist = s["final_error"], end.get("min_distance")
    print(f"| {s['solver']} | {time} | {ratio} | {'-' if it is None else it} | {'-' if err is None else f'{err:.1e}'} "
          f"| {s['status']} | {end.get('intersections', '-')} | {'-' if dist is None else f'{dist:.4g}'} |")
bad = [s["solver"] for s in j["solvers"] if (s.get("contact_at_end") or {}).get("intersections", 0) != 0]
if bad or x0.get("intersections", 0) != 0:
    print(f"\nINTERSECTIONS: {', '.join(bad) or 'x0'}")
    sys.exit(1)
PY
