"""Walk-run: the control vector driven from walking towards running and back in one rollout
(thesis 7.3.2 and 9).

The thesis saw the double stance of 3FBL go to zero at high A_INBAS / A_INCPG and guessed
that FBL+'s phase rules (thesis 2.1.3) would let the network run.  :func:`run_walkrun` tries
it on any network preset (3FBL built from an FBL+ gait, ``spinal build`` on an FBL+ preset):
one rollout walks ``walk_s`` seconds at the walking values of the driven commands, ramps them
linearly to their running values over ``ramp_s``, holds them ``hold_s``, ramps back over
``back_s`` and walks ``end_s`` more.  The gait is measured in consecutive windows of
``window_s`` seconds (:func:`window_gait`): mean speed [m/s], the fractions of time in double
stance and in flight (neither leg in stance) [-], the right leg's cycle frequency [Hz], and
the commands at the window's end.  A fall blanks the windows after it.  The same ramps on
another environment are the thesis's manual control (7.3.1): e.g. ``--env increasing_slope``
with a ramp up and a hold raises a command as the grade rises.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax
import numpy as np

from jaxgait import models, sim
from jaxgait.control.commands import schedule
from jaxgait.presets import load_preset
from jaxgait.spinal.record import SpinalError
from jaxgait.world import envs

#: the phases of a walk-run rollout, in order
PHASES = ("walk", "ramp up", "hold", "ramp down", "walk again")


@dataclass(frozen=True)
class WalkRun:
    """Commands driven (name -> (walking value, running value)) and the phase durations [s]."""

    drive: dict = field(default_factory=lambda: {"A_INBAS": (1.0, 1.6), "A_INCPG": (1.0, 1.6)})
    walk_s: float = 10.0
    ramp_s: float = 20.0
    hold_s: float = 10.0
    back_s: float = 20.0
    end_s: float = 10.0
    window_s: float = 2.0

    def __post_init__(self):
        if not self.drive:
            raise SpinalError("a walk-run drives at least one command")
        for name, pair in self.drive.items():
            if len(pair) != 2 or not all(np.isfinite(v) for v in pair):
                raise SpinalError(f"{name}: need (walking value, running value), got {pair!r}")
        durs = (self.walk_s, self.ramp_s, self.hold_s, self.back_s, self.end_s)
        if min(durs) < 0 or self.window_s <= 0:
            raise SpinalError(f"phase durations must be >= 0 and the window > 0, got {durs}")

    @property
    def duration(self) -> float:
        return self.walk_s + self.ramp_s + self.hold_s + self.back_s + self.end_s

    def knots(self) -> list[tuple[float, dict]]:
        """The schedule's knots (linear interpolation between them)."""
        lo = {k: float(v[0]) for k, v in self.drive.items()}
        hi = {k: float(v[1]) for k, v in self.drive.items()}
        t1 = self.walk_s
        t2 = t1 + self.ramp_s
        t3 = t2 + self.hold_s
        t4 = t3 + self.back_s
        return [(0.0, lo), (t1, lo), (t2, hi), (t3, hi), (t4, lo), (self.duration, lo)]

    def phase_of(self, t: float) -> str:
        """The phase a time [s] falls in."""
        edges = np.cumsum([self.walk_s, self.ramp_s, self.hold_s, self.back_s])
        return PHASES[int(np.searchsorted(edges, t, side="left"))]


def walkrun_schedule(commands, wr: WalkRun):
    """The linear schedule of a walk-run (:class:`CommandError` for unknown commands)."""
    names = {c.name for c in commands}
    bad = sorted(set(wr.drive) - names)
    if bad:
        raise SpinalError(f"commands {bad} are not this model's: {sorted(names)}")
    return schedule(commands, wr.knots(), interp="linear")


