"""Linearly-implicit resolution of stiff velocity damping in generalised coordinates.

Ground contact (Geyer's damping grows as k d / v_max) and the ligament soft limits
(k Delta / omega_ref) are spring-dampers acting along "rows": a row r has a Jacobian J_r
(nv,), a spring force a_r and a damping coefficient c_r >= 0, so its force is
f_r = a_r - c_r y_r with y_r = J_r v the row velocity.  With semi-implicit Euler,

    v+ = v + dt (qacc0 + M^-1 J^T f),          f = a - C J v+,

where qacc0 is the acceleration from every other force.  Taking the damping at the new
velocity (backward Euler in the damping only) gives the R x R linear system

    (I + dt A C) y = J v + dt J qacc0 + dt A a,     A = J M^-1 J^T,

whose solution y is unconditionally stable for any c_r >= 0.  Forces are then clipped by
each law's own rules (e.g. the normal force stays >= 0), which can only remove force.
"""

from __future__ import annotations

import jax.numpy as jnp


def implicit_row_velocities(J, a, c, qvel, qacc0, minv, dt):
    """Row velocities y (R,) of the linearly-implicit step.

    Args:
      J: (R, nv) row Jacobians.  a, c: (R,) spring forces and damping coefficients.
      qvel, qacc0: (nv,) velocity and acceleration from all other forces.
      minv: (nv, nv) inverse mass matrix.  dt: time step [s].
    """
    mjt = minv @ J.T  # (nv, R)
    A = J @ mjt
    R = J.shape[0]
    lhs = jnp.eye(R, dtype=J.dtype) + dt * A * c[None, :]
    rhs = J @ qvel + dt * (J @ qacc0) + dt * (A @ a)
    return jnp.linalg.solve(lhs, rhs), mjt


__all__ = ["implicit_row_velocities"]
