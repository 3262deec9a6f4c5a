"""How much the landing brake alone softens a Wang runner's slap: a grid of its parameters.

A ``wang8_run`` preset (or any of Wang's runners) is rolled out as model ``wang8_run_ld``
(:func:`jaxgait.control.wang.landing_brake`: TA excitation s_TA_pre in late swing, once the
CoM is d_TA_pre leg lengths behind the ankle, and s_TA_ld for the first T_ld of stance) at
every combination of the values given, nothing else changed, and each rollout's right stances
are measured as ``grf_slap.py`` does (heel or ball first, when and how fast the other point
comes down, the peak at the physics step and after a 50 Hz low-pass).  The brake's parameters
at 0 move the runner as the preset (``tests/test_wang.py``), the first row.  ``--scale
NAME=F1,F2,...`` multiplies any of the preset's parameters too (e.g. the stance knee's laws, to
see whether a leg that yields at touchdown lands softer).  Usage::

    ./jg python experiments/running/landing/brake_grid.py wang_run_3p5_human \\
        --value s_TA_pre=0,0.1,0.3 --value d_TA_pre=-0.15,-0.3 --value s_TA_ld=0,0.3 \\
        --value T_ld=0.03 --duration 6 --out experiments/running/landing/brake_grid.json
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

from grf_slap import describe, slap

from jaxgait import evaluation
from jaxgait.control.wang_params import LANDING_SPECS
from jaxgait.presets import resolve_preset

BRAKE = tuple(s.name for s in LANDING_SPECS)


def _values(
    items: list[str], p: argparse.ArgumentParser, option: str, allowed, what: str
) -> dict[str, list[float]]:
    out = {}
    for item in items:
        name, _, vals = item.partition("=")
        if name not in allowed:
            p.error(f"{option} {item!r}: {name!r} is not one of {what}")
        try:
            out[name] = [float(v) for v in vals.split(",")]
        except ValueError:
            p.error(f"{option} {item!r}: values must be numbers separated by commas")
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("preset")
    p.add_argument("--value", action="append", default=[], help="NAME=V1,V2,... (repeatable)")
    p.add_argument("--scale", action="append", default=[], help="NAME=F1,F2,... (repeatable)")
    p.add_argument("--duration", type=float, default=6.0)
    p.add_argument("--skip", type=float, default=2.0, help="seconds of start left out")
    p.add_argument("--cutoff", type=float, default=50.0, help="low-pass cut-off [Hz]")
    p.add_argument("--out")
    a = p.parse_args(argv)
    base = json.loads(Path(resolve_preset(a.preset)).read_text())
    if not str(base.get("model", "")).startswith("wang8"):
        p.error(f"{a.preset}: model {base.get('model')!r} is not one of Wang's")
    grid = _values(a.value, p, "--value", BRAKE, f"the brake's parameters {BRAKE}")
    scales = _values(a.scale, p, "--scale", base["params"], f"{a.preset}'s parameters")
    names, snames = list(grid), list(scales)
    rows = []
    combos = [({}, {})] + [
        (
            dict(zip(names, c[: len(names)], strict=True)),
            dict(zip(snames, c[len(names) :], strict=True)),
        )
        for c in itertools.product(*(grid[n] for n in names), *(scales[n] for n in snames))
    ]
    off = {sp.name: sp.init for sp in LANDING_SPECS}
    for brake, scale in combos:
        preset = {**base, "model": "wang8_run_ld", "table": "wang8_run_ld"}
        scaled = {k: base["params"][k] * f for k, f in scale.items()}
        preset["params"] = {**base["params"], **off, **brake, **scaled}
        r = evaluation.run(preset, duration=a.duration, log_dt=0.0005, reference="running")
        res = slap(r, a.skip, a.cutoff)
        label = [f"{k} {v:g}" for k, v in brake.items()] + [f"{k} x{v:g}" for k, v in scale.items()]
        print(
            f"{', '.join(label) or 'as shipped'}: {'falls; ' if res['fell'] else ''}"
            f"{describe(res, a.cutoff)}"
        )
        rows.append(
            {
                "brake": brake,
                "scale": scale,
                "fell_within_s": a.duration if res["fell"] else None,
                **res,
            }
        )
    if a.out:
        with open(a.out, "w") as f:
            json.dump({"preset": a.preset, "cutoff_hz": a.cutoff, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
