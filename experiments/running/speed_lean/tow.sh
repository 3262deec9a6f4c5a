#!/usr/bin/env bash
# A tow curriculum: CMA-ES stages of DURATION s rollouts on the weight_support environment
# pulling straight forwards (angle 0) with a force of FRACTION body weights, each stage from
# the previous stage's best, the tow lowered stage by stage to none, each best then evaluated
# alone for EVAL_S s (experiments/running/README.md, "A speed regulator" for the regulated
# FBL+ runner, the default; "Faster than 2.5 m/s?" for Wang's runner).
#
# Usage: tow.sh INIT OUTDIR "FRACTIONS" ITERATIONS SIGMA V_TARGET [--set ...]
# Environment: EXPERIMENT (fblplus_run), MODEL (fblplus_bal_run_sr; empty: the experiment's),
#   DURATION (20), EVAL_S (60), W (the running weights below).
set -euo pipefail
init=$1; out=$2; fracs=$3; iters=$4; sigma=$5; vt=$6; shift 6
experiment=${EXPERIMENT:-fblplus_run}
model=${MODEL-fblplus_bal_run_sr}
W=${W:-'{"distance":1,"upright":20,"speed":10,"upright_speed":20,"trunk":10,"no_double_stance":100,"flight":50,"mean_cycle_corr_hip":10,"mean_cycle_corr_knee":10,"mean_cycle_corr_ankle":10}'}
prev=$init
for f in $fracs; do
  d=$out/tow_$f
  ./jg train "$experiment" ${model:+--set model="$model"} --set init="$prev" --set particles=24 \
    --set iterations="$iters" --set duration="${DURATION:-20}" --set env=weight_support \
    --set "env_overrides={\"fraction\":$f,\"angle\":0.0}" --set "weights=$W" \
    --set targets.v_desired="$vt" --set v0=2.5 --set reference=running --set confirm_best=true \
    --set "optimiser_options={\"sigma_init\":$sigma}" "$@" --out "$d"
  ./jg evaluate "$d" --duration "${EVAL_S:-60}" --json --reference running > "$d/eval_${EVAL_S:-60}s.json"
  prev=$d
done
