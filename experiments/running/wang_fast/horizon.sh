#!/usr/bin/env bash
# A faster Wang runner by a horizon curriculum: CMA-ES stages on flat ground from INIT, each
# started at v0 and aiming at v*, the rollout lengthened stage by stage (each stage starts from
# the previous stage's best).
#
# Usage: horizon.sh EXPERIMENT INIT OUTDIR "DURATIONS" ITERATIONS V0 VSTAR [--set ...]
# W (the weights) and TRAIN (the training command, default ./jg train; e.g.
# "./jg python experiments/running/wang_fast/si_search.py" for swing initiation in reach)
# come from the environment.
set -euo pipefail
exp=$1; init=$2; out=$3; durs=$4; iters=$5; v0=$6; vstar=$7; shift 7
W=${W:-'{"distance":1,"upright":20,"speed":10,"upright_speed":20,"trunk":10,"effort":1,"no_double_stance":300,"flight":100,"mean_cycle_corr_hip":10,"mean_cycle_corr_knee":10,"mean_cycle_corr_ankle":10}'}
prev=$init
for d in $durs; do
  o=$out/h$d
  ${TRAIN:-./jg train} "$exp" --set init="$prev" --set particles=24 --set iterations="$iters" --set duration="$d" \
    --set "weights=$W" --set targets.v_desired="$vstar" --set v0="$v0" --set reference=running \
    --set confirm_best=true "$@" --out "$o"
  prev=$o
done
