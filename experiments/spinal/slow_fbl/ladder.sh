#!/usr/bin/env bash
# A slow-walking ladder for FBL itself (experiments/spinal/README.md, "How slow the reflex
# layer walks"): CMA-ES rungs of quickstart's task (20 s on flat ground), each from the
# previous rung's best with the target speed v* lowered; the first rung starts at fbl_walk's
# 1.3 m/s, the later ones at 1.1 m/s (a rung's best started at its own lower target falls
# within 2 s: the gaits are found from a faster start).
# Usage: experiments/spinal/slow_fbl/ladder.sh OUT_DIR
set -euo pipefail
out=$1
prev=fbl_walk
v0=1.3
for v in 1.1 0.9 0.75 0.6; do
  d=$out/v$v
  ./jg train quickstart --set init="$prev" --set particles=24 --set iterations=25 --set duration=20 \
    --set targets.v_desired="$v" --set v0="$v0" --set confirm_best=true \
    --set 'optimiser_options={"sigma_init":0.02}' --out "$d"
  ./jg evaluate "$d" --duration 60 --json > "$d/eval_60s.json"
  prev=$d
  v0=1.1
done
