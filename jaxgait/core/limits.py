"""The largest durations and distances a rollout can simulate, and the checks that say so.

Both simulators keep time on the step grid in float32: the planar step computes
``t = (round(t / dt) + 1) dt`` and Taga's ``t = n_steps dt``, which are exact while the step
count is below 2**24 (float32 has a 24-bit significand; above it consecutive counts are no
longer representable and the clock stops advancing by one step).  At the models' 0.5 ms
step that is 8388.6 s, a little over 2 h 19 min of simulated time; the trace of such a
rollout (one row every 10 ms) already holds 840,000 rows.

Positions are float32 as well: at 65.5 km their spacing is 7.8 mm, coarser than the contact
model's resolution, and no rollout of the longest duration covers 100 km below 12 m/s.  A
distance limit above :data:`MAX_DISTANCE_M` is therefore refused; ``inf`` means "no limit".
"""

from __future__ import annotations

import math

#: The models' physics step [s] (``models/*.xml`` timestep).
DEFAULT_DT = 5e-4
#: Step counts below this are exact on the float32 clock.
MAX_STEPS = 2**24
#: Largest finite distance limit [m].
MAX_DISTANCE_M = 1e5


class LimitError(ValueError):
    """A duration or distance outside what the simulation can represent."""


def max_duration(dt: float = DEFAULT_DT) -> float:
    """Longest simulated time [s] at physics step ``dt``: 2**24 steps."""
    return (MAX_STEPS - 1) * float(dt)


def check_duration(duration, dt: float = DEFAULT_DT, what: str = "duration") -> float:
    """``duration`` as a float if it is a positive number the clock can reach, else
    :class:`LimitError` naming ``what``, the value and the limit."""
    if isinstance(duration, bool) or not isinstance(duration, (int, float)):
        raise LimitError(f"{what} must be a number of seconds, got {duration!r}")
    d = float(duration)
    if not (math.isfinite(d) and d > 0):
        raise LimitError(f"{what} must be a positive, finite number of seconds, got {duration!r}")
    top = max_duration(dt)
    if d > top:
        raise LimitError(
            f"{what} {d:g} s is too long to simulate: the float32 simulation clock counts at "
            f"most 2**24 steps of {dt * 1e3:g} ms, i.e. {top:.1f} s; use a shorter duration"
        )
    return d


def check_distance(distance, what: str = "d_lim") -> float:
    """``distance`` as a float if it is positive and at most :data:`MAX_DISTANCE_M` or inf
    (no limit), else :class:`LimitError` naming ``what``."""
    if isinstance(distance, bool) or not isinstance(distance, (int, float)):
        raise LimitError(f"{what} must be a number of metres (inf for none), got {distance!r}")
    d = float(distance)
    if math.isnan(d) or d <= 0:
        raise LimitError(f"{what} must be > 0 metres (inf for none), got {distance!r}")
    if math.isfinite(d) and d > MAX_DISTANCE_M:
        raise LimitError(
            f"{what} {d:g} m is too far to simulate: float32 positions are coarser than "
            f"the contact model beyond {MAX_DISTANCE_M:g} m and no rollout of the longest "
            f"duration ({max_duration():.0f} s) walks that far; use at most "
            f"{MAX_DISTANCE_M:g} m, or inf for no distance limit"
        )
    return d
