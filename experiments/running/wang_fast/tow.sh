#!/usr/bin/env bash
# Tow curriculum for Wang's runner: CMA-ES stages of 10 s rollouts on weight_support pulling
# forwards (angle 0) with FRACTION body weights, each from the previous best, tow lowered to none
# (experiments/running/README.md, "Faster than 2.5 m/s?").
#
# Usage: tow.sh INIT OUTDIR "FRACTIONS" ITERATIONS SIGMA V_TARGET [--set ...]
set -euo pipefail
init=$1; out=$2; fracs=$3; iters=$4; sigma=$5; vt=$6; shift 6
W=${W:-'{"distance":1,"upright":20,"speed":10,"upright_speed":20,"trunk":10,"effort":1,"no_double_stance":300,"flight":100,"mean_cycle_corr_hip":10,"mean_cycle_corr_knee":10,"mean_cycle_corr_ankle":10}'}
prev=$init
for f in $fracs; do
  d=$out/tow_$f
  ./jg train wang_run_3p0 --set init="$prev" --set particles=24 \
    --set iterations="$iters" --set duration=10 --set env=weight_support \
    --set "env_overrides={\"fraction\":$f,\"angle\":0.0}" --set "weights=$W" \
    --set targets.v_desired="$vt" --set v0=2.5 --set reference=running --set confirm_best=true \
    --set "optimiser_options={\"sigma_init\":$sigma}" "$@" --out "$d"
  ./jg evaluate "$d" --duration 30 --json --reference running > "$d/eval_30s.json" || true
  prev=$d
done
