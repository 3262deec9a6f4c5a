"""Taga, Yamaguchi & Shimizu (1991): a neural-oscillator biped that walks, runs and switches.

Biol. Cybern. 65:147-159.  Five-link planar body (``models/taga1991.xml``, MJX), the 2-D
ground spring-damper with touchdown reset (Appendix A), twelve Matsuoka neurons (eq. 5-6)
with the feedback pathways of Appendix C and all numbers of Appendix D.

Typical use::

    from jaxgait import taga
    taga.evaluate_preset("taga_walk", duration=20.0)      # JSON-able measures
    state, log = taga.simulate(taga.TagaParams(u0=5.5), duration=20.0)

Experiments: ``python -m jaxgait.taga.experiments {fig5,fig6,fig7,ground,slope,fig11,all}``.
"""

from __future__ import annotations

import json
from pathlib import Path

from jaxgait.taga.measures import gait_measures, window_measures
from jaxgait.taga.model import Options, TagaParams, params_from_dict
from jaxgait.taga.sim import Push, Taga, TagaState, default_sim, push_on, simulate

__all__ = [
    "Options",
    "Push",
    "Taga",
    "TagaParams",
    "TagaState",
    "default_sim",
    "evaluate_preset",
    "gait_measures",
    "load_preset",
    "params_from_dict",
    "push_on",
    "run_preset",
    "simulate",
    "terrain_for",
    "window_measures",
]

ENVS = ("flat", "slope")


def load_preset(preset: str | dict) -> dict:
    """A Taga preset as a dict ``{"model": "taga", "description": ..., "params": {...}}``.

    ``preset`` is a dict, a path to a JSON file, or a preset name in the shipped presets
    folder (``experiments/presets/NAME.json``).  An optional ``"options"`` entry holds
    :class:`Options` fields and ``"dt"`` the time step [s].
    """
    if isinstance(preset, dict):
        d = dict(preset)
    else:
        from jaxgait.core.resources import presets_dir

        p = Path(preset)
        if not p.suffix == ".json" or not p.exists():
            p = presets_dir() / f"{preset}.json"
        if not p.exists():
            avail = sorted(x.stem for x in presets_dir().glob("taga*.json"))
            raise FileNotFoundError(f"no Taga preset {preset!r}; available: {avail}")
        try:
            d = json.loads(p.read_text())
        except json.JSONDecodeError as e:
            raise ValueError(f"preset {p} is not valid JSON: {e}") from e
    if d.get("model", "taga") != "taga":
        raise ValueError(f"preset is for model {d.get('model')!r}, not 'taga'")
    if not isinstance(d.get("params", {}), dict):
        raise ValueError("preset 'params' must be a JSON object")
    return d


def terrain_for(env: str = "flat", slope: float = 0.0, start: float = 5.0):
    """Terrain of an evaluation environment: ``"flat"``, or ``"slope"`` with the given
    grade (rise/run, negative = downhill) beginning ``start`` metres ahead of the start."""
    from jaxgait.world import terrain

    if env not in ENVS:
        raise ValueError(f"unknown environment {env!r} for the Taga model; choose from {ENVS}")
    if env == "flat" and slope == 0.0:
        return terrain.flat()
    return terrain.slope(float(slope), start=start)


def evaluate_preset(
    preset: str | dict, duration: float, env: str = "flat", slope: float = 0.0
) -> dict:
    """Simulate a Taga preset from the Appendix E state and return its gait measures.

    Args:
      preset: preset name (``"taga_walk"``, ``"taga_run"``), JSON path or dict.
      duration: simulated time [s].
      env: ``"flat"`` or ``"slope"``; slope: grade (rise/run), the slope starts 5 m ahead.
    Returns:
      JSON-able dict: speed_mps, stride_length_m, stride_duration_s,
      double_support_fraction, flight_fraction, fell, distance_m, duration_s (steady-state
      values over the second half of the walk, or of the part before a fall), plus
      preset, u0, env, slope.
    """
    return run_preset(preset, duration, env, slope)[0]


def run_preset(preset: str | dict, duration: float, env: str = "flat", slope: float = 0.0):
    """:func:`evaluate_preset` with the rollout: ``(measures, final state, log, terrain)``
    (the :class:`~jaxgait.taga.sim.Log` has one row every 10 ms)."""
    d = load_preset(preset)
    params = params_from_dict(d.get("params"))
    opts = dict(d.get("options", {}))
    dt = d.get("dt", opts.pop("dt", None))
    sim = default_sim(dt, **opts)
    cap = max(64, int(duration * 6) + 16)
    terrain = terrain_for(env, slope)
    state, log = simulate(params, duration, terrain, sim=sim, state=sim.init(event_capacity=cap))
    out = gait_measures(log, state.events, state)
    name = preset if isinstance(preset, str) else d.get("name", "custom")
    out.update(preset=name, u0=float(params.u0), env=env, slope=float(slope), model="taga")
    return out, state, log, terrain
