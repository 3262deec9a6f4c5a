"""Render a video of a preset's walk (MP4 or GIF), for every model family.

Command line::

    python -m jaxgait.render PRESET_OR_FILE [-o PATH.mp4|PATH.gif] [--model NAME]
        [--env ENV] [--env-seed N] [--duration S] [--v0 V]
        [--backend auto|mujoco|matplotlib] [--fps N] [--size WxH] [--start S] [--seconds S]
        [--json]

simulates the preset as ``python -m jaxgait.evaluate`` does and writes the video
(:mod:`jaxgait.analysis.video`: MuJoCo's offscreen renderer where EGL or OSMesa works, else a
matplotlib stick figure).  It prints where the video went and what the walk was; with
``--json`` one object with the keys ``video_file``, ``backend``, ``frames``, ``fps``,
``width``, ``height``, ``render_seconds``, ``preset``, ``model``, ``env``, ``distance_m``,
``duration_s``, ``mean_speed_mps`` and ``fell``.

Exit codes: 0 success, 2 bad input (preset, environment, duration, video settings or path).

Python API: :func:`render` (same arguments) returns that dict.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import re
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
from jaxgait.core.jsonio import json_safe
from jaxgait.evaluation import _check_inputs, _choose_model, _evaluate_taga, _load, run

#: Keys of the report of :func:`render` (and of ``--json``).
KEYS = (
    "video_file",
    "backend",
    "frames",
    "fps",
    "width",
    "height",
    "render_seconds",
    "preset",
    "model",
    "env",
    "distance_m",
    "duration_s",
    "mean_speed_mps",
    "fell",
)


def parse_size(text: str) -> tuple[int, int]:
    """``"640x360"`` -> (640, 360); ValueError naming the expected form otherwise."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", str(text))
    if not m:
        raise ValueError(f"--size {text!r}: expected WIDTHxHEIGHT in pixels, e.g. 640x360")
    return int(m.group(1)), int(m.group(2))


def render(
    preset,
    out,
    *,
    env: str = "flat",
    duration: float = 10.0,
    seed: int = 0,
    model: str | None = None,
    v0: float | None = None,
    backend: str = "auto",
    fps: float = 30.0,
    size: tuple[int, int] = (640, 360),
    start: float | None = None,
    seconds: float | None = None,
) -> dict:
    """Simulate ``preset`` (as :func:`jaxgait.evaluation.evaluate`) and write its video to
    ``out``; returns the report (:data:`KEYS`).  Raises ValueError subclasses on bad input."""
    _check_inputs(env, duration, seed)
    path = check_video_path(out)
    check_fps(fps)
    name = choose_backend(backend)
    declared, _, doc, label, file = _load(preset)
    mname = _choose_model(model, declared, label)
    if mname in models.model_names("taga"):
        rep, log, terrain = _evaluate_taga(doc, label, file, env, duration, seed, True)
        motion = motion_from_taga(log, terrain, title=label)
    else:
        result = run(preset, env=env, duration=duration, seed=seed, model=mname, v0=v0)
        rep = result.report
        mass = float(np.asarray(result.summary.mass))
        motion = motion_from_trace(result.trace, result.env, title=label, mass=mass)
    info = write_video(
        path,
        motion,
        backend=name,
        fps=fps,
        width=size[0],
        height=size[1],
        start=start,
        seconds=seconds,
    )
    out_rep = {
        "video_file": str(info.path),
        "backend": info.backend,
        "frames": info.frames,
        "fps": info.fps,
        "width": info.size[0],
        "height": info.size[1],
        "render_seconds": round(info.render_seconds, 3),
        "preset": label,
        "model": mname,
        "env": env,
    }
    for k in ("distance_m", "duration_s", "mean_speed_mps", "fell"):
        out_rep[k] = rep.get(k)
    return json_safe(out_rep)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m jaxgait.render",
        description="Simulate a preset and write a video of its walk (MP4 or GIF).",
    )
    p.add_argument("preset", help="preset name, preset JSON file, or results folder (best.json)")
    p.add_argument(
        "-o", "--out", type=Path, default=None, help="video file .mp4 or .gif (default NAME.mp4)"
    )
    p.add_argument("--model", choices=models.model_names(), default=None)
    p.add_argument("--env", default="flat", help="environment (default flat)")
    p.add_argument("--env-seed", type=int, default=0, help="environment PRNG seed (default 0)")
    p.add_argument("--duration", type=float, default=10.0, help="simulated time [s] (10)")
    p.add_argument("--v0", type=float, default=None, help="initial speed [m/s] (preset's)")
    p.add_argument("--backend", choices=("auto", *BACKENDS), default="auto")
    p.add_argument("--fps", type=float, default=30.0, help="frames per second (30)")
    p.add_argument("--size", default="640x360", help="frame size WIDTHxHEIGHT (640x360)")
    p.add_argument("--start", type=float, default=None, help="first time shown [s]")
    p.add_argument("--seconds", type=float, default=None, help="longest time shown [s]")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    return p


def format_report(rep: dict) -> str:
    """Two readable lines: the video and the walk it shows."""
    walk = (
        f"{rep['preset']} ({rep['model']}, {rep['env']}): walks {rep['duration_s']:.2f} s, "
        f"{rep['distance_m']:.2f} m at {rep['mean_speed_mps']:.2f} m/s"
        + (", then falls" if rep["fell"] else ", no fall")
    )
    video = (
        f"video written to {rep['video_file']}: {rep['frames']} frames at {rep['fps']:g} fps, "
        f"{rep['width']} x {rep['height']}, {rep['backend']} backend, "
        f"rendered in {rep['render_seconds']:.1f} s"
    )
    return walk + "\n" + video


def main(argv=None) -> int:
    """Command-line entry point; 0 on success, 2 on bad input."""
    try:
        a = _parser().parse_args(argv)
    except SystemExit as e:
        return int(e.code) if isinstance(e.code, int) else 2
    out = sys.stdout
    with contextlib.redirect_stdout(sys.stderr):
        from jaxgait.core import compile_cache

        compile_cache.enable()
        try:
            size = parse_size(a.size)
            path = a.out if a.out is not None else Path(f"{Path(str(a.preset)).stem}.mp4")
            rep = render(
                a.preset,
                path,
                env=a.env,
                duration=a.duration,
                seed=a.env_seed,
                model=a.model,
                v0=a.v0,
                backend=a.backend,
                fps=a.fps,
                size=size,
                start=a.start,
                seconds=a.seconds,
            )
        except ValueError as e:
            print(f"jaxgait.render: error: {e}", file=sys.stderr)
            return 2
        except OSError as e:
            print(f"jaxgait.render: error: cannot write the video: {e}", file=sys.stderr)
            return 2
    text = json.dumps(rep, allow_nan=False) if a.json else format_report(rep)
    print(text, file=out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
