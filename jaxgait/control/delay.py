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
    """Ring buffer (n + 1, ...) and write index; n, the longest delay in steps, is static via
    the shape (:attr:`n_steps`)."""

    buf: jax.Array
    idx: jax.Array

    @property
    def n_steps(self) -> int:
        return self.buf.shape[0] - 1


def delay_init(n_steps: int, value: jax.Array) -> DelayLine:
    """Delay of ``n_steps`` (>= 1) steps, filled with ``value``."""
    if n_steps < 1:
        raise ValueError(f"delay must be at least one step, got {n_steps}")
    shape = (n_steps + 1,) + jnp.shape(value)
    buf = jnp.broadcast_to(value, shape).astype(jnp.result_type(value))
    return DelayLine(buf=buf, idx=jnp.zeros((), jnp.int32))


def delay_step(line: DelayLine, x: jax.Array) -> tuple[jax.Array, DelayLine]:
    """Push ``x`` and return the value pushed ``n`` steps ago (n = the line's delay)."""
    out, line = delay_taps(line, x, (line.n_steps,))
    return out[0], line


def delay_taps(line: DelayLine, x: jax.Array, taps: tuple[int, ...]) -> tuple[jax.Array, DelayLine]:
    """Push ``x`` and return the values pushed ``n`` steps ago for each n in ``taps``.

    One ring buffer serves several delays (one write, one read per tap); ``taps`` are static
    whole numbers of steps in [1, n].  Returns (stacked (len(taps), ...), new line).

    The buffer has one slot more than the longest delay, so ``x`` is written first and the
    taps are read from the updated buffer: no slot is read and written in the same step, and
    XLA updates the buffer in place (reading before writing made it copy the whole buffer,
    twice, every step).
    """
    m = line.buf.shape[0]
    if not all(1 <= k <= m - 1 for k in taps):
        raise ValueError(f"taps {taps} must lie in [1, {m - 1}] steps (the line's delay)")
    buf = line.buf.at[line.idx].set(x)
    out = buf[jnp.stack([(line.idx - k) % m for k in taps])]
    return out, DelayLine(buf=buf, idx=(line.idx + 1) % m)


def steps_for(delay_s: float, dt: float) -> int:
    """Number of steps of a delay, requiring it to be a whole number of steps."""
    n = round(delay_s / dt)
    if n < 1 or abs(n * dt - delay_s) > 1e-9 + 1e-6 * delay_s:
        raise ValueError(f"delay {delay_s} s is not a whole number (>=1) of steps of {dt} s")
    return int(n)
