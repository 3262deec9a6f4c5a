#!/usr/bin/env bash
# A tow curriculum for the regulated FBL+ runner: CMA-ES stages of 20 s rollouts on the
# weight_support environment pulling straight forwards (angle 0) with a force of FRACTION
# body weights, each stage from the previous stage's best, the tow lowered stage by stage to
# none (experiments/running/README.md, "A speed regulator").
#
# Usage: tow.sh INIT OUTDIR "FRACTIONS" ITERATIONS SIGMA V_TARGET [--set ...]
set -euo pipefail
init=$1; out=$2; fracs=$3; iters=$4; sigma=$5; vt=$6; shift 6
W=${W:-'{"distance":1,"upright":20,"speed":10,"upright_speed":20,"trunk":10,"no_double_stance":100,"flight":50,"mean_cycle_corr_hip":10,"mean_cycle_corr_knee":10,"mean_cycle_corr_ankle":10}'}
prev=$init
for f in $fracs; do
  d=$out/tow_$f
  ./jg train fblplus_run --set model=fblplus_bal_run_sr --set init="$prev" --set particles=24 \
    --set iterations="$iters" --set duration=20 --set env=weight_support \
    --set "env_overrides={\"fraction\":$f,\"angle\":0.0}" --set "weights=$W" \
    --set targets.v_desired="$vt" --set v0=2.5 --set reference=running --set confirm_best=true \
    --set "optimiser_options={\"sigma_init\":$sigma}" "$@" --out "$d"
  ./jg evaluate "$d" --duration 60 --json --reference running > "$d/eval_60s.json"
  prev=$d
done
