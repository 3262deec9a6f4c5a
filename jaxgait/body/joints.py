"""Joint angle conventions and the ligament soft limits (thesis eq. 2.38, Table 2.3).

Two angle conventions meet here:

* MJCF / Winter (used in the state, the logs and the plots): hip flexion +, knee flexion +,
  ankle dorsiflexion +, 0 = upright with the foot flat.
* Geyer-Herr internal (used by the muscle geometry and the reflexes): ankle 90 deg at
  neutral (smaller = dorsiflexion), knee 180 deg at full extension, hip 180 deg straight
  (thigh-trunk angle, smaller = flexion).

  phi_hip = pi - q_hip,  phi_knee = pi - q_knee,  phi_ankle = pi/2 - q_ankle,
  and a torque tau_phi about phi is tau_q = -tau_phi about q.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

_OFFSET = np.array([np.pi, np.pi, np.pi / 2])  # hip, knee, ankle


def q_to_phi(q_leg: jax.Array) -> jax.Array:
    """(..., 3) Winter joint angles (hip, knee, ankle) [rad] -> GH2010 angles [rad]."""
    q_leg = jnp.asarray(q_leg)
    return jnp.asarray(_OFFSET, q_leg.dtype) - q_leg


def phi_to_q(phi: jax.Array) -> jax.Array:
    """Inverse of :func:`q_to_phi`."""
    phi = jnp.asarray(phi)
    return jnp.asarray(_OFFSET, phi.dtype) - phi


@dataclass(frozen=True)
class SoftLimits:
    """Ranges (GH convention, rad) outside which the ligament torque engages.

    Thesis Table 2.3: hip [20, 230] deg, knee [45, 175] deg, ankle [70, 130] deg;
    k = 17.19 Nm/rad (0.3 Nm/deg), omega_ref = 1.74e-2 rad/s (1 deg/s).
    """

    lower: tuple = (np.deg2rad(20.0), np.deg2rad(45.0), np.deg2rad(70.0))
    upper: tuple = (np.deg2rad(230.0), np.deg2rad(175.0), np.deg2rad(130.0))
    k: float = 17.19
    omega_ref: float = 1.74e-2


def soft_limit_torque(lim: SoftLimits, phi: jax.Array, dphi: jax.Array) -> jax.Array:
    """Ligament torque about phi (thesis eq. 2.38) [Nm], shape (..., 3).

    With Delta = angle beyond the limit (> 0 when violated) and omega the angular speed
    towards (further past) the limit, the torque pushes back into the range with magnitude
    k * Delta * (1 + omega / omega_ref) while that factor is positive, i.e. unless the
    joint already returns faster than omega_ref (Geyer's `-u1 (1 - u2) (u2 < 1)` block).
    """
    lo = jnp.asarray(lim.lower, phi.dtype)
    hi = jnp.asarray(lim.upper, phi.dtype)
    over = phi - hi  # > 0 beyond the upper limit; moving further = dphi > 0
    under = lo - phi  # > 0 beyond the lower limit; moving further = dphi < 0
    up = jnp.where(over > 0, lim.k * over * jnp.maximum(0.0, 1.0 + dphi / lim.omega_ref), 0.0)
    down = jnp.where(under > 0, lim.k * under * jnp.maximum(0.0, 1.0 - dphi / lim.omega_ref), 0.0)
    return down - up
