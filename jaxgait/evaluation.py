"""Evaluation API: simulate a parameter preset once and measure the gait, for every model.

:func:`run` simulates a planar preset (FBL, FBL+, the spinal networks) and returns the whole
record (:class:`EvalRun`: report, measures, trace, events, summary, final state);
:func:`evaluate` returns the report dict of any model, Taga's included.  A Taga report uses
the planar report's key for the same measure (:func:`taga_report`; the schema is in
``docs/measures.md``).  The command line over it is :mod:`jaxgait.evaluate`.
"""

from __future__ import annotations

import functools
import importlib
import math
from dataclasses import dataclass

import numpy as np

from jaxgait import models
from jaxgait.analysis.refdata import GAIT_REFERENCES
from jaxgait.core.jsonio import json_safe
from jaxgait.core.limits import LimitError, check_duration
from jaxgait.presets import load_preset, preset_dynamics, preset_from_dict, resolve_preset


class EvaluateError(ValueError):
    """Bad input to :func:`evaluate` / :func:`run` (model, environment, duration, paths)."""


@dataclass
class EvalRun:
    """Everything one FBL evaluation produced (host-side NumPy arrays).

    Attributes:
      report: the JSON-ready dict of :func:`evaluate`.
      measures: :func:`jaxgait.analysis.measures.compute_measures` output (NumPy).
      trace, events, summary: the rollout record (NumPy leaves).
      final_state: the final :class:`~jaxgait.sim.SimState` (JAX arrays).
      model: the :class:`~jaxgait.sim.Model`; vec: (D,) parameters; doc: the preset document.
      env: the :class:`~jaxgait.world.envs.Env`; cfg: the :class:`~jaxgait.sim.SimConfig`.
    """

    report: dict
    measures: dict
    trace: object
    events: object
    summary: object
    final_state: object
    model: object
    vec: np.ndarray
    doc: dict
    env: object
    cfg: object


# --------------------------------------------------------------------------- helpers


def _load(preset) -> tuple[str, np.ndarray, dict, str, str]:
    """(model, vec, doc, label, file) for a preset name / path / dict."""
    if isinstance(preset, dict):
        model, vec, doc = preset_from_dict(preset, where="preset dict")
        return model, vec, doc, str(preset.get("name", "<dict>")), ""
    path = resolve_preset(preset)
    model, vec, doc = load_preset(path)
    return model, vec, doc, str(preset), str(path)


#: Human gait references of :func:`run` (``reference=``): the analysis layer's names.
REFERENCES = GAIT_REFERENCES


def reference_data(name: str):
    """``(Kinematics, VerticalGRF)`` of the human gait named ``name`` (:data:`REFERENCES`)."""
    from jaxgait.analysis import refdata

    if name not in REFERENCES:
        raise EvaluateError(f"unknown reference {name!r}; valid: {', '.join(REFERENCES)}")
    return refdata.gait_reference(name)


def _check_log_dt(log_dt, dt: float) -> float:
    """``log_dt`` [s] if it is a positive whole multiple of the physics step ``dt``."""
    ok = isinstance(log_dt, (int, float)) and not isinstance(log_dt, bool) and log_dt > 0
    k = round(log_dt / dt) if ok and math.isfinite(log_dt) else 0
    if k < 1 or abs(k * dt - log_dt) > 1e-9:
        raise EvaluateError(
            f"log interval {log_dt!r} s must be a positive whole multiple of the physics step "
            f"{dt:g} s (e.g. {dt:g} or 0.01)"
        )
    return float(k * dt)


def _check_inputs(env: str, duration: float, seed: int) -> None:
    from jaxgait.world.envs import ENVIRONMENTS

    if env not in ENVIRONMENTS:
        raise EvaluateError(f"unknown environment {env!r}; valid names: {', '.join(ENVIRONMENTS)}")
    try:
        check_duration(duration, what="duration")
    except LimitError as e:
        raise EvaluateError(str(e)) from None
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise EvaluateError(f"environment seed must be a non-negative integer, got {seed!r}")


