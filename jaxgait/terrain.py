"""Terrain as a pure height function z = h(x) of the horizontal position (sagittal plane).

Every terrain is one pytree type, :class:`Terrain`: a piecewise-linear profile through
``K`` knots (x_k, z_k) with linear extrapolation beyond both ends using the end segments'
slopes.  Flat ground, constant slopes, wavy ground (trapezoids) and the increasing slope are
all built as knots, so a batch of different random terrains is simply a batch of knot arrays
(``vmap``-able, no Python branching on the terrain kind inside the jitted step).

Units: metres.  Slope in rise/run (0.1 = 10 %).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct


@struct.dataclass
class Terrain:
    """Piecewise-linear ground profile.

    Attributes:
      xs: (K,) strictly increasing knot abscissae [m], K >= 2.
      zs: (K,) knot heights [m].
    """

    xs: jax.Array
    zs: jax.Array

    def segment(self, x):
        """Index i of the segment [x_i, x_{i+1}] used at x (end segments extrapolate)."""
        k = self.xs.shape[-1]
        i = jnp.searchsorted(self.xs, x, side="right") - 1
        return jnp.clip(i, 0, k - 2)

    def slope(self, x):
        """dh/dx at x (rise/run) of the segment containing x."""
        i = self.segment(x)
        x0, x1 = self.xs[i], self.xs[i + 1]
        z0, z1 = self.zs[i], self.zs[i + 1]
        return (z1 - z0) / (x1 - x0)

    def height(self, x):
        """Ground height h(x) [m]."""
        i = self.segment(x)
        x0, z0 = self.xs[i], self.zs[i]
        return z0 + self.slope(x) * (x - x0)

    def normal(self, x):
        """Unit upward ground normal (n_x, n_z) at x."""
        s = self.slope(x)
        inv = 1.0 / jnp.sqrt(1.0 + s * s)
        return jnp.stack([-s * inv, inv], -1)


def flat(length: float = 1000.0, dtype=jnp.float32) -> Terrain:
    """Level ground at z = 0 (environment 1)."""
    return Terrain(xs=jnp.asarray([-10.0, length], dtype), zs=jnp.zeros(2, dtype))


def slope(grade: float, start: float = 2.0, length: float = 1000.0, dtype=jnp.float32) -> Terrain:
    """Level ground up to ``start`` then a constant grade (rise/run; negative = downhill)."""
    xs = np.array([-10.0, start, length])
    zs = np.array([0.0, 0.0, grade * (length - start)])
    return Terrain(xs=jnp.asarray(xs, dtype), zs=jnp.asarray(zs, dtype))
