#!/usr/bin/env bash
# Throughput of `mgcloth sweep` on this machine: the 20-run strip sweep (scenes/sweeps/strip_bending.json) one run
# after another on one thread (the baseline), on two threads, and on 1 and 2 MPI ranks of one thread each. The four
# are alternated, REPEATS times, so that the machine's drift falls on all of them; times.csv has every repeat, with
# busy_s, the runs' own wall times summed (what the ranks spent inside runs: wall_s x ranks - busy_s is idle time).
# Usage: bench/sweep_throughput/run.sh [REPEATS]   (from the repository root; about 2 minutes per repeat)
set -euo pipefail
cd "$(dirname "$0")/../.."
repeats=${1:-3}
cli=build/bin/mgcloth
sweep=scenes/sweeps/strip_bending.json
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# One machine: shared memory (vader) and the ob1 layer; probing for UCX (the default pml) costs 0.2 s of MPI_Init.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl=self,vader OMPI_MCA_pml=ob1
out=bench/sweep_throughput/times.csv
echo "repeat,config,runs,wall_s,busy_s,runs_per_minute" > "$out"
for r in $(seq 1 "$repeats"); do
  for config in serial_1thread serial_2threads mpi_1rank mpi_2ranks; do
    dir="$work/$config-$r"
    case $config in
      serial_1thread)  cmd=("$cli" sweep "$sweep" --out "$dir" -q -j 1) ;;
      serial_2threads) cmd=("$cli" sweep "$sweep" --out "$dir" -q -j 2) ;;
      mpi_1rank)       cmd=(mpirun --oversubscribe -np 1 "$cli" sweep "$sweep" --out "$dir" -q -j 1) ;;
      mpi_2ranks)      cmd=(mpirun --oversubscribe -np 2 "$cli" sweep "$sweep" --out "$dir" -q -j 1) ;;
    esac
    start=$(date +%s.%N)
    "${cmd[@]}"
    end=$(date +%s.%N)
    runs=$(grep -c ',ok,' "$dir/summary.csv")
    busy=$(awk -F, 'NR > 1 && $2 == "ok" { s += $4 } END { printf "%.2f", s }' "$dir/summary.csv")
    awk -v r="$r" -v c="$config" -v n="$runs" -v s="$start" -v e="$end" -v b="$busy" \
      'BEGIN { w = e - s; printf "%s,%s,%d,%.2f,%s,%.2f\n", r, c, n, w, b, 60 * n / w }' | tee -a "$out"
  done
done
