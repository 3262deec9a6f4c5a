"""Evaluate a parameter preset: simulate it in one environment and report the gait measures.

Command line::

    python -m jaxgait.evaluate PRESET_OR_FILE [--model fbl|fblplus|taga]
        [--env flat|slope_up|slope_down|push|random_push|wavy|increasing_slope|weight_support]
        [--env-set FIELD=VALUE ...] [--env-seed N] [--duration S] [--json]
        [--save-trajectory PATH] [--plots DIR]
        [--save-scene PATH] [--video PATH.mp4|PATH.gif] [--video-backend auto|mujoco|matplotlib]
        [--video-fps N]

``PRESET_OR_FILE`` is a shipped preset name, a preset JSON file or a results folder holding
``best.json`` (see :mod:`jaxgait.presets`). The model defaults to the preset's ``model``
field; ``--model`` must agree with it. Without ``--json`` a readable table is printed; with
``--json`` exactly one JSON object (see :func:`evaluate` for its keys; non-finite numbers
are ``null``). ``--save-trajectory`` writes the alive samples as CSV
(:mod:`jaxgait.analysis.trajectory_io`), ``--plots`` the figures of
:func:`jaxgait.analysis.plots.plot_all`,
``--save-scene`` an MJCF scene of the body on the environment's terrain over the walked range
(:mod:`jaxgait.world.scene`; open it with ``python -m mujoco.viewer --mjcf PATH``), and
``--video`` a video of the walk for any model (:mod:`jaxgait.analysis.video`).

Exit codes: 0 success, 2 bad input (unknown preset or parameter, bad environment name,
non-positive duration, unwritable output, model not available), with a message on stderr.

Python API: :func:`evaluate` returns the report dict; :func:`run` also returns the trace,
events, summary and final state (for notebooks).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from pathlib import Path

import numpy as np

from jaxgait import models
from jaxgait.analysis.video import (
    BACKENDS,
    check_fps,
    check_video_path,
    choose_backend,
    motion_from_taga,
    motion_from_trace,
    write_video,
)
from jaxgait.core.jsonio import json_safe, parse_assignment
from jaxgait.evaluation import (  # noqa: F401 - the Python API, re-exported
    REFERENCES,
    TAGA_RENAMED,
    TAGA_UNITS,
    EvalRun,
    EvaluateError,
    _check_inputs,
    _choose_model,
    _evaluate_taga,
    _load,
    _taga_env,
    env_config,
    evaluate,
    reference_data,
    run,
    taga_report,
)

#: Environment names (keys of :data:`jaxgait.world.envs.ENVIRONMENTS`).
ENV_CHOICES = (
    "flat",
    "slope_up",
    "slope_down",
    "push",
    "random_push",
    "wavy",
    "increasing_slope",
    "weight_support",
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
    ("flight fraction", "flight_fraction", ".3f", "-"),
    ("steady speed (2nd half)", "steady_speed_mps", ".3f", "m/s"),
    ("stride length", "stride_length_m", ".3f", "m"),
    ("stride duration", "stride_duration_s", ".3f", "s"),
    ("mean trunk lean", "mean_trunk_lean_deg", ".2f", "deg"),
    ("corr. hip (Winter)", "corr_hip", ".3f", "-"),
    ("corr. knee (Winter)", "corr_knee", ".3f", "-"),
    ("corr. ankle (Winter)", "corr_ankle", ".3f", "-"),
    ("c_angles (min corr.)", "c_angles", ".3f", "-"),
)


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
        "--env-set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="replace a field of the environment's config, e.g. --env weight_support "
        "--env-set fraction=0.2 (repeatable; values are read as JSON numbers)",
    )
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
    p.add_argument(
        "--reference",
        choices=REFERENCES,
        default="walking",
        help="human joint angles for the correlations and standard scores: walking (Winter, "
        "default) or running (Fukuchi 3.5 m/s)",
    )
    p.add_argument(
        "--log-dt",
        type=float,
        default=None,
        help="interval of the logged trajectory (CSV, plots) in seconds, a multiple of the "
        "physics step (default 0.01; 0.0005 logs every step)",
    )
    p.add_argument(
        "--dynamics",
        choices=("mjx", "planar"),
        default=None,
        help="multibody dynamics to simulate with (default: the preset's own, written by "
        "train; mjx for a preset without it); the two agree to rounding",
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
    p.add_argument(
        "--video",
        metavar="PATH",
        type=Path,
        default=None,
        help="write a video of the walk to PATH (.mp4 or .gif), every model family",
    )
    p.add_argument(
        "--video-backend",
        choices=("auto", *BACKENDS),
        default="auto",
        help="mujoco: MuJoCo's offscreen renderer (needs EGL or OSMesa); matplotlib: stick "
        "figure; auto (default): mujoco where it works, else matplotlib",
    )
    p.add_argument(
        "--video-fps", type=float, default=30.0, help="video frames per second (default 30)"
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
    """Readable multi-line table of a report (the keys of any model it holds)."""
    head = (
        f"preset {rep.get('preset')}"
        + (
            f" ({rep['preset_file']})"
            if rep.get("preset_file") and rep.get("preset_file") != rep.get("preset")
            else ""
        )
        + f"\nmodel {rep.get('model')}"
        + (f" ({rep['dynamics']} dynamics)" if rep.get("dynamics") else "")
        + f", environment {rep.get('env')} "
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


def _env_sets(items: list[str]) -> dict:
    """``--env-set FIELD=VALUE`` options as a dict (VALUE as ``train --set`` reads it)."""
    out = {}
    for item in items:
        parsed = parse_assignment(item)
        if parsed is None:
            raise EvaluateError(f"--env-set {item!r}: expected FIELD=VALUE, e.g. fraction=0.2")
        out[parsed[0]] = parsed[1]
    return out


def _main(a: argparse.Namespace) -> tuple[int, str | None]:
    def err(msg):
        print(f"jaxgait.evaluate: error: {msg}", file=sys.stderr)
        return 2, None

    try:
        _check_inputs(a.env, a.duration, a.env_seed)
        env_overrides = _env_sets(a.env_set)
        env_config(a.env, env_overrides)
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
        backend = None
        if a.video is not None:
            check_video_path(a.video)
            check_fps(a.video_fps)
            backend = choose_backend(a.video_backend)
        if not a.json:
            print(f"simulating {label} ({name}, {a.env}, {a.duration:g} s)...", file=sys.stderr)
        result = motion = None
        if name == "taga":
            if a.dynamics is not None:
                return err(
                    "--dynamics: the Taga biped has its own equations (no MJX or planar tree)"
                )
            out = _evaluate_taga(
                doc, label, file, a.env, a.duration, a.env_seed, a.video is not None
            )
            rep = out[0] if a.video is not None else out
            if a.video is not None:
                motion = motion_from_taga(out[1], out[2], title=label)
        else:
            result = run(
                a.preset,
                env=a.env,
                duration=a.duration,
                seed=a.env_seed,
                model=name,
                v0=a.v0,
                reference=a.reference,
                log_dt=a.log_dt,
                env_overrides=env_overrides,
                dynamics=a.dynamics,
            )
            rep = result.report
            if a.video is not None:
                mass = float(np.asarray(result.summary.mass))
                motion = motion_from_trace(result.trace, result.env, title=label, mass=mass)
    except ValueError as e:  # PresetError, EvaluateError, VideoError, invalid values
        return err(str(e))

    if motion is not None:
        try:
            info = write_video(a.video, motion, backend=backend, fps=a.video_fps)
        except OSError as e:
            return err(f"cannot write video {a.video}: {e.strerror or e}")
        rep["video_file"] = str(info.path)
        rep["video_backend"] = info.backend
        rep["video_frames"] = info.frames

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

                kin, grf = reference_data(a.reference)
                paths = plot_all(
                    a.plots,
                    result.trace,
                    result.events,
                    result.summary,
                    result.model,
                    terrain=result.env.terrain,
                    measures_dict=result.measures,
                    reference=kin,
                    grf_reference=grf,
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
    text = format_report(rep)
    if "trajectory_file" in rep:
        text += f"\n\ntrajectory written to {rep['trajectory_file']}"
    if "plot_files" in rep:
        text += "\nfigures written: " + ", ".join(rep["plot_files"].values())
    if "scene_file" in rep:
        text += (
            f"\nscene written to {rep['scene_file']} "
            f"(view: python -m mujoco.viewer --mjcf {rep['scene_file']})"
        )
    if "video_file" in rep:
        text += (
            f"\nvideo written to {rep['video_file']} ({rep['video_frames']} frames, "
            f"{rep['video_backend']})"
        )
    return 0, text


if __name__ == "__main__":
    sys.exit(main())
