#!/bin/bash
# Same-run comparison: baseline binary (HEAD before this change) against the new one, alternating.
OUT=/tmp/meas; rm -rf $OUT; mkdir -p $OUT
S=/work/main/scenes/drape_sphere.json
for r in 1 2 3; do
  for b in base new; do
    if [ $b = base ]; then B=/work/bin_base/mgcloth; else B=/work/main/build/bin/mgcloth; fi
    OMP_WAIT_POLICY=passive $B bench scalability $S --vertices 40000,120000 --solver fmg --steps 3 --warmup 3 --rel-grad 1e-2 --threads 2 --out $OUT/sc_${b}_$r -q >/dev/null 2>&1
    t0=$(date +%s.%N); OMP_WAIT_POLICY=passive $B run $S --frames 30 --threads 2 --out $OUT/demo_${b}_$r >/dev/null 2>&1; t1=$(date +%s.%N)
    echo "demo $b $r: $(echo "$t1 - $t0" | bc) s" >> $OUT/demo_times.txt
  done
done