def env_config(env: str, overrides: dict | None = None):
    """The config of environment ``env`` with ``overrides`` (field -> value) applied.

    Raises:
      EvaluateError: unknown environment, unknown field or invalid value (the message lists
        the valid fields).
    """
    from jaxgait.world.envs import get_env_config

    if overrides is not None and not isinstance(overrides, dict):
        raise EvaluateError(f"environment overrides must be a dict of fields, got {overrides!r}")
    try:
        return get_env_config(env, **(overrides or {}))
    except (TypeError, ValueError) as e:
        raise EvaluateError(f"environment {env!r}: {e}") from None


def _choose_model(requested: str | None, declared: str, label: str) -> str:
    """The model to run: ``requested`` if given (must agree with the preset), else declared."""
    for name in (requested, declared):
        if name is not None and name not in models.model_names():
            _fbl_model(name)  # raises EvaluateError: the name is not registered
    if requested is not None and requested != declared:
        raise EvaluateError(
            f"model {requested!r} was requested (--model) but the preset {label} is for "
            f"model {declared!r}; leave --model out to use the preset's model"
        )
    return declared


def _fbl_model(name: str):
    """The planar model ``name`` from the registry (cached there)."""
    if name not in models.model_names("planar"):
        raise EvaluateError(
            f"model {name!r} is not available in this version of jaxgait "
            f"(available: {', '.join(models.model_names())})"
        )
    return models.get_model(name)


@functools.lru_cache(maxsize=8)
def _jit_rollout(name: str, cfg):
    from jaxgait import sim

    return sim.make_rollout(_fbl_model(name), cfg, batched=False)


def _report(
    meas: dict, *, label: str, file: str, model: str, env: str, seed: int, duration: float
) -> dict:
    from jaxgait.analysis.measures import MEASURE_UNITS

    rep = {}
    units = {}
    for k, v in meas.items():
        if np.ndim(v) == 0:
            rep[k] = json_safe(v)
            units[k] = MEASURE_UNITS.get(k, "")
    rep["mean_trunk_lean_deg"] = json_safe(np.rad2deg(float(meas["mean_trunk_lean_rad"])))
    units["mean_trunk_lean_deg"] = "deg"
    rep["duration_requested_s"] = float(duration)
    units["duration_requested_s"] = "s"
    rep.update(preset=label, preset_file=file, model=model, env=env, env_seed=int(seed))
    rep["units"] = units
    return rep


# --------------------------------------------------------------------------- API


