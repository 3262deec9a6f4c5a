"""Pure neural transmission delays: ring buffers held in the simulation state.

A delay of ``n`` steps returns at step k exactly the value pushed at step k - n
(n * dt seconds earlier).  Until n values have been pushed it returns the initial fill.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class DelayLine:
    """Ring buffer (n, ...) and write index (n is the delay in steps, static via shape)."""

    buf: jax.Array
    idx: jax.Array


def delay_init(n_steps: int, value: jax.Array) -> DelayLine:
    """Delay of ``n_steps`` (>= 1) steps, filled with ``value``."""
    if n_steps < 1:
        raise ValueError(f"delay must be at least one step, got {n_steps}")
    buf = jnp.broadcast_to(value, (n_steps,) + jnp.shape(value)).astype(jnp.result_type(value))
    return DelayLine(buf=buf, idx=jnp.zeros((), jnp.int32))


def delay_step(line: DelayLine, x: jax.Array) -> tuple[jax.Array, DelayLine]:
    """Push ``x`` and return the value pushed ``n`` steps ago (n = the line's length)."""
    out, line = delay_taps(line, x, (line.buf.shape[0],))
    return out[0], line


def delay_taps(line: DelayLine, x: jax.Array, taps: tuple[int, ...]) -> tuple[jax.Array, DelayLine]:
    """Push ``x`` and return the values pushed ``n`` steps ago for each n in ``taps``.

    One ring buffer of length max(taps) serves several delays (one write, one read per tap);
    ``taps`` are static whole numbers of steps in [1, n].  Returns (stacked (len(taps), ...),
    new line).
    """
    n = line.buf.shape[0]
    if not all(1 <= k <= n for k in taps):
        raise ValueError(f"taps {taps} must lie in [1, {n}] steps (the line's length)")
    idx = jnp.stack([(line.idx - k) % n for k in taps])
    out = line.buf[idx]
    buf = line.buf.at[line.idx].set(x)
    return out, DelayLine(buf=buf, idx=(line.idx + 1) % n)


def steps_for(delay_s: float, dt: float) -> int:
    """Number of steps of a delay, requiring it to be a whole number of steps."""
    n = round(delay_s / dt)
    if n < 1 or abs(n * dt - delay_s) > 1e-9 + 1e-6 * delay_s:
        raise ValueError(f"delay {delay_s} s is not a whole number (>=1) of steps of {dt} s")
    return int(n)
