"""Robustness of a walking preset from the command line.

The library is :mod:`jaxgait.analysis.robustness`.

Command line::

    python -m jaxgait.robustness PRESET_OR_FILE [--model fbl|fblplus] [--seeds N]
        [--duration S] [--after-push T] [--push-env random_push|push] [--seed S]
        [--push-window T_MIN T_MAX] [--push-max-duration S] [--push-duration S]
        [--push-step N] [--push-max N] [--push-per-rung M] [--push-refine R]
        [--tests push,wavy,slope] [--json]

prints ``max_push_N``, ``max_slope_pct`` and ``slope_distance_m`` with their SDs.  An FBL
preset run with ``--model fblplus`` is lifted to FBL+ with the neutral extra parameters
(:func:`jaxgait.control.fblplus.lift_fbl`).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import sys

import numpy as np

from jaxgait import models
from jaxgait.analysis.robustness import TEST_CHOICES, RobustnessConfig, robustness
from jaxgait.control.fblplus import lift_fbl
from jaxgait.core.jsonio import json_safe
from jaxgait.presets import load_preset, preset_dynamics


def model_choices() -> tuple[str, ...]:
    """Models the robustness tests run: the planar models of the registry."""
    return models.model_names("planar")


def get_model(name: str):
    """The planar model ``name`` from the registry (cached there)."""
    if name not in model_choices():
        raise ValueError(f"unknown model {name!r}; available: {', '.join(model_choices())}")
    return models.get_model(name)


def params_for_model(declared: str, vec: np.ndarray, requested: str | None):
    """(model name, vector) to run: an FBL preset is lifted to FBL+ on request."""
    name = requested or declared
    if name not in model_choices():
        raise ValueError(f"model {name!r} is not available here ({', '.join(model_choices())})")
    if name == declared:
        return name, vec
    if declared == "fbl" and name == "fblplus":
        return name, lift_fbl(vec)
    raise ValueError(f"the preset is for model {declared!r}; it cannot run as {name!r}")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m jaxgait.robustness",
        description="Maximum push, wavy-ground slope and increasing-slope distance of a preset.",
    )
    p.add_argument("preset", help="preset name, preset JSON file, or results folder")
    p.add_argument("--model", choices=model_choices(), default=None, help="default: the preset's")
    p.add_argument("--seeds", type=int, default=5, help="environment draws per measure (5)")
    p.add_argument("--seed", type=int, default=0, help="base PRNG seed (0)")
    p.add_argument(
        "--duration", type=float, default=60.0, help="max. time of the slope walks [s] (60)"
    )
    p.add_argument("--after-push", type=float, default=5.0, help="time judged after a push [s] (5)")
    p.add_argument("--push-env", choices=("random_push", "push"), default="random_push")
    p.add_argument(
        "--push-window",
        type=float,
        nargs=2,
        default=(3.0, 8.0),
        metavar=("T_MIN", "T_MAX"),
        help="window of the push start time [s] (3 8)",
    )
    p.add_argument(
        "--push-max-duration", type=float, default=1.0, help="push duration clip [s] (1)"
    )
    p.add_argument(
        "--push-duration",
        type=float,
        default=None,
        help="with --push-env push: the push's duration [s] (default 0.25)",
    )
    p.add_argument("--push-step", type=float, default=20.0, help="ladder spacing [N] (20)")
    p.add_argument("--push-max", type=float, default=400.0, help="largest push tried [N] (400)")
    p.add_argument("--push-per-rung", type=int, default=4, help="amplitudes per batch (4)")
    p.add_argument("--push-refine", type=int, default=1, help="m-section rounds (1)")
    p.add_argument(
        "--tests", default="push,wavy,slope", help="comma list of push, wavy, slope (all)"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    return p


def format_report(rep: dict) -> str:
    """Readable summary of a :func:`robustness` report."""
    lines = [f"preset {rep.get('preset')}  model {rep.get('model')}  seeds {rep.get('seeds')}"]
    rows = (
        ("max push", "max_push_N", "N", "max_push_censored"),
        ("max slope change (wavy)", "max_slope_pct", "%", "max_slope_censored"),
        ("distance on increasing slope", "slope_distance_m", "m", "slope_censored"),
        ("grade reached on it", "slope_max_grade_pct", "%", "slope_censored"),
    )
    for label, key, unit, cens in rows:
        if key in rep:
            c = rep.get(cens, 0)
            note = f"  ({c} of {rep['seeds']} censored: did not fail)" if c else ""
            lines.append(f"  {label:<30} {rep[key]:8.2f} +- {rep[key + '_sd']:6.2f} {unit}{note}")
    return "\n".join(lines)


def main(argv=None) -> int:
    """CLI entry point; 0 on success, 2 on bad input."""
    try:
        a = _parser().parse_args(argv)
    except SystemExit as e:
        return int(e.code) if isinstance(e.code, int) else 2
    out = sys.stdout
    with contextlib.redirect_stdout(sys.stderr):
        try:
            tests = tuple(t.strip() for t in a.tests.split(",") if t.strip())
            bad = sorted(set(tests) - set(TEST_CHOICES))
            if bad or not tests:
                raise ValueError(f"--tests: unknown {bad}; valid: {', '.join(TEST_CHOICES)}")
            rcfg = RobustnessConfig(
                seeds=a.seeds,
                seed=a.seed,
                duration=a.duration,
                after_push=a.after_push,
                push_env=a.push_env,
                push_t_min=a.push_window[0],
                push_t_max=a.push_window[1],
                push_max_duration=a.push_max_duration,
                push_duration=a.push_duration,
                push_step=a.push_step,
                push_max=a.push_max,
                push_per_rung=a.push_per_rung,
                push_refine=a.push_refine,
            )
            declared, vec, doc = load_preset(a.preset)
            # the preset's start (as evaluate): its initial speed and posture
            rcfg = dataclasses.replace(
                rcfg, v0=doc.get("v0"), pose=doc.get("pose"), dynamics=preset_dynamics(doc)
            )
            name, vec = params_for_model(declared, vec, a.model)
            model = get_model(name)
            rep = {"preset": str(a.preset), **robustness(model, vec, rcfg, tests)}
        except ValueError as e:
            print(f"jaxgait.robustness: error: {e}", file=sys.stderr)
            return 2
    text = json.dumps(json_safe(rep), allow_nan=False) if a.json else format_report(rep)
    print(text, file=out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
