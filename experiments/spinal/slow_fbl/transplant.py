"""Candidate slow anchors for the 3FBL network from a slow FBL gait (experiments/spinal/README.md,
"How slow the reflex layer walks").

The network's 28 FBL gains (``net_*``) of an anchor preset are replaced three ways and each
result written as a preset: ``A_s0_v75`` (S0 with the slow gait's gains), ``B_d85_delta`` (the
0.85 m/s anchor plus the slow gait's change from ``fbl_walk``), ``C_s0_delta`` (S0 plus that
change); values outside the network table's ranges are clipped to them.  Usage::

    ./jg python experiments/spinal/slow_fbl/transplant.py experiments/spinal/slow_fbl/v0.75 OUT_DIR
"""

import argparse
import copy
import json
import os

from jaxgait import models
from jaxgait.presets import load_preset

ANCHORS = "experiments/spinal/anchors"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("slow", help="an FBL preset or run folder (the slow gait)")
    ap.add_argument("out")
    a = ap.parse_args(argv)
    fbl = models.get_spec("fbl").table.names
    _, walk, _ = load_preset("fbl_walk")
    _, slow, _ = load_preset(a.slow)
    delta = {n: float(s) - float(w) for n, s, w in zip(fbl, slow, walk, strict=True)}
    slow = dict(zip(fbl, map(float, slow), strict=True))
    with open(os.path.join(ANCHORS, "s0.json")) as f:
        s0 = json.load(f)
    with open(os.path.join(ANCHORS, "d0p85.json")) as f:
        d85 = json.load(f)
    load_preset(os.path.join(ANCHORS, "s0.json"))  # registers the network's model
    table = {s.name: s for s in models.get_spec(s0["model"]).table.specs}  # the anchors' too
    os.makedirs(a.out, exist_ok=True)
    for name, base, new in (
        ("A_s0_v75", s0, lambda x, n: slow[n]),
        ("B_d85_delta", d85, lambda x, n: x + delta[n]),
        ("C_s0_delta", s0, lambda x, n: x + delta[n]),
    ):
        doc = copy.deepcopy(base)
        for n in fbl:
            k = "net_" + n
            spec = table[k]
            doc["params"][k] = min(max(new(doc["params"][k], n), spec.lower), spec.upper)
        doc["description"] = f"{name}: network gains from {a.slow} ({__doc__.splitlines()[0]})"
        with open(os.path.join(a.out, name + ".json"), "w") as f:
            json.dump(doc, f, indent=1)
        print(os.path.join(a.out, name + ".json"))


if __name__ == "__main__":
    main()
