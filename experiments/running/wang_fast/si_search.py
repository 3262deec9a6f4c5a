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

``--landing`` (before the train arguments) builds both models on ``wang8_run_ld`` (the running
table with the landing brake's four parameters, :func:`jaxgait.control.wang.landing_brake`)
instead of ``wang8_run``.
"""

import dataclasses
import sys

from jaxgait.core import host_devices

host_devices.use_cpu_cores()  # as `python -m jaxgait.train`: one XLA device per core

from jaxgait import models  # noqa: E402
from jaxgait.control.wang import WANG_RUN_CONTROLLER, WANG_RUN_LD_CONTROLLER  # noqa: E402
from jaxgait.core.params import ParamTable, widened  # noqa: E402
from jaxgait.evaluate import main as evaluate_main  # noqa: E402
from jaxgait.muscles.tables import WANG8, with_headroom  # noqa: E402
from jaxgait.train.cli import main  # noqa: E402

SI_RANGE = (0.35, 0.6)


def si_table(base=WANG_RUN_CONTROLLER) -> ParamTable:
    """``base``'s table (``wang8_run``) with d_SI held within reach (a narrower range, so not
    :func:`widened`)."""
    return ParamTable(
        "wang8_run_si",
        tuple(
            dataclasses.replace(
                s, lower=SI_RANGE[0], upper=SI_RANGE[1], source=s.source + "; held within reach"
            )
            if s.name == "d_SI"
            else s
            for s in base.table.specs
        ),
    )


def _register(table, muscles=None, base=WANG_RUN_CONTROLLER):
    ctrl = dataclasses.replace(base, name=table.name, table=table)
    models.register(models.planar_spec(ctrl, muscles=muscles))


def _pairs(option, value, n, example):
    """(NAME, n floats) of ``option``'s ``NAME=X[,Y]``, or exit saying what it takes."""
    try:
        name, v = value.split("=")
        xs = tuple(float(x) for x in v.split(","))
        if len(xs) != n:
            raise ValueError
    except ValueError:
        sys.exit(f"si_search.py: {option} takes {example}, got {value!r}")
    return name, xs


def _parse_options(argv):
    """Split ``--widen NAME=LO,HI`` and ``--headroom MUSCLE=FACTOR`` off ``argv``: (ranges,
    headroom factors, the rest)."""
    ranges, factors, rest, it = {}, {}, [], iter(argv)
    for a in it:
        if a == "--widen":
            name, ranges[name] = _pairs(a, next(it, ""), 2, "NAME=LO,HI, e.g. GL_HFL_sw=0,5")
        elif a == "--headroom":
            name, (factors[name],) = _pairs(a, next(it, ""), 1, "MUSCLE=FACTOR, e.g. GLU=1.25")
        else:
            rest.append(a)
    return ranges, factors, rest


if __name__ == "__main__":
    argv = sys.argv[1:]
    run = main
    if argv[:1] == ["--evaluate"]:
        run, argv = evaluate_main, argv[1:]
    base = WANG_RUN_CONTROLLER
    if "--landing" in argv:
        base = WANG_RUN_LD_CONTROLLER
        argv = [a for a in argv if a != "--landing"]
    widen, factors, args = _parse_options(argv)
    try:
        muscles = with_headroom(WANG8, factors, f"stimulation up to {factors}") if factors else None
        table = si_table(base)
        _register(table, muscles, base)
        if widen:
            siw = widened(table, "wang8_run_siw", widen, "; widened for speed")
            _register(siw, muscles, base)
    except ValueError as e:  # an unknown name, a range that narrows, a factor below 1
        sys.exit(f"si_search.py: {e}")
    sys.exit(run(args))
