"""Linearly-implicit resolution of stiff velocity damping in generalised coordinates.

Ground contact (Geyer's damping grows as k d / v_max) and the ligament soft limits
(k Delta / omega_ref) are spring-dampers acting along "rows": a row r has a Jacobian J_r
(nv,), a spring force a_r and a damping coefficient c_r >= 0, so its force is
f_r = a_r - c_r y_r with y_r = J_r v the row velocity.  With semi-implicit Euler,

    v+ = v + dt (qacc0 + M^-1 J^T f),          f = a - C J v+,

where qacc0 is the acceleration from every other force.  Taking the damping at the new
velocity (backward Euler in the damping only) gives the R x R linear system

    (I + dt A C) y = J v + dt J qacc0 + dt A a,     A = J M^-1 J^T,

whose solution y is unconditionally stable for any c_r >= 0.  With S = C^1/2 and w = S y
it is solved in the symmetric positive-definite form

    (I + dt S A S) w = S r,        y = r - dt A S w,        r = J v + dt J qacc0 + dt A a,

by an unrolled Cholesky factorisation (:mod:`jaxgait.linalg`; no pivoting needed, the
matrix is >= I).  Forces are then clipped by each law's own rules (e.g. the normal force
stays >= 0), which can only remove force.
"""

from __future__ import annotations

import jax.numpy as jnp

from jaxgait.linalg import spd_solve


def implicit_row_velocities(J, a, c, qvel, qacc0, minv_jt, dt):
    """Row velocities y (R,) of the linearly-implicit step.

    Args:
      J: (R, nv) row Jacobians.  a, c: (R,) spring forces [N] and damping coefficients
        [N s/m] (c >= 0).
      qvel, qacc0: (nv,) velocity and acceleration from all other forces.
      minv_jt: (nv, R) M^-1 J^T (the rows' Jacobians through the inverse mass matrix).
      dt: time step [s].

    Returns (y, minv_jt).
    """
    A = J @ minv_jt  # (R, R), symmetric positive semi-definite
    R = J.shape[0]
    on = c > 0  # sqrt with a finite derivative (rows with c = 0 carry no damping)
    s = jnp.where(on, jnp.sqrt(jnp.where(on, c, 1.0)), 0.0)
    r = J @ (qvel + dt * qacc0) + dt * (A @ a)
    K = jnp.eye(R, dtype=J.dtype) + dt * (s[:, None] * A * s[None, :])
    w = spd_solve(K, s * r)
    return r - dt * (A @ (s * w)), minv_jt


__all__ = ["implicit_row_velocities"]
