"""Videos of a walk (MP4 or GIF), for every model family.

A :class:`Motion` is what a video shows: times, the ``qpos`` rows of an MJCF body model
(``models/fbl_planar.xml`` for the planar models, ``models/taga1991.xml`` for Taga), the
ground reaction force of each leg and the terrain.  :func:`motion_from_trace` and
:func:`motion_from_taga` build one from a rollout; :func:`write_video` renders it at ``fps``
frames per second of simulated time (real-time playback) with one of two backends:

* ``"mujoco"``: MuJoCo's offscreen renderer on the scene of :mod:`jaxgait.world.scene` (the
  body on its terrain as a height field), GRF arrows as scene geoms, the time stamp as an
  overlay, the scene's ``follow`` camera tracking the walker.  It needs an OpenGL backend
  without a display: EGL (Debian packages ``libegl1`` and ``libgl1-mesa-dri``; a GPU driver's
  EGL also works) or OSMesa (``libosmesa6``), chosen with ``MUJOCO_GL=egl|osmesa`` (default:
  EGL, then OSMesa);
* ``"matplotlib"``: a stick figure of the body's geoms (right leg red, left leg blue) on the
  terrain profile, GRF arrows at the feet, the time stamp, distance and speed, with a
  camera that follows the hip.  It needs nothing beyond the Python dependencies.

``backend="auto"`` uses MuJoCo when an OpenGL context can be created and matplotlib
otherwise.  Frames are encoded by imageio: MP4 (H.264) through imageio-ffmpeg's ffmpeg, GIF
through Pillow.
"""

from __future__ import annotations

import math
import time
import warnings
from pathlib import Path

import numpy as np

from jaxgait.analysis.video_motion import (
    Motion,
    VideoError,
    VideoInfo,
    caption,
    motion_from_taga,
    motion_from_trace,
)

#: Rendering backends, in the order ``"auto"`` tries them.
BACKENDS = ("mujoco", "matplotlib")
#: File types written.
FORMATS = (".mp4", ".gif")

__all__ = [
    "BACKENDS",
    "FORMATS",
    "Motion",
    "VideoError",
    "VideoInfo",
    "caption",
    "check_fps",
    "check_video_path",
    "choose_backend",
    "frame_rows",
    "motion_from_taga",
    "motion_from_trace",
    "mujoco_available",
    "write_video",
]


def check_fps(fps) -> float:
    """``fps`` as a float if it is a number in (0, 240], else :class:`VideoError`."""
    ok = isinstance(fps, (int, float)) and not isinstance(fps, bool)
    if not (ok and math.isfinite(fps) and 0 < fps <= 240):
        raise VideoError(f"video fps must be a number in (0, 240], got {fps!r}")
    return float(fps)


def frame_rows(motion: Motion, fps: float, start: float | None = None, seconds=None):
    """``(times (N,), rows (N,))`` of the frames: N = round(shown time x fps) (at least 1)
    frames at t0 + k / fps, each showing the sample nearest to its time.

    ``start``: first time shown [s] (default the first sample); ``seconds``: longest time
    shown (default to the last sample).
    """
    check_fps(fps)
    t = motion.t
    t0 = float(t[0]) if start is None else float(start)
    if not t[0] - 1e-9 <= t0 <= t[-1] + 1e-9:
        raise VideoError(f"start {t0:g} s is outside the motion's [{t[0]:g}, {t[-1]:g}] s")
    t1 = float(t[-1]) if seconds is None else min(float(t[-1]), t0 + float(seconds))
    if seconds is not None and not (math.isfinite(float(seconds)) and float(seconds) > 0):
        raise VideoError(f"seconds must be a positive number, got {seconds!r}")
    n = max(1, int(round((t1 - t0) * fps)))
    times = t0 + np.arange(n) / float(fps)
    rows = np.clip(np.searchsorted(t, times), 0, t.size - 1)
    prev = np.clip(rows - 1, 0, t.size - 1)
    rows = np.where(np.abs(t[prev] - times) <= np.abs(t[rows] - times), prev, rows)
    return times, rows


def mujoco_available() -> tuple[bool, str]:
    """Whether MuJoCo can render offscreen here, and which GL backend (or why not)."""
    from jaxgait.analysis.video_gl import gl_context

    try:
        name, ctx = gl_context(16, 16)
    except VideoError as e:
        return False, str(e)
    ctx.free()
    return True, name


