#!/usr/bin/env bash
# Running by a body-weight-support curriculum: CMA-ES stages on the weight_support
# environment (a constant upward force of fraction x 80 kg x 9.81 m/s^2 on the trunk, 0.3 m
# above the hip, from t = 0), each stage starting from the previous stage's best, the support
# lowered stage by stage.  The last stage should be fraction 0 (no support).
#
# Usage: support_curriculum.sh EXPERIMENT INIT OUTDIR "FRACTIONS" ITERATIONS [--set ...]
# Weights: $W (JSON) or the default below (Wang's running terms; FBL+ has no trunk/effort).
set -euo pipefail
exp=$1; init=$2; out=$3; fracs=$4; iters=$5; shift 5
W=${W:-'{"distance":1,"upright":20,"speed":10,"upright_speed":20,"trunk":10,"effort":1,"no_double_stance":100,"flight":200}'}
prev=$init
for f in $fracs; do
  d=$out/bws_$f
  ./jg train "$exp" --set init="$prev" --set particles=24 --set iterations="$iters" --set duration=10 \
    --set env=weight_support --set "env_overrides={\"fraction\":$f}" \
    --set "weights=$W" "$@" --out "$d"
  prev=$d
done
