"""What a video shows: a :class:`Motion` (times, the qpos rows of an MJCF body, ground
forces, terrain), built from a planar or a Taga rollout, and the caption of a frame.

Shared by :mod:`jaxgait.analysis.video` and its two backends
(:mod:`jaxgait.analysis.video_mpl`, :mod:`jaxgait.analysis.video_gl`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

G = 9.81


class VideoError(ValueError):
    """Bad video settings, or a backend that is not available here."""


@dataclass(frozen=True)
class Motion:
    """What a video shows (host NumPy arrays, alive samples only).

    Attributes:
      t: (T,) time [s], increasing.
      qpos: (T, nq) generalised positions of the MJCF ``model``; qpos[:, 0] is the root x.
      grf: (T, 2, 2) ground reaction force per leg (right, left) as (x, z) [N], or None.
      terrain: the :class:`~jaxgait.world.terrain.Terrain` walked on (None: flat z = 0).
      model: MJCF in the models folder (``fbl_planar``, ``taga1991``).
      weight: body weight [N] (scales the GRF arrows: 1 body weight is 0.5 m long).
      title: text in the top-left corner (e.g. the preset name).
    """

    t: np.ndarray
    qpos: np.ndarray
    grf: np.ndarray | None
    terrain: object | None
    model: str = "fbl_planar"
    weight: float = 80.0 * G
    title: str = ""

    def __post_init__(self):
        t, q = np.asarray(self.t, float), np.asarray(self.qpos, float)
        if t.ndim != 1 or q.ndim != 2 or q.shape[0] != t.shape[0] or t.size == 0:
            raise VideoError(f"a motion needs t (T,) and qpos (T, nq), got {t.shape}, {q.shape}")
        if self.grf is not None and np.shape(self.grf) != (t.size, 2, 2):
            raise VideoError(f"grf must be (T, 2, 2), got {np.shape(self.grf)}")

    @property
    def duration(self) -> float:
        """Time from the first to the last sample [s]."""
        return float(self.t[-1] - self.t[0])


@dataclass(frozen=True)
class VideoInfo:
    """What :func:`write_video` wrote: file, backend, frame count, fps, seconds of wall time."""

    path: Path
    backend: str
    frames: int
    fps: float
    render_seconds: float
    size: tuple[int, int]


def _np(x) -> np.ndarray:
    return np.asarray(x)


def motion_from_trace(trace, terrain=None, *, title: str = "", mass: float | None = None):
    """The :class:`Motion` of a planar rollout (a :class:`~jaxgait.sim.trace.Trace`).

    ``terrain``: the rollout's Terrain or Env; ``mass``: body mass [kg] (default 80 kg).
    """
    alive = _np(trace.alive).astype(bool).reshape(-1)
    if not alive.any():
        raise VideoError("the rollout has no alive samples to show")
    terrain = getattr(terrain, "terrain", terrain)
    weight = (80.0 if mass is None else float(mass)) * G
    return Motion(
        t=_np(trace.t)[alive].astype(float),
        qpos=_np(trace.qpos)[alive].astype(float),
        grf=_np(trace.grf)[alive].astype(float),
        terrain=terrain,
        model="fbl_planar",
        weight=weight,
        title=title,
    )


def motion_from_taga(log, terrain=None, *, title: str = "", mass: float = 70.0):
    """The :class:`Motion` of a Taga rollout (:class:`jaxgait.taga.sim.Log`); Taga's body
    is 70 kg (48 kg hip, 2 x 7 kg thighs, 2 x 4 kg shanks)."""
    alive = _np(log.alive).astype(bool).reshape(-1)
    if not alive.any():
        raise VideoError("the rollout has no alive samples to show")
    return Motion(
        t=_np(log.t)[alive].astype(float),
        qpos=_np(log.qpos)[alive].astype(float),
        grf=_np(log.grf)[alive].astype(float),
        terrain=terrain,
        model="taga1991",
        weight=float(mass) * 9.8,
        title=title,
    )


def caption(motion: Motion, row: int, t: float) -> tuple[str, str]:
    """(left, right) text of a frame: the title; time, distance and speed so far."""
    x = motion.qpos[:, 0]
    d = float(x[row] - x[0])
    dt = float(motion.t[row] - motion.t[0])
    v = f"{d / dt:.2f} m/s" if dt > 0.2 else "-"
    return motion.title, f"t = {t:5.2f} s  x = {d:5.2f} m  mean v = {v}"
