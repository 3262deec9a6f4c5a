"""Feedforward pattern generation: periodic splines, the arbitrary-wave oscillator and the
central clock (thesis 6.3, eq. 6.4-6.9).

* :class:`PeriodicSpline`: a 1-periodic cubic spline (thesis 6.4.3: 100 regularly spaced
  knots per cycle) as a coefficient table, evaluated with its derivative inside ``jit``.
  Built on the host by :func:`periodic_spline` (scipy's ``CubicSpline``, periodic ends).
* :func:`awo_step`: the arbitrary-wave oscillator (eq. 6.5, K = 0)
  ``x' = gamma (g(theta) - x) + g'(theta) theta'``: x converges to g(theta) at rate gamma and
  then follows it exactly, whatever theta' does.
* :func:`clock_step`: one central clock per side (eq. 6.6-6.9).  theta' = omega [cycles/s]
  up to phase p (0.9); past p the clock slows as theta' = omega (1 - theta) / (1 - p), so
  theta -> 1 asymptotically and theta(t) is C^1 at p.  This is the law whose solution the
  thesis writes as c(t) = 1 - exp(-beta t + gamma) with beta = omega / (1 - p) (eq. 6.8, its
  derivation garbled; the intent, C^1 at p and never past 1, is what is implemented).  The
  clock restarts (theta = 0) at the ipsilateral touchdown: a late clock jumps from below 1,
  an early one waits near 1.  The step integrates the law exactly over dt (linear part, then
  the exponential approach), so theta < 1 for any omega and time step.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

#: Knots per cycle of the nominal patterns (thesis 6.4.3).
N_KNOTS = 100
#: AWO convergence rate gamma [1/s] (thesis 6.3.1).
AWO_GAMMA = 100.0
#: Phase past which the central clock slows down (thesis 6.3.2: p = 0.9).
CLOCK_SLOW_PHASE = 0.9
#: Smallest clock frequency the step uses [cycles/s] (a zero or negative omega would stop
#: or reverse the clock; the command is clipped to this).
OMEGA_MIN = 1e-3


@struct.dataclass
class PeriodicSpline:
    """A batch of 1-periodic cubic splines on ``n`` regular knots.

    Attributes:
      coef: (..., n, 4) polynomial coefficients per interval, highest power first: on
        [i/n, (i+1)/n), g(theta) = sum_k coef[..., i, k] (theta - i/n)^(3-k).
    """

    coef: jax.Array

    def __call__(self, theta: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(g(theta), dg/dtheta) for phases ``theta`` broadcast against the batch (taken
        modulo 1)."""
        return spline_eval(self.coef, theta)


def spline_eval(coef: jax.Array, theta: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Value and derivative of the periodic splines ``coef`` (..., n, 4) at ``theta`` (...)."""
    n = coef.shape[-2]
    theta = jnp.asarray(theta)
    batch = jnp.broadcast_shapes(coef.shape[:-2], theta.shape)
    coef = jnp.broadcast_to(coef, batch + coef.shape[-2:])
    u = jnp.broadcast_to(jnp.mod(theta, 1.0), batch)
    i = jnp.clip(jnp.floor(u * n).astype(jnp.int32), 0, n - 1)
    dx = u - i.astype(u.dtype) / n
    c = jnp.take_along_axis(coef, i[..., None, None], axis=-2)[..., 0, :]
    g = ((c[..., 0] * dx + c[..., 1]) * dx + c[..., 2]) * dx + c[..., 3]
    dg = (3.0 * c[..., 0] * dx + 2.0 * c[..., 1]) * dx + c[..., 2]
    return g, dg


def periodic_spline(values, n_knots: int = N_KNOTS) -> np.ndarray:
    """Coefficients (..., n_knots, 4) of the periodic cubic splines through ``values``.

    Args:
      values: (..., N) samples of one cycle at phases j/N, j = 0..N-1 (the cycle's end, phase
        1, is its start again).  When N differs from ``n_knots`` the cycle is first
        resampled at the knots by its own periodic spline.
    """
    from scipy.interpolate import CubicSpline

    v = np.asarray(values, np.float64)
    if v.ndim < 1 or v.shape[-1] < 3:
        raise ValueError(f"a periodic pattern needs at least 3 samples, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("a periodic pattern has non-finite samples")

    def closed(y):
        x = np.linspace(0.0, 1.0, y.shape[-1] + 1)
        return CubicSpline(x, np.concatenate([y, y[..., :1]], -1), axis=-1, bc_type="periodic")

    if v.shape[-1] != n_knots:
        v = closed(v)(np.arange(n_knots) / n_knots)
    cs = closed(v)
    # scipy: c (4, n, ...) highest power first over intervals; move to (..., n, 4)
    return np.moveaxis(np.moveaxis(cs.c, 0, -1), 0, -2)


def awo_step(x, theta, dtheta, spline: PeriodicSpline, dt, gamma: float = AWO_GAMMA):
    """One explicit step of the arbitrary-wave oscillator (eq. 6.5, K = 0).

    Args:
      x: (...) oscillator outputs; theta: their phases [cycles]; dtheta: phase rates
        [cycles/s] over the step; spline: their shapes g; dt: step [s]; gamma: rate [1/s].
    Returns the new x.  Stable for gamma dt < 2 (0.05 at 0.5 ms).
    """
    g, dg = spline(theta)
    return x + dt * (gamma * (g - x) + dg * dtheta)


def clock_step(theta, omega, touchdown, dt, p: float = CLOCK_SLOW_PHASE):
    """One step of the central clocks (eq. 6.6-6.9): ``(new theta, mean rate over the step)``.

    Args:
      theta: (...) phases in [0, 1) [cycles]; omega: frequency [cycles/s] (clipped to
        :data:`OMEGA_MIN`); touchdown: (...) bool, the ipsilateral leg touched down this step
        (the clock restarts at 0); dt: step [s]; p: phase where the slowing starts.
    """
    omega = jnp.maximum(omega, OMEGA_MIN)
    lin_end = jnp.minimum(theta + omega * dt, p)
    base = jnp.where(theta < p, lin_end, theta)
    rest = jnp.where(theta < p, jnp.maximum(dt - (p - theta) / omega, 0.0), dt)
    slowed = 1.0 - (1.0 - base) * jnp.exp(-omega * rest / (1.0 - p))
    new = jnp.where(rest > 0.0, slowed, base)
    # the exponential approach rounds to 1 after a long wait: stay strictly below
    new = jnp.minimum(new, jnp.nextafter(jnp.ones((), new.dtype), jnp.zeros((), new.dtype)))
    rate = (new - theta) / dt
    return jnp.where(touchdown, jnp.zeros_like(new), new), rate


def clock_rate(theta, omega, p: float = CLOCK_SLOW_PHASE):
    """theta' of the slowed clock at phase ``theta`` (eq. 6.7's intent): omega below p,
    omega (1 - theta) / (1 - p) above."""
    omega = jnp.maximum(omega, OMEGA_MIN)
    return jnp.where(theta < p, omega, omega * (1.0 - theta) / (1.0 - p))
