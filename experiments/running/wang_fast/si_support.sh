#!/usr/bin/env bash
# The support curriculum (bws/support_curriculum.sh) with swing initiation held within reach
# (si_search.py: d_SI in [0.35, 0.6] leg lengths): the d_SI = 0.6 probe of wang_run_2p5,
# which flexes its knee like a runner and falls at 3.9 s alone, is first re-tuned under a
# harness that keeps it up, then the harness is lowered stage by stage
# (experiments/running/README.md, "Swing initiation under a harness").
#
# Usage: si_support.sh INIT OUTDIR "FRACTIONS" ITERATIONS SIGMA [--set ...]
set -euo pipefail
init=$1; out=$2; fracs=$3; iters=$4; sigma=$5; shift 5
W=${W:-'{"distance":1,"upright":20,"speed":10,"upright_speed":20,"trunk":10,"effort":1,"no_double_stance":300,"flight":100,"mean_cycle_corr_hip":10,"mean_cycle_corr_knee":20,"mean_cycle_corr_ankle":10}'}
prev=$init
for f in $fracs; do
  d=$out/bws_$f
  ./jg python experiments/running/wang_fast/si_search.py wang_run_3p0 --set model=wang8_run_si \
    --set init="$prev" --set particles=24 --set iterations="$iters" --set duration=10 \
    --set env=weight_support --set "env_overrides={\"fraction\":$f}" \
    --set "weights=$W" --set targets.v_desired=3.0 --set v0=2.5 --set reference=running \
    --set confirm_best=true --set "optimiser_options={\"sigma_init\":$sigma}" "$@" --out "$d"
  prev=$d
done
