#!/bin/sh
# The measurements of bench/RESULTS.md, "Solver defaults (issue 25)": each solver's defaults against one changed
# setting, on copies of scenes/hanging.json (30 frames) and scenes/drape_sphere.json (12 frames), one thread.
# About 50 minutes on a shared 2-core machine; each command prints its table (Markdown) on stdout. The tables and
# per-run logs of the session that measured them are in bench/defaults/data/.
set -e
CLI=${CLI:-build/bin/mgcloth}
OUT=${OUT:-/tmp/defaults}
C="python3 bench/defaults/compare.py --cli $CLI"
# FMG: every choice at once (and the final frames against fmg solved to rel_grad 1e-5)
$C --out $OUT/fmg_q --configs fmg,fmg@interleave=true,fmg@adaptive_threshold=0.5,fmg@adaptive_threshold=1,\
fmg@pre_smooth=2@post_smooth=2,fmg@pre_smooth=4@post_smooth=4,fmg@momentum=false,fmg@chebyshev_smoothing=false,\
fmg@refresh_below=0
# the two closest, again, with both bending models
for b in quadratic hinge; do
  $C --out $OUT/cheb_$b --bending $b --reference-rel-grad 0 --group 2 \
     --configs fmg,fmg@chebyshev_smoothing=false,fmg@adaptive_threshold=0.5
done
# newton-mg's V-cycle preconditioner: the default V(1,1) against V(2,2), the default when it was measured (then A
# was V(2,2); here A is V(1,1), so the ratios are the inverse of those in bench/RESULTS.md)
$C --out $OUT/nmg_h --scenes hanging --reps 6 --reference-rel-grad 0 --group 1 \
   --configs newton-mg,newton-mg@pre_smooth=2@post_smooth=2
$C --out $OUT/nmg_d --scenes drape --frames drape=6 --reference-rel-grad 0 --group 1 \
   --configs newton-mg,newton-mg@pre_smooth=2@post_smooth=2
# the default stop rule (no "solver" block: fmg, rel_grad 1e-6, max_iters 100) on 10 frames of the hanging cloth
python3 - "$OUT" <<'PY'
import json, sys
s = json.load(open("scenes/hanging.json"))
del s["solver"]
s["frames"] = 10
s["cloths"][0]["material"]["bending"] = "quadratic"
json.dump(s, open(sys.argv[1] + "/hanging_nosolver.json", "w"))
PY
nice -n 10 $CLI run $OUT/hanging_nosolver.json --threads 1 -q --out $OUT/nosolver
cut -d, -f1,5,10,11,12 $OUT/nosolver/stats.csv
