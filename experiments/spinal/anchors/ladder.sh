#!/bin/bash
# A ladder of anchors: each rung trains the network's 28 FBL gains (net_*) of the previous
# rung's preset, the command law fixed, to hold constant targets drawn in LO-HI on flat
# ground or, with --grade, on ground rising to that grade (spinal tune; CMA-ES population 12,
# sigma 0.015 of the ranges, 2 profiles of one 30 s target per generation, the last 20 s
# scored).  Usage:
#   experiments/spinal/anchors/ladder.sh START OUT_DIR GENERATIONS NAME:LO,HI[:--grade=G] ...
# e.g. (the speed rungs below 1.25 m/s of experiments/spinal/README.md, "Speed and grade anchors"):
#   experiments/spinal/anchors/ladder.sh START.json runs/anchors 20 d0p85:0.85,0.85 e0p8:0.78,0.82
set -e
prev=$1; out=$2; gens=$3; shift 3
mkdir -p "$out"
for rung in "$@"; do
  IFS=: read -r name vr extra <<< "$rung"
  ./jg python -m jaxgait.spinal tune "$prev" --name "$name" --gains 'net_*' --v-range "$vr" \
    --segments 1 --segment 30 --settle 10 --profiles 2 --popsize 12 --generations "$gens" \
    --sigma 0.015 --held-out 2 --out-dir "$out" --out "$out/tuning" $extra | tee "$out/$name.log"
  prev=$out/$name.json
done