def run(
    preset,
    env: str = "flat",
    duration: float = 20.0,
    seed: int = 0,
    model: str | None = None,
    v0: float | None = None,
    reference: str = "walking",
    log_dt: float | None = None,
    env_overrides: dict | None = None,
    dynamics: str | None = None,
) -> EvalRun:
    """Simulate an FBL-family preset once and measure it.

    Args:
      preset: preset name, JSON path, results folder, or a preset dict.
      env: environment name (:data:`jaxgait.world.envs.ENVIRONMENTS`).
      duration: maximal simulated time [s] (the run stops earlier on a fall).
      seed: environment PRNG seed (same seed, same terrain and pushes).
      model: model name; default the preset's ``model`` (must agree if given).
      v0: initial forward speed [m/s]; default the preset's ``v0`` entry (written by
        ``train`` for its best), else :attr:`jaxgait.sim.SimConfig.v0` (1.3).  The start
        posture is the preset's ``pose`` entry (a key of :data:`jaxgait.sim.POSES`), else
        Geyer's.
      reference: human gait the joint-angle correlations, standard scores and ``grf_corr``
        compare with: ``"walking"`` (Winter, 1.33 m/s) or ``"running"`` (Fukuchi, 3.5 m/s).
      log_dt: interval of the logged trajectory [s], a whole multiple of the physics step
        (default :attr:`jaxgait.sim.SimConfig.log_dt`, 10 ms); the per-stance GRF peaks are
        measured at the physics step whatever it is.
      env_overrides: fields of the environment's config to replace (e.g. ``{"fraction":
        0.2}`` for ``weight_support``); reported under ``env_overrides``.
      dynamics: ``"mjx"`` or ``"planar"`` (:data:`jaxgait.sim.DYNAMICS`), the multibody
        dynamics to simulate with; default the preset's ``dynamics`` entry (written by
        ``train``), else ``"mjx"`` (a preset without it was made with MJX's passes).  The
        two agree to rounding, but a gait in a narrow basin can fall under the other's
        rounding; reported under ``dynamics``.

    Returns:
      An :class:`EvalRun` (report, measures, trace, events, summary, final state...).

    Raises:
      PresetError, EvaluateError: bad input (both are ``ValueError``).
    """
    import jax

    from jaxgait import sim
    from jaxgait.analysis.measures import compute_measures
    from jaxgait.world import envs

    _check_inputs(env, duration, seed)
    ref, grf_ref = reference_data(reference)
    declared, vec, doc, label, file = _load(preset)
    name = _choose_model(model, declared, label)
    if name in models.model_names("taga"):
        raise EvaluateError(f"run() simulates FBL models; use evaluate() for model {name!r}")
    mdl = _fbl_model(name)
    table = doc.get("table", declared)
    if table != mdl.table.name or vec.shape != (mdl.table.size,):
        raise EvaluateError(
            f"preset {label} holds parameter table {table!r} ({vec.size} values); model "
            f"{name!r} needs table {mdl.table.name!r} ({mdl.table.size} values)"
        )
    if v0 is None:
        v0 = doc.get("v0", sim.SimConfig.v0)
    if isinstance(v0, bool) or not isinstance(v0, (int, float)) or not math.isfinite(v0):
        raise EvaluateError(f"initial speed v0 must be a finite number [m/s], got {v0!r}")
    cfg_kw = {} if log_dt is None else {"log_dt": _check_log_dt(log_dt, mdl.dt)}
    pose = doc.get("pose", sim.SimConfig.pose)
    if pose not in sim.POSES:
        raise EvaluateError(
            f"preset {label}: unknown start pose {pose!r}; "
            f"available: {', '.join(sorted(sim.POSES))}"
        )
    own = dynamics is None
    if own:
        dynamics = preset_dynamics(doc)
    if dynamics not in sim.DYNAMICS:
        where = f"preset {label}" if own else "dynamics"
        raise EvaluateError(
            f"{where}: unknown dynamics {dynamics!r}; available: {', '.join(sim.DYNAMICS)}"
        )
    cfg = sim.SimConfig(
        duration=float(duration), v0=float(v0), pose=pose, dynamics=dynamics, **cfg_kw
    )
    env_cfg = env_config(env, env_overrides)
    environment = envs.make_env(env_cfg, jax.random.PRNGKey(int(seed)))
    params = mdl.table.as_jnp(vec)
    trace, events, summary, final = _jit_rollout(name, cfg)(params, environment)
    meas = compute_measures(trace, events, summary, reference=ref, grf_reference=grf_ref)
    to_np = lambda tree: jax.tree.map(np.asarray, tree)
    meas, trace, events, summary = to_np(meas), to_np(trace), to_np(events), to_np(summary)
    rep = _report(meas, label=label, file=file, model=name, env=env, seed=seed, duration=duration)
    rep["dynamics"] = dynamics
    if env_overrides:
        rep["env_overrides"] = dict(env_overrides)
    return EvalRun(rep, meas, trace, events, summary, final, mdl, vec, doc, environment, cfg)


def _taga_env(env: str) -> tuple[str, float]:
    """Taga's (env, slope) for an environment name: flat ground or a constant grade."""
    from jaxgait.world.envs import ENVIRONMENTS

    if env == "flat":
        return "flat", 0.0
    grade = getattr(ENVIRONMENTS[env], "grade", None)
    if env.startswith("slope") and grade is not None:
        return "slope", float(grade)
    raise EvaluateError(
        f"environment {env!r} is not available for model 'taga' (use flat, slope_up, slope_down)"
    )


