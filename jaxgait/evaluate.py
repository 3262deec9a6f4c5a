"""Evaluate a parameter preset: simulate it in one environment and report the gait measures.

Command line::

    python -m jaxgait.evaluate PRESET_OR_FILE [--model fbl|fblplus|taga]
        [--env flat|slope_up|slope_down|push|random_push|wavy|increasing_slope]
        [--env-seed N] [--duration S] [--json] [--save-trajectory PATH] [--plots DIR]
        [--save-scene PATH]

``PRESET_OR_FILE`` is a shipped preset name, a preset JSON file or a results folder holding
``best.json`` (see :mod:`jaxgait.presets`). The model defaults to the preset's ``model``
field; ``--model`` must agree with it. Without ``--json`` a readable table is printed; with
``--json`` exactly one JSON object (see :func:`evaluate` for its keys; non-finite numbers
are ``null``). ``--save-trajectory`` writes the alive samples as CSV
(:mod:`jaxgait.analysis.trajectory_io`), ``--plots`` the figures of
:func:`jaxgait.analysis.plots.plot_all`,
``--save-scene`` an MJCF scene of the body on the environment's terrain over the walked range
(:mod:`jaxgait.world.scene`; open it with ``python -m mujoco.viewer --mjcf PATH``).

Exit codes: 0 success, 2 bad input (unknown preset or parameter, bad environment name,
non-positive duration, unwritable output, model not available), with a message on stderr.

Python API: :func:`evaluate` returns the report dict; :func:`run` also returns the trace,
events, summary and final state (for notebooks).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jaxgait import models
from jaxgait.core.jsonio import json_safe
from jaxgait.presets import load_preset, preset_from_dict, resolve_preset

#: Environment names (keys of :data:`jaxgait.world.envs.ENVIRONMENTS`).
ENV_CHOICES = (
    "flat",
    "slope_up",
    "slope_down",
    "push",
    "random_push",
    "wavy",
    "increasing_slope",
)
#: Ground shown by ``--save-scene`` behind the start and ahead of the end of the walk [m].
_SCENE_BEHIND, _SCENE_AHEAD = 3.0, 5.0

#: Report keys shown in the readable table: (label, key, format, unit).
_TABLE_ROWS = (
    ("distance", "distance_m", ".3f", "m"),
    ("simulated time", "duration_s", ".2f", "s"),
    ("fell", "fell", "", ""),
    ("mean speed", "mean_speed_mps", ".3f", "m/s"),
    ("energy", "energy_J", ".1f", "J"),
    ("energy per distance", "energy_J_per_m", ".1f", "J/m"),
    ("cost of transport", "cost_of_transport", ".3f", "J/(kg m)"),
    ("cost of transport (E/mgd)", "cost_of_transport_dimless", ".3f", "-"),
    ("steps (touchdowns)", "n_steps", "d", ""),
    ("full right cycles", "n_cycles", "d", ""),
    ("step length mean", "step_length_mean_m", ".3f", "m"),
    ("step length SD", "step_length_sd_m", ".4f", "m"),
    ("step length SNR", "step_length_snr", ".2f", "log(m/m^2)"),
    ("cycle frequency", "cycle_frequency_hz", ".3f", "Hz"),
    ("double stance fraction", "double_stance_fraction", ".3f", "-"),
    ("mean trunk lean", "mean_trunk_lean_deg", ".2f", "deg"),
    ("corr. hip (Winter)", "corr_hip", ".3f", "-"),
    ("corr. knee (Winter)", "corr_knee", ".3f", "-"),
    ("corr. ankle (Winter)", "corr_ankle", ".3f", "-"),
    ("c_angles (min corr.)", "c_angles", ".3f", "-"),
)


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


def _check_inputs(env: str, duration: float, seed: int) -> None:
    from jaxgait.world.envs import ENVIRONMENTS

    if env not in ENVIRONMENTS:
        raise EvaluateError(f"unknown environment {env!r}; valid names: {', '.join(ENVIRONMENTS)}")
    if not isinstance(duration, (int, float)) or not (math.isfinite(duration) and duration > 0):
        raise EvaluateError(f"duration must be a positive number of seconds, got {duration!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise EvaluateError(f"environment seed must be a non-negative integer, got {seed!r}")


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
) -> EvalRun:
    """Simulate an FBL-family preset once and measure it.

    Args:
      preset: preset name, JSON path, results folder, or a preset dict.
      env: environment name (:data:`jaxgait.world.envs.ENVIRONMENTS`).
      duration: maximal simulated time [s] (the run stops earlier on a fall).
      seed: environment PRNG seed (same seed, same terrain and pushes).
      model: model name; default the preset's ``model`` (must agree if given).
      v0: initial forward speed [m/s]; default the preset's ``v0`` entry (written by
        ``train`` for its best), else :attr:`jaxgait.sim.SimConfig.v0` (1.3).

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
    cfg = sim.SimConfig(duration=float(duration), v0=float(v0))
    environment = envs.make_env(env, jax.random.PRNGKey(int(seed)))
    params = mdl.table.as_jnp(vec)
    trace, events, summary, final = _jit_rollout(name, cfg)(params, environment)
    meas = compute_measures(trace, events, summary)
    to_np = lambda tree: jax.tree.map(np.asarray, tree)
    meas, trace, events, summary = to_np(meas), to_np(trace), to_np(events), to_np(summary)
    rep = _report(meas, label=label, file=file, model=name, env=env, seed=seed, duration=duration)
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


