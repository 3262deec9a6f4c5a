#!/usr/bin/env bash
# Wang's runner with swing initiation held within reach (d_SI in [0.35, 0.6], si_search.py),
# through a horizon curriculum: CMA-ES stages on flat ground from INIT with small steps, the
# rollout lengthened stage by stage (each stage starts from the previous stage's best).
#
# Usage: si_horizon.sh INIT OUTDIR "DURATIONS" ITERATIONS SIGMA V0 VSTAR [--set ...]
set -euo pipefail
init=$1; out=$2; durs=$3; iters=$4; sigma=$5; v0=$6; vstar=$7; shift 7
W=${W:-'{"distance":1,"upright":20,"speed":10,"upright_speed":20,"trunk":10,"effort":1,"no_double_stance":300,"flight":100,"mean_cycle_corr_hip":10,"mean_cycle_corr_knee":20,"mean_cycle_corr_ankle":10}'}
prev=$init
for d in $durs; do
  o=$out/h$d
  ./jg python experiments/running/wang_fast/si_search.py wang_run_3p0 --set model=wang8_run_si \
    --set init="$prev" --set particles=24 --set iterations="$iters" --set duration="$d" \
    --set "weights=$W" --set targets.v_desired="$vstar" --set v0="$v0" --set reference=running \
    --set confirm_best=true --set "optimiser_options={\"sigma_init\":$sigma}" "$@" --out "$o"
  prev=$o
done
