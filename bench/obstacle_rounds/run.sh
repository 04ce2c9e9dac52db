#!/usr/bin/env bash
# The re-solves a step needs while a mesh obstacle is short of its pose (stats.csv obstacle_rounds), on
# scenes/poncho_walk.json (4,000-vertex poncho on the generated walking body, 1 s standing, then walking):
# substeps 1 and 2, and (with a binary given as $NOCARRY built without Assembly::carry_swept) the baseline that
# carries only the cloth already in contact. Usage: bench/obstacle_rounds/run.sh OUT [FRAMES]
set -euo pipefail
out=${1:?usage: run.sh OUT [FRAMES]}
frames=${2:-90}
bin=${MGCLOTH:-build/bin/mgcloth}
mkdir -p "$out"
for sub in 1 2; do
  /usr/bin/python3 - "$sub" "$out/poncho_s$sub.json" <<'PY'
import json, sys
s = json.load(open("scenes/poncho_walk.json"))
s["substeps"] = int(sys.argv[1])
s["output"] = {"dir": sys.argv[2][:-5], "format": ["obj"], "every": 1000}
json.dump(s, open(sys.argv[2], "w"), indent=1)
PY
done
run() {  # name binary scene [env]
  local name=$1 b=$2 scene=$3
  shift 3
  /usr/bin/time -f "%e s wall" env "$@" "$b" run "$scene" --frames "$frames" -j 2 --quiet --out "$out/$name" \
    2> "$out/$name.time"
}
# The scenes name their mesh files relative to scenes/, the body is generated: run from the repository root.
[ -n "${NOCARRY:-}" ] && run nocarry_s1 "$NOCARRY" "$out/poncho_s1.json" MGCLOTH_NO_CARRY_TMP=1
run carry_s1 "$bin" "$out/poncho_s1.json"
run carry_s2 "$bin" "$out/poncho_s2.json"
/usr/bin/python3 bench/obstacle_rounds/summary.py "$out"