def _evaluate_taga(doc: dict, label: str, file: str, env: str, duration: float, seed: int):
    import importlib

    taga_env, slope = _taga_env(env)
    try:
        taga = importlib.import_module("jaxgait.taga")
        fn = taga.evaluate_preset
    except (ImportError, AttributeError):
        raise EvaluateError(
            "model 'taga' cannot be evaluated: jaxgait.taga.evaluate_preset is not available "
            "in this installation"
        ) from None
    out = fn(doc, duration=float(duration), env=taga_env, slope=slope)
    rep = json_safe(dict(out))
    rep.update(preset=label, preset_file=file, model="taga", env=env, env_seed=int(seed))
    rep["duration_requested_s"] = float(duration)
    return rep


def evaluate(
    preset,
    env: str = "flat",
    duration: float = 20.0,
    seed: int = 0,
    model: str | None = None,
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
    return run(preset, env=env, duration=duration, seed=seed, model=model).report


# --------------------------------------------------------------------------- CLI


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m jaxgait.evaluate",
        description="Simulate a parameter preset in one environment and report gait measures.",
    )
    p.add_argument("preset", help="preset name, preset JSON file, or results folder (best.json)")
    p.add_argument(
        "--model",
        choices=models.model_names(),  # every registered model (jaxgait.models)
        default=None,
        help="model family (default: the preset's 'model' field)",
    )
    p.add_argument("--env", default="flat", help=f"environment: {', '.join(ENV_CHOICES)}")
    p.add_argument("--env-seed", type=int, default=0, help="environment PRNG seed (default 0)")
    p.add_argument(
        "--duration",
        type=float,
        default=20.0,
        help="maximal simulated time in seconds (default 20)",
    )
    p.add_argument(
        "--v0",
        type=float,
        default=None,
        help="initial forward speed [m/s] (default: the preset's v0 entry, else 1.3)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.add_argument(
        "--save-trajectory",
        metavar="PATH",
        type=Path,
        default=None,
        help="write the trajectory CSV to PATH; its columns root_x_m, root_z_m, "
        "trunk_lean_deg, hip_r_deg, knee_r_deg, ankle_r_deg, hip_l_deg, knee_l_deg, "
        "ankle_l_deg (degrees converted to radians) are the qpos of the --save-scene model, "
        "row by row (jaxgait.world.scene.trajectory_qpos): set data.qpos and call "
        "mujoco.mj_forward "
        "to replay",
    )
    p.add_argument(
        "--plots", metavar="DIR", type=Path, default=None, help="write the PNG figures into DIR"
    )
    p.add_argument(
        "--save-scene",
        metavar="PATH",
        type=Path,
        default=None,
        help="write an MJCF scene to PATH: the body model on the environment's terrain "
        f"(height field, display only) from {_SCENE_BEHIND:g} m behind to {_SCENE_AHEAD:g} m "
        "ahead of the walked range; view it with: python -m mujoco.viewer --mjcf PATH",
    )
    return p


