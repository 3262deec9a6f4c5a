"""The increasing slope with the lean speed regulator around a speed-controlled 3FBL.

Registers, for this process, ``MODEL_sr``: the model of a spinal preset (e.g. ``3fbl_auto``)
wrapped by :func:`jaxgait.control.speed_lean.speed_regulated`, which leans the trunk forwards
as the walk slows below v_reg (the models fall backwards on the slope for want of
propulsion), then climbs the increasing slope (environment 5, 0 -> 30 % over 160 m) for each
setting of the regulator's gains, as ``spinal climb`` does (``walk_tests``' slope test).
Usage::

    ./jg python experiments/spinal/control/lean_climb.py 3fbl_auto --v-reg 1.3 --k-vp 0,0.05 \
        --k-vi 0,0.02 --seeds 1 --duration 300 --out FILE.json
"""

import argparse
import itertools
import json

import numpy as np

from jaxgait import models
from jaxgait.analysis.robustness import RobustnessConfig, walk_tests
from jaxgait.control.speed_lean import REGULATOR_NAMES, speed_regulated
from jaxgait.presets import load_preset


def floats(s):
    return [float(x) for x in s.split(",")]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("preset")
    ap.add_argument("--v-reg", type=floats, default=[1.3])
    ap.add_argument("--k-vp", type=floats, default=[0.0, 0.05])
    ap.add_argument("--k-vi", type=floats, default=[0.0, 0.02])
    ap.add_argument("--tau", type=floats, default=[1.0])
    ap.add_argument("--i-max", type=floats, default=[2.0])
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)

    name, vec, doc = load_preset(a.preset)
    base = models.get_model(name).controller
    ctrl = speed_regulated(base, name + "_sr")
    models.register(models.planar_spec(ctrl), replace=True)
    model = models.get_model(ctrl.name)
    rcfg = RobustnessConfig(
        seeds=a.seeds, duration=a.duration, v0=doc.get("v0"), pose=doc.get("pose")
    )
    rows = []
    for c in itertools.product(a.v_reg, a.k_vp, a.k_vi, a.tau, a.i_max):
        full = np.concatenate([np.asarray(vec, float), np.asarray(c, float)])
        r = walk_tests(model, full, rcfg, tests=("slope",))
        row = dict(zip(REGULATOR_NAMES, c, strict=True))
        row.update(
            distance_m=float(r["slope_distance_m"]),
            distance_sd=float(r["slope_distance_m_sd"]),
            grade_pct=float(r["slope_max_grade_pct"]),
            grade_sd=float(r["slope_max_grade_pct_sd"]),
        )
        rows.append(row)
        print(json.dumps(row), flush=True)
    if a.out:
        with open(a.out, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
