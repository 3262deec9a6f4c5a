"""A Wang runner search with swing initiation held within reach.

Registers, for this process only, ``wang8_run_si``: the running table (``wang8_run``) with
d_SI limited to [0.35, 0.6] leg lengths, where the probes of ``si_probe.sh`` change the gait,
then runs ``jaxgait.train`` with the arguments given (experiments/running/README.md, "Swing
initiation is never entered").  Usage::

    ./jg python experiments/running/wang_fast/si_search.py wang_run_3p0 --set model=wang8_run_si ...
"""

import dataclasses
import sys

from jaxgait.core import host_devices

host_devices.use_cpu_cores()  # as `python -m jaxgait.train`: one XLA device per core

from jaxgait import models  # noqa: E402
from jaxgait.control.wang import WANG_RUN_CONTROLLER  # noqa: E402
from jaxgait.core.params import ParamTable  # noqa: E402
from jaxgait.train.cli import main  # noqa: E402

SI_RANGE = (0.35, 0.6)

specs = tuple(
    dataclasses.replace(
        s, lower=SI_RANGE[0], upper=SI_RANGE[1], source=s.source + "; held within reach"
    )
    if s.name == "d_SI"
    else s
    for s in WANG_RUN_CONTROLLER.table.specs
)
ctrl = dataclasses.replace(
    WANG_RUN_CONTROLLER, name="wang8_run_si", table=ParamTable("wang8_run_si", specs)
)
models.register(models.planar_spec(ctrl))

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
