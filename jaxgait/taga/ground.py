"""Ground reaction of Taga et al. (1991), Appendix A: a 2-D spring-damper at each ankle.

While the ankle is below the terrain, y_r - y_g(x_r) < 0,

  F_g1 = -k_g (x_r - x_r0) - b_g dx_r/dt,
  F_g2 = -k_g (y_r - y_r0) + b_g f(-dy_r/dt),   f(x) = max(0, x),

and zero otherwise (left ankle: F_g3, F_g4 alike).  The rest point (x_r0, y_r0) is reset
to the point where the ankle first touches the ground, every time it touches down (after
Raibert 1984).  In a discrete-time simulation "first touches" is the first step at which
the ankle is below the terrain; the rest point is then put on the terrain surface straight
above the ankle, (x_r, y_g(x_r)).  The terrain is any :class:`jaxgait.world.terrain.Terrain`
(the same height functions as the FBL model).  Units: m, m/s, N.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from jaxgait.world.terrain import Terrain


@struct.dataclass
class GroundState:
    """Per-ankle contact memory; index 0 = right, 1 = left.

    Attributes:
      below: (2,) the ankle was below the terrain at the previous step (bool).
      rest: (2, 2) rest point (x0, y0) of the ground spring [m].
    """

    below: jax.Array
    rest: jax.Array


def initial(dtype=jnp.float32) -> GroundState:
    """No contact, rest points at the origin (overwritten at the first touchdown)."""
    return GroundState(below=jnp.zeros(2, bool), rest=jnp.zeros((2, 2), dtype))


def contact_forces(pos, vel, state: GroundState, terrain: Terrain, k_g, b_g):
    """Appendix A ground forces with the touchdown reset of the rest point.

    Args:
      pos, vel: (2, 2) ankle positions (x, y) and velocities, rows right / left [m, m/s].
      state: contact memory of the previous step.
      terrain: ground profile y_g(x).
      k_g: ground stiffness [N/m]; b_g: ground damping [N s/m].
    Returns:
      forces (2, 2) = ((F_g1, F_g2), (F_g3, F_g4)) [N]; the new :class:`GroundState`;
      touchdown (2,) bool, True on the step where the rest point was reset.
    """
    x, y = pos[:, 0], pos[:, 1]
    yg = terrain.height(x)
    below = y - yg < 0.0
    touchdown = below & ~state.below
    rest = jnp.where(touchdown[:, None], jnp.stack([x, yg], -1), state.rest)
    fx = -k_g * (x - rest[:, 0]) - b_g * vel[:, 0]
    fy = -k_g * (y - rest[:, 1]) + b_g * jnp.maximum(-vel[:, 1], 0.0)
    forces = jnp.where(below[:, None], jnp.stack([fx, fy], -1), 0.0)
    return forces, GroundState(below=below, rest=rest), touchdown


def somatic_sense(forces) -> jax.Array:
    """h(F_g2), h(F_g4): 1.0 while the vertical ground force is positive, else 0.0 (2,)."""
    return (forces[:, 1] > 0.0).astype(forces.dtype)