def choose_backend(backend: str = "auto") -> str:
    """``backend`` itself (checked), or for ``"auto"`` the first available of BACKENDS."""
    if backend not in ("auto", *BACKENDS):
        raise VideoError(f"unknown video backend {backend!r}; choose auto, {', '.join(BACKENDS)}")
    if backend == "auto":
        return "mujoco" if mujoco_available()[0] else "matplotlib"
    if backend == "mujoco":
        ok, why = mujoco_available()
        if not ok:
            raise VideoError(f"the mujoco video backend is not available here: {why}")
    return backend


def check_video_path(path) -> Path:
    """``path`` as a Path if it ends in .mp4 or .gif and its folder exists and is writable."""
    import os

    p = Path(path)
    if p.suffix.lower() not in FORMATS:
        raise VideoError(f"video {p}: the file must end in {' or '.join(FORMATS)}")
    parent = p.expanduser().resolve().parent
    if p.is_dir():
        raise VideoError(f"video {p}: is a folder, need a file path")
    if not parent.is_dir():
        raise VideoError(f"video {p}: folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise VideoError(f"video {p}: folder {parent} is not writable")
    return p


class _Writer:
    """Frames to an MP4 (streamed through ffmpeg) or a GIF (Pillow, written at the end)."""

    def __init__(self, path: Path, fps: float):
        self.path, self.fps, self.n = path, float(fps), 0
        self.gif = path.suffix.lower() == ".gif"
        self.frames: list[np.ndarray] = []
        self._w = None
        if not self.gif:
            import imageio.v2 as iio

            # ffmpeg is started by fork + exec; JAX warns about any fork of its threaded
            # process, but the child only execs ffmpeg, so the warning does not apply
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", "os.fork", RuntimeWarning)
                self._w = self._open(iio)

    def _open(self, iio):
        return iio.get_writer(
            self.path,
            format="FFMPEG",
            mode="I",
            fps=self.fps,
            codec="libx264",
            pixelformat="yuv420p",
            macro_block_size=2,
            ffmpeg_log_level="error",
        )

    def add(self, frame: np.ndarray) -> None:
        self.n += 1
        if self.gif:
            self.frames.append(frame)
        else:
            with warnings.catch_warnings():  # the first frame starts ffmpeg
                warnings.filterwarnings("ignore", "os.fork", RuntimeWarning)
                self._w.append_data(frame)

    def close(self) -> None:
        if self.gif:
            import imageio.v3 as iio

            iio.imwrite(
                self.path, np.stack(self.frames), extension=".gif", duration=1000 / self.fps, loop=0
            )
        elif self._w is not None:
            self._w.close()


def write_video(
    path,
    motion: Motion,
    *,
    backend: str = "auto",
    fps: float = 30.0,
    width: int = 640,
    height: int = 360,
    start: float | None = None,
    seconds: float | None = None,
) -> VideoInfo:
    """Render ``motion`` into ``path`` (.mp4 or .gif) and return what was written.

    Args:
      path: output file; its suffix chooses the format.
      motion: the :class:`Motion`.
      backend: ``"auto"``, ``"mujoco"`` or ``"matplotlib"`` (see the module docstring).
      fps: frames per second of simulated time (playback is real time).
      width, height: frame size in pixels (rounded down to even numbers for H.264).
      start, seconds: the part shown (:func:`frame_rows`).

    Raises:
      VideoError: bad settings or path, or ``backend="mujoco"`` without an OpenGL backend.
    """
    path = check_video_path(path)
    w, h = int(width) // 2 * 2, int(height) // 2 * 2
    if not (32 <= w <= 4096 and 32 <= h <= 4096):
        raise VideoError(f"frame size must be within 32..4096 pixels, got {width} x {height}")
    times, rows = frame_rows(motion, fps, start, seconds)
    name = choose_backend(backend)
    t0 = time.perf_counter()
    if name == "mujoco":
        from jaxgait.analysis.video_gl import GLFrames as Frames
    else:
        from jaxgait.analysis.video_mpl import StickFrames as Frames
    writer = _Writer(path, fps)
    try:
        with Frames(motion, w, h) as frames:
            for ti, r in zip(times, rows, strict=True):
                writer.add(frames.render(int(r), float(ti)))
    finally:
        writer.close()
    secs = time.perf_counter() - t0
    return VideoInfo(path, name, writer.n, float(fps), secs, (w, h))