def _evaluate_taga(
    doc: dict,
    label: str,
    file: str,
    env: str,
    duration: float,
    seed: int,
    with_rollout: bool = False,
):
    """The Taga report; with ``with_rollout`` ``(report, log, terrain)``."""
    taga_env, slope = _taga_env(env)
    name = "run_preset" if with_rollout else "evaluate_preset"
    try:
        taga = importlib.import_module("jaxgait.taga")
        fn = getattr(taga, name)
    except (ImportError, AttributeError):
        raise EvaluateError(
            f"model 'taga' cannot be evaluated: jaxgait.taga.{name} is not available "
            "in this installation"
        ) from None
    out = fn(doc, duration=float(duration), env=taga_env, slope=slope)
    log = terrain = None
    if with_rollout:
        out, _, log, terrain = out
    rep = taga_report(json_safe(dict(out)))
    rep.update(preset=label, preset_file=file, model="taga", env=env, env_seed=int(seed))
    rep["duration_requested_s"] = float(duration)
    from jaxgait.analysis.measures import MEASURE_UNITS

    units = {**MEASURE_UNITS, **TAGA_UNITS}
    rep["units"] = {k: units[k] for k in rep if k in units}
    return (rep, log, terrain) if with_rollout else rep


#: Taga measures renamed to the key the planar report uses for the same measure
#: (docs/measures.md).
TAGA_RENAMED = {
    "speed_mps": "steady_speed_mps",
    "double_support_fraction": "double_stance_fraction",
}
#: Units of the keys a Taga report has beside the planar measures (:data:`MEASURE_UNITS`).
TAGA_UNITS = {
    "steady_speed_mps": "m/s",
    "stride_speed_mps": "m/s",
    "stride_length_m": "m",
    "stride_length_sd_m": "m",
    "stride_duration_s": "s",
    "stride_duration_sd_s": "s",
    "flight_fraction": "-",
    "n_strides": "count",
    "window_s": "s, [start, end]",
    "u0": "-",
    "slope": "rise/run",
    "duration_requested_s": "s",
}


def taga_report(measures: dict) -> dict:
    """A Taga measures dict in the keys of the planar report (docs/measures.md): renamed by
    :data:`TAGA_RENAMED`, plus ``mean_speed_mps`` = distance / duration and
    ``cycle_frequency_hz`` = 1 / stride duration, as the planar report defines them."""
    rep = {TAGA_RENAMED.get(k, k): v for k, v in measures.items()}
    d, t = rep.get("distance_m"), rep.get("duration_s")
    if isinstance(d, (int, float)) and isinstance(t, (int, float)):
        rep["mean_speed_mps"] = float(d) / float(t) if t > 0 else 0.0
    stride = rep.get("stride_duration_s")
    if "stride_duration_s" in rep:
        ok = isinstance(stride, (int, float)) and stride > 0
        rep["cycle_frequency_hz"] = 1.0 / float(stride) if ok else None
    return rep


def evaluate(
    preset,
    env: str = "flat",
    duration: float = 20.0,
    seed: int = 0,
    model: str | None = None,
    reference: str = "walking",
) -> dict:
    """Simulate a preset and return its gait measures as a JSON-ready dict.

    For FBL models the dict holds every scalar of :func:`jaxgait.analysis.measures.compute_measures`
    (``distance_m``, ``duration_s``, ``fell``, ``mean_speed_mps``, ``energy_J_per_m``,
    ``cost_of_transport``, ``c_angles``, ``corr_hip``, ``corr_knee``, ``corr_ankle``,
    ``step_length_snr``, ``step_length_mean_m``, ``n_steps``, ``double_stance_fraction``,
    ...), plus ``mean_trunk_lean_deg``, ``duration_requested_s``, ``preset``,
    ``preset_file``, ``model``, ``env``, ``env_seed`` and ``units`` (key -> unit). Numbers
    are Python floats / ints / bools; non-finite values are None. For model ``taga`` the dict
    of :func:`jaxgait.taga.evaluate_preset` is returned, with the same identification keys.

    Args: as :func:`run`.
    """
    _check_inputs(env, duration, seed)
    declared, _, doc, label, file = _load(preset)
    name = _choose_model(model, declared, label)
    if name == "taga":
        return _evaluate_taga(doc, label, file, env, duration, seed)
    return run(
        preset, env=env, duration=duration, seed=seed, model=model, reference=reference
    ).report
