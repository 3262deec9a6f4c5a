"""Gait measures of a Taga rollout: speed, stride length/duration, double support, flight.

Definitions (Taga et al. 1991, Fig. 11 caption and section 4.2):

* stride length: distance between successive contact points of the same leg [m]
  (the touchdown rest points x_r0 / x_l0 of Appendix A);
* stride (cycle) duration: time between successive touchdowns of the same leg [s];
* speed: hip displacement over the window divided by its duration [m/s] (the paper's
  "stride length divided by stride cycle duration" is also returned as
  ``stride_speed_mps``);
* double-support fraction: share of the time with both ankles in ground contact;
* flight fraction: share of the time with neither ankle in contact (running).

These run on host NumPy arrays after a rollout (events are sparse and irregular).
"""

from __future__ import annotations

import numpy as np

# a same-leg touchdown closer than this to the previous one is a bounce, not a new step [s]
MIN_STRIDE_S = 0.15


def touchdowns(events, min_interval: float = MIN_STRIDE_S) -> dict:
    """Host arrays of touchdown events, bounces of the same leg merged.

    Args:
      events: :class:`jaxgait.taga.sim.Events` (one rollout, unbatched).
    Returns:
      dict t, leg, x (each (n,)) in time order.
    """
    n = int(min(int(events.n), events.t.shape[0]))
    t = np.asarray(events.t[:n], float)
    leg = np.asarray(events.leg[:n], int)
    x = np.asarray(events.x[:n], float)
    keep = np.ones(n, bool)
    last = {0: -np.inf, 1: -np.inf}
    for i in range(n):
        if t[i] - last[leg[i]] < min_interval:
            keep[i] = False
        else:
            last[leg[i]] = t[i]
    return dict(t=t[keep], leg=leg[keep], x=x[keep])


def strides(td: dict, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """Stride durations and lengths (k,) of both legs whose two touchdowns lie in [t0, t1]."""
    dur, length = [], []
    for leg in (0, 1):
        m = (td["leg"] == leg) & (td["t"] >= t0) & (td["t"] <= t1)
        dur.append(np.diff(td["t"][m]))
        length.append(np.diff(td["x"][m]))
    return np.concatenate(dur), np.concatenate(length)


def window_measures(log, events, t0: float, t1: float) -> dict:
    """Measures over the time window [t0, t1] of one rollout (alive part only).

    Args:
      log: :class:`jaxgait.taga.sim.Log` (unbatched); events: its final ``Events``.
    Returns:
      JSON-able dict (floats; NaN where undefined).
    """
    t = np.asarray(log.t, float)
    alive = np.asarray(log.alive, bool)
    m = (t >= t0) & (t <= t1) & alive
    out = dict(
        speed_mps=np.nan,
        stride_length_m=np.nan,
        stride_duration_s=np.nan,
        stride_speed_mps=np.nan,
        double_support_fraction=np.nan,
        flight_fraction=np.nan,
        n_strides=0,
        stride_length_sd_m=np.nan,
        stride_duration_sd_s=np.nan,
    )
    if m.sum() >= 2:
        x = np.asarray(log.qpos[:, 0], float)[m]
        tt = t[m]
        out["speed_mps"] = float((x[-1] - x[0]) / (tt[-1] - tt[0]))
        out["double_support_fraction"] = float(np.asarray(log.double, float)[m].mean())
        out["flight_fraction"] = float(np.asarray(log.flight, float)[m].mean())
        td = touchdowns(events)
        dur, length = strides(td, t0, min(t1, tt[-1]))
        if len(dur):
            out["n_strides"] = int(len(dur))
            out["stride_duration_s"] = float(dur.mean())
            out["stride_length_m"] = float(length.mean())
            out["stride_duration_sd_s"] = float(dur.std())
            out["stride_length_sd_m"] = float(length.std())
            out["stride_speed_mps"] = float(length.mean() / dur.mean())
    return out


def gait_measures(log, events, final_state, settle: float | None = None) -> dict:
    """Summary of a whole rollout: steady-state measures plus fall / distance / duration.

    The steady-state window is [settle, end] with ``end`` the fall time (or the end of
    the rollout); by default ``settle`` is half of ``end``.

    Returns:
      dict with speed_mps, stride_length_m, stride_duration_s, double_support_fraction,
      flight_fraction, fell, distance_m, duration_s (and a few extras), JSON-able.
    """
    t = np.asarray(log.t, float)
    fell = bool(final_state.fell)
    end = float(final_state.t_end) if fell else float(t[-1])
    t0 = end / 2 if settle is None else min(settle, end)
    out = window_measures(log, events, t0, end)
    alive = np.asarray(log.alive, bool)
    x = np.asarray(log.qpos[:, 0], float)
    last = int(np.nonzero(alive)[0][-1]) if alive.any() else 0
    out.update(
        fell=fell,
        distance_m=float(x[last] - x[0]) if alive.any() else 0.0,
        duration_s=end,
        window_s=[float(t0), float(end)],
    )
    return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in out.items()}


def dominant_period(signal, dt: float) -> float:
    """Mean period [s] of a roughly periodic signal from its upward mean crossings."""
    s = np.asarray(signal, float)
    s = s - s.mean()
    up = np.nonzero((s[:-1] < 0) & (s[1:] >= 0))[0]
    if len(up) < 3:
        return float("nan")
    # linear interpolation of the crossing instants
    tc = (up + (-s[up]) / (s[up + 1] - s[up])) * dt
    return float(np.diff(tc).mean())
