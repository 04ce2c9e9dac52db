#!/usr/bin/env bash
# One thread against two on the hanging cloth (scenes/hanging.json, fmg, 10 frames) from 500 to 10,000 vertices,
# alternated, 3 repeats: where a second thread starts to pay. Writes bench/threads_small/times.csv (about 2 minutes).
set -euo pipefail
cd "$(dirname "$0")/../.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sizes=(500 1000 2000 4000 10000)
for n in "${sizes[@]}"; do
  /usr/bin/python3 -c "import json, sys
s = json.load(open('scenes/hanging.json'))
s['cloths'][0]['mesh']['vertices'] = $n
s['frames'] = 10
s['output'] = {'dir': '$work/out$n'}
json.dump(s, open('$work/h$n.json', 'w'))"
done
out=bench/threads_small/times.csv
echo "vertices,threads,repeat,wall_s" > "$out"
for r in 1 2 3; do for n in "${sizes[@]}"; do for j in 1 2; do
  s=$(date +%s.%N); build/bin/mgcloth run "$work/h$n.json" -q -j "$j"; e=$(date +%s.%N)
  awk -v n="$n" -v j="$j" -v r="$r" -v s="$s" -v e="$e" 'BEGIN { printf "%d,%d,%d,%.3f\n", n, j, r, e - s }' >> "$out"
done; done; done
