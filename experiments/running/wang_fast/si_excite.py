"""A Wang runner search over swing initiation alone: the other gains held.

When d_SI is moved into a running stride's reach, swing initiation acts for the first time
with excitations (s_VAS, s_RF, s_GLU, s_HFL) that no search has tuned (they never acted).
This registers, for this process only, ``wang8_run_si6``: the running table with every entry
held within 1e-6 of the start preset's value except d_SI (in [0.35, $SI_MAX], 0.7 by
default), d_SP and the four
excitations, then runs ``jaxgait.train`` with the arguments given.  Usage::

    ./jg python experiments/running/wang_fast/si_excite.py START.json wang_run_3p0 \
        --set model=wang8_run_si6 --set init=START.json ...
"""

import dataclasses
import json
import os
import sys

from jaxgait import models
from jaxgait.control.wang import WANG_RUN_CONTROLLER
from jaxgait.core.params import ParamTable
from jaxgait.train.cli import main

FREE = {
    "d_SI": (0.35, float(os.environ.get("SI_MAX", "0.7"))),
    "d_SP": None,
    "s_VAS": None,
    "s_RF": None,
    "s_GLU": None,
    "s_HFL": None,
}


def held_table(start: dict) -> ParamTable:
    specs = []
    for s in WANG_RUN_CONTROLLER.table.specs:
        if s.name in FREE:
            lo, hi = FREE[s.name] or (s.lower, s.upper)
            v = min(max(start[s.name], lo), hi)
            specs.append(dataclasses.replace(s, lower=lo, upper=hi, init=v))
        else:
            v = start[s.name]
            w = 1e-6 * max(abs(v), 1e-3)
            specs.append(dataclasses.replace(s, lower=v - w, upper=v + w, init=v, source="held"))
    return ParamTable("wang8_run_si6", tuple(specs))


if __name__ == "__main__":
    start = json.load(open(sys.argv[1]))["params"]
    ctrl = dataclasses.replace(WANG_RUN_CONTROLLER, name="wang8_run_si6", table=held_table(start))
    models.register(models.planar_spec(ctrl))
    sys.exit(main(sys.argv[2:]))
