#!/usr/bin/env bash
# Wang's runner with the knee as a stage (experiments/running/README.md, "The knee as a
# stage"): CMA-ES 48 candidates on a stage objective, 10 s rollouts up to 24 m, from INIT
# (default the swing-initiation horizon run's best), resumed to 160 and 300 generations, then
# 50 generations of 20 s rollouts up to 50 m with the flight fraction as a fifth stage, and
# 150 generations aimed at 4 m/s from there (w4).
#
# Usage: staged.sh OUTDIR [INIT]
set -euo pipefail
out=$1; init=${2:-experiments/running/wang_fast/si_horizon/h20}
TRAIN="./jg python experiments/running/wang_fast/si_search.py"
S='[["distance",null],["mean_cycle_corr_knee",null],["no_double_stance",0.7],["speed",-0.01]]'
S5='[["distance",null],["mean_cycle_corr_knee",null],["no_double_stance",0.7],["speed",-0.01],["flight",-0.05]]'
common=(--set model=wang8_run_si --set particles=48 --set 'weights={}' --set targets.v_desired=3.0
  --set v0=2.4 --set reference=running --set confirm_best=true)
$TRAIN wang_run_3p0 "${common[@]}" --set init="$init" --set iterations=60 --set duration=10 --set d_lim=24 \
  --set "stages=$S" --set 'optimiser_options={"sigma_init":0.02}' --out "$out/wk"
cp -r "$out/wk" "$out/wk2"
$TRAIN wang_run_3p0 "${common[@]}" --set init="$init" --set iterations=60 --set duration=10 --set d_lim=24 \
  --set "stages=$S" --set 'optimiser_options={"sigma_init":0.02}' --out "$out/wk2" --resume --iterations 160
cp -r "$out/wk2" "$out/wk3"
$TRAIN wang_run_3p0 "${common[@]}" --set init="$init" --set iterations=60 --set duration=10 --set d_lim=24 \
  --set "stages=$S" --set 'optimiser_options={"sigma_init":0.02}' --out "$out/wk3" --resume --iterations 300
$TRAIN wang_run_3p0 "${common[@]}" --set init="$out/wk3" --set iterations=50 --set duration=20 --set d_lim=50 \
  --set "stages=$S5" --set 'optimiser_options={"sigma_init":0.01}' --out "$out/wk20"
# towards 4 m/s: the same five stages from wk20 at v* 4.0, rollouts of 10 s up to 28 m
$TRAIN wang_run_4p0 "${common[@]}" --set targets.v_desired=4.0 --set init="$out/wk20" --set iterations=150 \
  --set duration=10 --set d_lim=28 --set "stages=$S5" --set 'optimiser_options={"sigma_init":0.02}' --out "$out/w4"
