#!/usr/bin/env bash
# A speed ladder for the Wang runner: CMA-ES stages of 10 s rollouts on flat ground, each
# from the previous stage's best, started faster (v0) and aiming higher (v* = v0 + 0.2).
#
# Usage: ladder.sh INIT OUTDIR "V0S" [--set ...]   (model wang8_run, 48 x 30, sigma 0.05)
set -euo pipefail
init=$1; out=$2; v0s=$3; shift 3
W=${W:-'{"distance":1,"upright":20,"speed":10,"upright_speed":20,"trunk":10,"effort":1,"no_double_stance":300,"flight":100,"mean_cycle_corr_hip":10,"mean_cycle_corr_knee":10,"mean_cycle_corr_ankle":10}'}
prev=$init
for v0 in $v0s; do
  o=$out/v$v0
  vstar=$(python3 -c "print(round($v0 + 0.2, 2))")
  ./jg train wang_run_3p0 --set model=wang8_run --set init="$prev" --set particles=48 --set iterations=30 \
    --set duration=10 --set "weights=$W" --set targets.v_desired="$vstar" --set v0="$v0" \
    --set reference=running --set confirm_best=true --set 'optimiser_options={"sigma_init":0.05}' "$@" --out "$o"
  prev=$o
done
