#!/usr/bin/env bash
# Runs on the GPU machine (the device tool), from the repository root, with .device/ carried: the CUDA tests of
# fmg-cuda, then its benchmark on the sphere drape (Wang 2018, Table 1) at 40K, 120K and 250K vertices, Δt = 1/30 and
# 1/90 s, to a 1% relative residual, with the CPU fmg of the same machine as the baseline at 120K. Writes two files
# to $OUT (or out/device), as the device tool brings back only a few: report.txt (environment, test summaries,
# tables) and scalability.csv (every run's rows, the run's name first). Usage: scripts/device_check.sh [tests|bench|all]
set -uo pipefail
cd "$(dirname "$0")/.."
what=${1:-all}
out=${OUT:-out/device}
mkdir -p "$out"
root=/tmp/mgcloth-device
rm -rf "$root" && mkdir -p "$root" && tar -C "$root" -xJf .device/bundle.tar.xz
# cuSOLVER is opened at run time; the machine's CUDA Python packages carry it.
cusolver=$(find / -name 'libcusolver.so.1[12]' -not -path '*/proc/*' 2>/dev/null | head -n 1)
# cuSPARSE likewise, for the Galerkin gather's comparison with a general SpGEMM (fmg-cuda@compare_spgemm=true).
cusparse=$(find / -name 'libcusparse.so.1[23]' -not -path '*/proc/*' 2>/dev/null | head -n 1)
export LD_LIBRARY_PATH="$root/lib${cusolver:+:$(dirname "$cusolver")}${cusparse:+:$(dirname "$cusparse")}${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
report="$out/report.txt"
: > "$report"
echo "cuSOLVER: ${cusolver:-not found (the coarse solve falls back to the host)}" | tee -a "$report"
echo "cuSPARSE: ${cusparse:-not found (no SpGEMM comparison)}" | tee -a "$report"
nvidia-smi --query-gpu=name,memory.total,clocks.max.sm,clocks.max.mem --format=csv 2>&1 | tee -a "$report"
status=0
run_test() {  # program, filter
  echo "== $1 $2" | tee -a "$report"
  "$root/bin/$1" ${2:+--gtest_filter=$2} > "$root/test.log" 2>&1 || status=1
  grep -E "Failure|Expected|actual|which is|SKIPPED|FAILED|PASSED" "$root/test.log" | head -n 60 | tee -a "$report"
}
if [ "$what" = tests ] || [ "$what" = all ]; then
  run_test mgcloth_tests_cuda ""
  run_test mgcloth_tests_solvers 'FmgCuda*'
  run_test mgcloth_tests_sim '*FmgCuda*'
fi
bench() {  # name, arguments...
  local name=$1
  shift
  echo "== $name: mgcloth bench scalability scenes/drape_sphere.json $*" | tee -a "$report"
  "$root/bin/mgcloth" bench scalability scenes/drape_sphere.json "$@" --out "$root/$name" -q 2>&1 | tee -a "$report" || status=1
  local csv="$root/$name/scalability.csv"
  [ -f "$csv" ] || return 0
  [ -f "$root/all.csv" ] || { printf 'run,'; head -n 1 "$csv"; } > "$root/all.csv"
  tail -n +2 "$csv" | sed "s/^/$name,/" >> "$root/all.csv"
}
if [ "$what" = bench ] || [ "$what" = all ]; then
  rm -f "$root/all.csv"
  for sub in 1 3; do
    bench "gpu_dt1_$((30 * sub))" --vertices 40000,120000,250000 --solver fmg-cuda --substeps $sub --steps 5 --warmup 3 --rel-grad 0.01
    bench "gpu_profile_dt1_$((30 * sub))" --vertices 120000 --solver fmg-cuda@profile=true --substeps $sub --steps 3 --warmup 3 --rel-grad 0.01
  done
  bench gpu_nographs_dt1_30 --vertices 120000 --solver fmg-cuda@graphs=false --substeps 1 --steps 5 --warmup 3 --rel-grad 0.01
  bench gpu_spgemm_dt1_30 --vertices 40000,120000,250000 --solver fmg-cuda@compare_spgemm=true --substeps 1 --steps 1 --warmup 1 --rel-grad 0.01
  bench gpu_hostcoarse_dt1_30 --vertices 120000 --solver fmg-cuda@coarse_solve=host --substeps 1 --steps 5 --warmup 3 --rel-grad 0.01
  bench cpu16_dt1_30 --vertices 120000 --solver fmg --threads 16 --substeps 1 --steps 3 --warmup 3 --rel-grad 0.01
  [ -f "$root/all.csv" ] && cp "$root/all.csv" "$out/scalability.csv"
fi
echo "device_check: exit $status" | tee -a "$report"
exit $status
