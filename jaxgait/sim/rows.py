"""Linearly-implicit resolution of stiff velocity damping in generalised coordinates.

Ground contact (Geyer's damping grows as k d / v_max) and the ligament soft limits
(k Delta / omega_ref) are spring-dampers acting along "rows": a row r has a Jacobian J_r
(nv,), a spring force a_r and a damping coefficient c_r >= 0, so its force is
f_r = a_r - c_r y_r with y_r = J_r v the row velocity.  With semi-implicit Euler,

    M (v+ - v) = dt (f + J^T f_rows),          f_rows = a - C J v+,

where f is every other generalised force (applied, passive, minus bias).  Taking the damping
at the new velocity (backward Euler in the damping only) gives the nv x nv system

    (M + dt J^T C J) v+ = M v + dt (f + J^T a),

symmetric positive definite (M is, J^T C J is semi-definite) and so unconditionally stable
for any c_r >= 0.  It is the same step as the R x R "dual" system
(I + dt A C) y = J v + dt J M^-1 f + dt A a with A = J M^-1 J^T, but of size nv = 9
instead of R = 14 rows, and needs no M^-1 J^T.  It is solved by an unrolled Cholesky
factorisation (:mod:`jaxgait.core.linalg`); given the kinematic tree, one that skips the
structural zeros of M, which requires each row to act on one chain of the tree (a point on
one body, a joint): J^T C J then couples only degrees of freedom that M couples.  The
caller then clips the row forces by each law's own rules (e.g. the normal force stays
>= 0), which can only remove force, and applies them.
"""

from __future__ import annotations

import jax.numpy as jnp

from jaxgait.core.linalg import spd_solve


def implicit_row_velocities(J, a, c, M, qvel, qfrc, dt, parents=None):
    """Row velocities y = J v+ (R,) of the linearly-implicit step.

    Args:
      J: (R, nv) row Jacobians.  a, c: (R,) spring forces [N] and damping coefficients
        [N s/m] (c >= 0).
      M: (nv, nv) joint-space mass matrix.
      qvel: (nv,) velocity at the start of the step; qfrc: (nv,) every other generalised force
        (applied + passive - bias).
      dt: time step [s].
      parents: static dof_parentid of the kinematic tree, for the tree-structured solve
        (:func:`jaxgait.core.linalg.spd_solve`); every row must act on one chain of the tree.
    """
    # sums, not dot products: XLA's CPU dots of these tiny shapes may round differently
    # with the thread count of the device, and results must not depend on the sharding
    K = M + dt * jnp.sum(J[:, :, None] * (c[:, None] * J)[:, None, :], axis=0)
    rhs = jnp.sum(M * qvel, axis=1) + dt * (qfrc + jnp.sum(J * a[:, None], axis=0))
    return jnp.sum(J * spd_solve(K, rhs, parents), axis=1)


__all__ = ["implicit_row_velocities"]
