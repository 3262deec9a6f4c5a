#!/bin/bash
# wang_run_2p5 with its swing-initiation (d_SI) or stance-preparation (d_SP) threshold moved
# into reach, 10 s each on flat ground (experiments/running/README.md, "Swing initiation").
set -e
out=${1:-runs/si_probe}; mkdir -p "$out"
for kv in d_SI=0.2 d_SI=0.3 d_SI=0.4 d_SI=0.5 d_SI=0.6 d_SP=-0.2 d_SP=-0.3 d_SP=-0.4 d_SP=-0.5; do
  k=${kv%=*}; v=${kv#*=}
  python3 - "$k" "$v" "$out/$kv.json" <<'PY'
import json, sys
d = json.load(open("experiments/presets/wang_run_2p5.json"))
d["params"][sys.argv[1]] = float(sys.argv[2])
d.pop("description", None)
json.dump(d, open(sys.argv[3], "w"))
PY
  ./jg evaluate "$out/$kv.json" --duration 10 --reference running --json > "$out/$kv.eval.json"
  python3 -c "import json,sys; m=json.load(open('$out/$kv.eval.json')); m=m.get('measures',m); print('$kv', 'fell at', round(m['duration_s'],1), 's;', 'speed', round(m['mean_speed_mps'],2), 'knee corr', round(m['corr_knee'],2))"
done
