#!/usr/bin/env bash
# Running by body-weight-support curriculum: CMA-ES stages with a constant upward force on
# the trunk (fraction x 80 kg x 9.81 m/s^2, straight up, 0.3 m above the hip, from t = 0),
# each stage starting from the previous stage's best, the support lowered stage by stage.
# Usage: curriculum.sh MODEL_EXPERIMENT INIT OUTDIR "FRACTIONS" ITERATIONS [extra --set ...]
set -euo pipefail
exp=$1; init=$2; out=$3; fracs=$4; iters=$5; shift 5
W='{"distance":1,"upright":20,"speed":10,"upright_speed":20,"trunk":10,"effort":1,"no_double_stance":100,"flight":200}'
prev=$init
for f in $fracs; do
  mag=$(python3 -c "print(round($f*80*9.81, 2))")
  d=$out/bws_$f
  ./jg train "$exp" --set init="$prev" --set particles=24 --set iterations="$iters" --set duration=10 \
    --set env=push \
    --set "env_overrides={\"magnitude\":$mag,\"angle\":1.5707963,\"t_min\":0.0,\"t_max\":0.0,\"duration\":10000.0,\"height\":0.3}" \
    --set "weights=$W" "$@" --out "$d"
  prev=$d
done
