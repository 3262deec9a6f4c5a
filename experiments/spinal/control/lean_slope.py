"""3fbl_auto before its slope training (control/3fbl_auto_flat.json) on the increasing slope,
with the lean slope rule (k_lean_g) and lean feedforward (k_lean_v) set by hand; prints the
distance and the fall per setting.

    ./jg python experiments/spinal/control/lean_slope.py 0,0.5,1.0,-0.5 0
"""

import copy
import json
import sys

from jaxgait import evaluation

doc = json.load(open("experiments/spinal/control/3fbl_auto_flat.json"))  # before the slope rule
for kg in map(float, sys.argv[1].split(",")):
    for kv in map(float, sys.argv[2].split(",")):
        q = copy.deepcopy(doc)
        q["params"].update(k_lean_g=kg, k_lean_v=kv)
        r = evaluation.run(q, env="increasing_slope", duration=60).report
        print(f"k_lean_g {kg:+.2f} k_lean_v {kv:+.2f}: {r['distance_m']:.1f} m, fell {r['fell']}")
