#!/usr/bin/env bash
# Wang 2018's Table 1 on this machine: per scene (default: funnel, dress, gown), the colors of the multi-color
# Gauss-Seidel smoother per level (`mgcloth hierarchy`) and the first FRAMES frames of the scene at its own time
# step (`mgcloth run`, resumable: a second call continues each run where it stopped), then the table.
# Usage: bench/table1/run.sh OUT [FRAMES]   (env: SCENES="funnel dress gown", THREADS=2, MGCLOTH=build/bin/mgcloth)
set -euo pipefail
out=${1:?usage: run.sh OUT [FRAMES]}
frames=${2:-10}
bin=${MGCLOTH:-build/bin/mgcloth}
mkdir -p "$out"
for s in ${SCENES:-funnel dress gown}; do
  compgen -G "$out/$s/hierarchy/*/hierarchy.json" > /dev/null || "$bin" hierarchy "scenes/$s.json" --out "$out/$s/hierarchy" > /dev/null
  resume=()
  [ -f "$out/$s/run/stats.csv" ] && resume=(--resume)
  "$bin" run "scenes/$s.json" --out "$out/$s/run" --frames "$frames" -j "${THREADS:-2}" --quiet "${resume[@]}"
done
/usr/bin/python3 bench/table1/summary.py "$out"
