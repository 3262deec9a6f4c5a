#!/usr/bin/env bash
# A speed ladder for the regulated FBL+ runner (model fblplus_bal_run_sr): CMA-ES rungs of
# 20 s rollouts on flat ground, each from the previous rung's best with the target speed v*
# raised (experiments/running/README.md, "A speed regulator").
#
# Usage: ladder.sh INIT OUTDIR "V_TARGETS" ITERATIONS SIGMA [--set ...]
set -euo pipefail
init=$1; out=$2; targets=$3; iters=$4; sigma=$5; shift 5
W=${W:-'{"distance":1,"upright":20,"speed":10,"upright_speed":20,"trunk":10,"no_double_stance":100,"flight":50,"mean_cycle_corr_hip":10,"mean_cycle_corr_knee":10,"mean_cycle_corr_ankle":10}'}
prev=$init
for v in $targets; do
  d=$out/v$v
  ./jg train fblplus_run --set model=fblplus_bal_run_sr --set init="$prev" --set particles=24 \
    --set iterations="$iters" --set duration=20 --set "weights=$W" --set targets.v_desired="$v" \
    --set v0=2.5 --set reference=running --set confirm_best=true \
    --set "optimiser_options={\"sigma_init\":$sigma}" "$@" --out "$d"
  ./jg evaluate "$d" --duration 60 --json --reference running > "$d/eval_60s.json"
  prev=$d
done