def window_gait(
    t, com_x, stance, td_t, window_s: float, fell_at: float = np.inf, duration=None
) -> dict:
    """Per window [k window_s, (k+1) window_s] up to ``duration`` [s] (default the last
    time): speed [m/s], double-stance and flight fractions [-] and the cycle frequency [Hz]
    from the right touchdowns ``td_t`` [s]; NaN for windows that end after ``fell_at`` [s].
    t (T,), com_x (T,), stance (T, 2) bool."""
    t, com_x, stance = np.asarray(t, float), np.asarray(com_x, float), np.asarray(stance, bool)
    end = (t[-1] if t.size else 0.0) if duration is None else float(duration)
    n = int(np.floor(end / window_s + 1e-9))
    keys = ("speed_mps", "double_stance_fraction", "flight_fraction", "cycle_frequency_hz")
    out = {k: np.full(n, np.nan) for k in keys}
    out["t_end_s"] = (np.arange(n) + 1) * window_s
    for j in range(n):
        a, b = j * window_s, (j + 1) * window_s
        rows = (t > a + 1e-9) & (t <= b + 1e-9)
        if rows.sum() < 2 or fell_at <= b + 1e-9:
            continue
        i0, i1 = np.flatnonzero(rows)[[0, -1]]
        out["speed_mps"][j] = (com_x[i1] - com_x[i0]) / (t[i1] - t[i0])
        out["double_stance_fraction"][j] = float(np.mean(stance[rows, 0] & stance[rows, 1]))
        out["flight_fraction"][j] = float(np.mean(~stance[rows, 0] & ~stance[rows, 1]))
        td = np.asarray(td_t, float)
        td = td[(td > a) & (td <= b)]
        if td.size >= 2:
            out["cycle_frequency_hz"][j] = 1.0 / float(np.mean(np.diff(td)))
    return out


def run_walkrun(preset, wr: WalkRun, env: str = "flat", seed: int = 0) -> dict:
    """One walk-run rollout of ``preset`` (a model whose commands include ``wr.drive``)."""
    name, vec, doc = load_preset(preset)
    model = models.get_model(name)
    sched = walkrun_schedule(model.controller.commands, wr)
    cfg = sim.SimConfig(
        duration=wr.duration,
        v0=float(doc.get("v0", sim.SimConfig.v0)),
        pose=doc.get("pose", sim.SimConfig.pose),
        max_events=max(512, int(6 * wr.duration)),
    )
    e = envs.make_env(env, jax.random.PRNGKey(int(seed)))
    f = sim.make_rollout(model, cfg, batched=False)
    trace, events, summary, _ = f(model.table.as_jnp(vec), e, sched)
    trace, events = jax.tree.map(np.asarray, trace), jax.tree.map(np.asarray, events)
    fell = bool(np.asarray(summary.fell))
    fell_at = float(np.asarray(summary.duration)) if fell else np.inf
    n_ev = min(int(events.n), events.t.shape[0])
    td = events.t[:n_ev][events.leg[:n_ev] == 0]
    win = window_gait(trace.t, trace.com[:, 0], trace.stance, td, wr.window_s, fell_at, wr.duration)
    knots = wr.knots()
    tk = [t for t, _ in knots]
    cmd = {c: np.interp(win["t_end_s"], tk, [v[c] for _, v in knots]).tolist() for c in wr.drive}
    return {
        "preset": str(preset),
        "model": name,
        "env": env,
        "seed": int(seed),
        "drive": {k: list(v) for k, v in wr.drive.items()},
        "phases_s": {
            "walk": wr.walk_s,
            "ramp up": wr.ramp_s,
            "hold": wr.hold_s,
            "ramp down": wr.back_s,
            "walk again": wr.end_s,
        },
        "window_s": wr.window_s,
        "distance_m": float(trace.com[-1, 0] - trace.com[0, 0]),
        "fell": fell,
        "fell_at_s": fell_at if fell else None,
        "fell_in": wr.phase_of(fell_at) if fell else None,
        "windows": {
            **{k: v.tolist() for k, v in win.items()},
            "phase": [wr.phase_of(t - 1e-9) for t in win["t_end_s"]],
            "commands": cmd,
        },
    }