def _check_output_file(path: Path, flag: str = "--save-trajectory") -> None:
    parent = path.expanduser().resolve().parent
    if path.is_dir():
        raise EvaluateError(f"{flag} {path}: is a folder, need a file path")
    if not parent.is_dir():
        raise EvaluateError(f"{flag} {path}: folder {parent} does not exist")
    if not os.access(parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise EvaluateError(f"{flag} {path}: not writable")


def scene_range(trace) -> tuple[float, float]:
    """(x0, x1) [m] of the ground ``--save-scene`` shows for a rollout.

    The range of the root x position (hip) over the alive samples (0 if there are none),
    widened by 3 m behind and 5 m ahead.
    """
    alive = np.asarray(trace.alive, bool).reshape(-1)
    x = np.asarray(trace.qpos, np.float64)[alive, 0]
    lo, hi = (float(x.min()), float(x.max())) if x.size else (0.0, 0.0)
    return lo - _SCENE_BEHIND, hi + _SCENE_AHEAD


def _check_output_dir(path: Path) -> None:
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise EvaluateError(f"--plots {path}: cannot create folder ({e.strerror})") from None
    if not os.access(path, os.W_OK):
        raise EvaluateError(f"--plots {path}: folder not writable")


def format_report(rep: dict) -> str:
    """Readable multi-line table of an FBL report."""
    head = (
        f"preset {rep.get('preset')}"
        + (
            f" ({rep['preset_file']})"
            if rep.get("preset_file") and rep.get("preset_file") != rep.get("preset")
            else ""
        )
        + f"\nmodel {rep.get('model')}, environment {rep.get('env')} "
        f"(seed {rep.get('env_seed')}), {rep.get('duration_requested_s', 0):g} s requested"
    )
    lines = [head, ""]
    for label, key, fmt, unit in _TABLE_ROWS:
        if key not in rep:
            continue
        v = rep[key]
        if v is None:
            s = "n/a"
        elif isinstance(v, bool):
            s = "yes" if v else "no"
        else:
            s = format(v, fmt)
        lines.append(f"  {label:<24} {s:>12} {unit}")
    if rep.get("n_cycles", 1) == 0:
        lines.append("  (no full gait cycle: correlations are 0 by convention)")
    return "\n".join(lines)


def _print_generic(rep: dict) -> str:
    w = max((len(k) for k in rep), default=0)
    return "\n".join(f"  {k:<{w}}  {v}" for k, v in rep.items() if k != "units")


def main(argv=None) -> int:
    """Command-line entry point; returns the exit code (0 ok, 2 bad input).

    Anything the libraries print while loading and simulating goes to stderr, so that with
    ``--json`` stdout holds exactly one JSON object.
    """
    try:
        a = _parser().parse_args(argv)
    except SystemExit as e:  # argparse printed its message (or the help) already
        return int(e.code) if isinstance(e.code, int) else 2
    out = sys.stdout
    with contextlib.redirect_stdout(sys.stderr):
        from jaxgait.core import compile_cache

        compile_cache.enable()
        code, text = _main(a)
    if text is not None:
        print(text, file=out)
    return code


def _main(a: argparse.Namespace) -> tuple[int, str | None]:
    def err(msg):
        print(f"jaxgait.evaluate: error: {msg}", file=sys.stderr)
        return 2, None

    try:
        _check_inputs(a.env, a.duration, a.env_seed)
        declared, _, doc, label, file = _load(a.preset)
        name = _choose_model(a.model, declared, label)
        if name == "taga" and (a.save_trajectory or a.plots or a.save_scene):
            raise EvaluateError(
                "--save-trajectory, --plots and --save-scene are available for FBL models only"
            )
        if name == "taga":
            _taga_env(a.env)
        if a.save_trajectory is not None:
            _check_output_file(a.save_trajectory)
        if a.plots is not None:
            _check_output_dir(a.plots)
        if a.save_scene is not None:
            _check_output_file(a.save_scene, "--save-scene")
        if not a.json:
            print(f"simulating {label} ({name}, {a.env}, {a.duration:g} s)...", file=sys.stderr)
        if name == "taga":
            rep = _evaluate_taga(doc, label, file, a.env, a.duration, a.env_seed)
            result = None
        else:
            result = run(
                a.preset, env=a.env, duration=a.duration, seed=a.env_seed, model=name, v0=a.v0
            )
            rep = result.report
    except ValueError as e:  # PresetError, EvaluateError, invalid environment values
        return err(str(e))

    if result is not None:
        try:
            if a.save_trajectory is not None:
                from jaxgait.analysis.trajectory_io import write_trajectory_csv

                p = write_trajectory_csv(
                    a.save_trajectory, result.trace, result.summary, result.model
                )
                rep["trajectory_file"] = str(p)
            if a.plots is not None:
                from jaxgait.analysis.plots import plot_all

                paths = plot_all(
                    a.plots,
                    result.trace,
                    result.events,
                    result.summary,
                    result.model,
                    terrain=result.env.terrain,
                    measures_dict=result.measures,
                )
                rep["plot_files"] = {k: str(v) for k, v in paths.items()}
            if a.save_scene is not None:
                from jaxgait.world.scene import write_scene

                x0, x1 = scene_range(result.trace)
                p = write_scene(a.save_scene, result.env, x0, x1)  # FBL body: fbl_planar
                rep["scene_file"] = str(p)
        except OSError as e:
            where = getattr(e, "filename", None) or ""
            return err(f"cannot write output {where}: {e.strerror or e}")

    if a.json:
        return 0, json.dumps(json_safe(rep), allow_nan=False)
    text = format_report(rep) if result is not None else _print_generic(rep)
    if "trajectory_file" in rep:
        text += f"\n\ntrajectory written to {rep['trajectory_file']}"
    if "plot_files" in rep:
        text += "\nfigures written: " + ", ".join(rep["plot_files"].values())
    if "scene_file" in rep:
        text += (
            f"\nscene written to {rep['scene_file']} "
            f"(view: python -m mujoco.viewer --mjcf {rep['scene_file']})"
        )
    return 0, text


if __name__ == "__main__":
    sys.exit(main())
