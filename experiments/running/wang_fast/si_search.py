"""A Wang runner search with swing initiation held within reach.

Registers, for this process only, ``wang8_run_si``: the running table (``wang8_run``) with
d_SI limited to [0.35, 0.6] leg lengths, where the probes of ``si_probe.sh`` change the gait,
then runs ``jaxgait.train`` with the arguments given (experiments/running/README.md, "Swing
initiation is never entered").  Usage::

    ./jg python experiments/running/wang_fast/si_search.py wang_run_3p0 --set model=wang8_run_si ...

``--widen NAME=LO,HI`` (repeatable, before the train arguments) also registers
``wang8_run_siw``: ``wang8_run_si`` with those ranges widened (a range may only grow, so every
``wang8_run_si`` vector is a ``wang8_run_siw`` vector); search it with ``--set
model=wang8_run_siw``.  ``--evaluate`` (first) runs ``jaxgait.evaluate`` instead of the
search, with the same models registered (a best of ``wang8_run_siw`` outside ``wang8_run``'s
ranges)::

    ./jg python .../si_search.py --evaluate --widen ... BEST.json --duration 60

``--headroom MUSCLE=FACTOR`` (repeatable) gives both models Wang's muscle table with those
muscles' stimulation allowed up to FACTOR (:func:`jaxgait.muscles.tables.with_headroom`, a
capacity study as ``fblplus_bal_run_sr_hr125``; the same vector moves alike while no muscle is
asked for more than 1).
"""

import dataclasses
import sys

from jaxgait.core import host_devices

host_devices.use_cpu_cores()  # as `python -m jaxgait.train`: one XLA device per core

from jaxgait import models  # noqa: E402
from jaxgait.control.wang import WANG_RUN_CONTROLLER  # noqa: E402
from jaxgait.core.params import ParamTable  # noqa: E402
from jaxgait.evaluate import main as evaluate_main  # noqa: E402
from jaxgait.muscles.tables import WANG8, with_headroom  # noqa: E402
from jaxgait.train.cli import main  # noqa: E402

SI_RANGE = (0.35, 0.6)


def _held(specs, ranges, note):
    out = []
    for s in specs:
        if s.name in ranges:
            lo, hi = ranges[s.name]
            s = dataclasses.replace(s, lower=lo, upper=hi, source=s.source + note)
        out.append(s)
    return tuple(out)


def _register(name, specs, muscles=None):
    ctrl = dataclasses.replace(WANG_RUN_CONTROLLER, name=name, table=ParamTable(name, specs))
    models.register(models.planar_spec(ctrl, muscles=muscles), replace=True)


def _parse_options(argv):
    """Split ``--widen NAME=LO,HI`` and ``--headroom MUSCLE=FACTOR`` off ``argv``: (ranges,
    headroom factors, the rest)."""
    ranges, factors, rest, it = {}, {}, [], iter(argv)
    for a in it:
        if a == "--widen":
            try:
                name, bounds = next(it).split("=")
                lo, hi = (float(x) for x in bounds.split(","))
            except (StopIteration, ValueError):
                sys.exit("si_search.py: --widen takes NAME=LO,HI, e.g. --widen GL_HFL_sw=0,5")
            ranges[name] = (lo, hi)
        elif a == "--headroom":
            try:
                name, f = next(it).split("=")
                factors[name] = float(f)
            except (StopIteration, ValueError):
                sys.exit("si_search.py: --headroom takes MUSCLE=FACTOR, e.g. --headroom GLU=1.25")
            if name not in WANG8.names or factors[name] < 1.0:
                sys.exit(f"si_search.py: --headroom {name}: a muscle of {WANG8.names}, factor >= 1")
        else:
            rest.append(a)
    return ranges, factors, rest


si_specs = _held(WANG_RUN_CONTROLLER.table.specs, {"d_SI": SI_RANGE}, "; held within reach")
_register("wang8_run_si", si_specs)

if __name__ == "__main__":
    argv = sys.argv[1:]
    run = main
    if argv[:1] == ["--evaluate"]:
        run, argv = evaluate_main, argv[1:]
    widen, factors, args = _parse_options(argv)
    muscles = None
    if factors:
        muscles = with_headroom(WANG8, factors, f"stimulation up to {factors}")
        _register("wang8_run_si", si_specs, muscles)
    if widen:
        by_name = {s.name: s for s in si_specs}
        for n, (lo, hi) in widen.items():
            if n not in by_name:
                sys.exit(f"si_search.py: --widen {n}: no such parameter in wang8_run_si")
            if lo > by_name[n].lower or hi < by_name[n].upper:
                sys.exit(
                    f"si_search.py: --widen {n}={lo},{hi} narrows its range "
                    f"[{by_name[n].lower}, {by_name[n].upper}]; a range may only grow"
                )
        _register("wang8_run_siw", _held(si_specs, widen, "; widened for speed"), muscles)
    sys.exit(run(args))
