"""Geyer Hill-type muscle-tendon units (MTUs), batched over muscles.

The model is Geyer's MTU (Geyer, Seyfarth & Blickhan 2003; Geyer & Herr 2010, "GH2010") as
written up in Dzeladini's thesis (2013), section 2.1.1.1, eq. 2.1-2.30 and Tables 2.1/2.2, with
the seed errata of SPEC section 8 applied:

* N = 1.5 (eccentric force enhancement) and K = 5 (shape factor), not the swapped nomenclature;
* one force-velocity convention: shortening is negative, v_n = v_ce / (v_max * l_opt);
* the buffer element engages when l_ce < l_opt (1 - w) (eq. 2.7/2.11 print another condition);
* SOL is the uniarticular ankle plantarflexor and GAS spans knee and ankle (Table 2.2 swaps the
  joint rows; the geometry below is GH2010's, see ``geyer_reference.md`` section 1b).

Each MTU is a contractile element (CE) with a parallel element (PE) and a buffer element (BE), in
series with a tendon (SE).  The state is the activation A and the CE length l_ce.  Given the MTU
length from the joint angles (eq. 2.23-2.24), the force balance F_se + F_be = F_ce + F_pe is
solved for the force-velocity factor (eq. 2.15), inverted to the CE velocity (eq. 2.16) and
integrated.

Shapes: every muscle quantity has shape (..., M) with the muscle order of the table (for GEYER7
``MUSCLES = ("HFL", "GLU", "HAM", "VAS", "GAS", "SOL", "TA")``); joint quantities have shape
(..., 3) ordered (hip, knee, ankle).  The simulator uses (2, M) [leg, muscle] and (2, 3)
[leg, joint].  All functions broadcast over leading axes, are branchless and jit/vmap/grad safe.

Layout: the element characteristics (eq. 2.4-2.16) are in :mod:`jaxgait.muscles.elements`,
the muscle tables and their joint geometry (eq. 2.17-2.24, 2.37; GH2010 angle convention) in
:mod:`jaxgait.muscles.tables`; this module integrates the MTU state and re-exports both, so
``mtu.f_v`` or ``mtu.GEYER7`` keep working.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxgait.muscles.elements import (
    FV_LINE_SLOPE,
    as_const,
    compute_dtype,
    f_be,
    f_l,
    f_pe_star,
    f_se,
    f_v,
    v_from_fv,
)
from jaxgait.muscles.tables import (
    GEYER7,
    JOINTS,
    MUSCLES,
    MUSCLES8,
    WANG8,
    MuscleTable,
    joint_torques,
    moment_arms,
    mtu_length,
    mtu_length_changes,
)

__all__ = [
    "ACT_MIN",
    "GEYER7",
    "JOINTS",
    "MUSCLES",
    "MUSCLES8",
    "WANG8",
    "MuscleState",
    "MuscleTable",
    "contraction_velocity",
    "f_be",
    "f_l",
    "f_pe_star",
    "f_se",
    "f_v",
    "force_velocity_balance",
    "init_lce",
    "init_muscle_state",
    "merge_muscle_axes",
    "joint_torques",
    "moment_arms",
    "mtu_force",
    "mtu_length",
    "mtu_length_changes",
    "muscle_step",
    "stim_upper",
    "v_from_fv",
]

#: Lower bound of activation and stimulation (Geyer's pre-activation ``preA``).  f_v is
#: undefined at zero activation, so the force balance always uses max(A, ACT_MIN).
ACT_MIN = 0.01
# Floor on A f_l + f_pe in eq. 2.15.  With A >= 0.01 it binds only when f_l < 0.01, i.e.
# l_ce < 0.35 l_opt, deep inside the buffer-element range where no equilibrium exists; it
# bounds the (then huge) lengthening speed the buffer element commands.
_DEN_MIN = 1e-4
# Safety floor on l_ce [l_opt]; never reached in normal operation (the BE engages at 1 - w).
_LCE_MIN = 0.05

#: default iterations of the backward-Euler CE solve after its first intersection
#: (``muscle_step``); per-step accuracy in ``benchmarks/ce_solver_accuracy.py``
CE_SOLVE_ITERS = 1


# ----------------------------------------------------------------------------------------------
# contraction dynamics


@struct.dataclass
class MuscleState:
    """MTU state (pytree).

    Attributes:
      act: (..., M) activation A [-].
      l_ce: (..., M) contractile-element length [m].
    """

    act: jax.Array
    l_ce: jax.Array


def mtu_force(table: MuscleTable, act, l_ce, l_mtu):
    """MTU force F_mtu = F_se = F_max f_se(l_mtu - l_ce) [N], shape (..., M) (eq. 2.1, 2.9).

    act is not needed (the tendon force depends on lengths only); it is accepted so that all
    MTU functions share one signature.  Lengths in m.
    """
    del act
    l_ce, l_mtu = jnp.asarray(l_ce), jnp.asarray(l_mtu)
    dt = compute_dtype(l_ce, l_mtu)
    fse = f_se(l_mtu - l_ce, as_const(table.l_slack, dt), table.eps_ref)
    return as_const(table.f_max, dt) * fse


def _active_fl(table: MuscleTable, act, l_norm):
    """A f_l(l_ce / l_opt) with A floored at ACT_MIN (Geyer's pre-activation) [-]."""
    return jnp.maximum(act, ACT_MIN) * f_l(l_norm, table.w, table.c)


def force_velocity_balance(table: MuscleTable, act, l_ce, l_mtu):
    """Solve the force balance for the force-velocity factor, eq. 2.13-2.15.

    f_v = (f_se + f_be) / (A f_l + f_pe*), with A >= ACT_MIN and the denominator floored.

    Returns:
      (fv, a_fl): fv (..., M) [-] and the activation-length term A f_l (..., M) [-] used, so
      that the active CE force is F_ce = F_max a_fl fv.
    """
    act, l_ce, l_mtu = jnp.asarray(act), jnp.asarray(l_ce), jnp.asarray(l_mtu)
    dt = compute_dtype(act, l_ce, l_mtu)
    l_opt = as_const(table.l_opt, dt)
    l_n = l_ce / l_opt
    fse = f_se(l_mtu - l_ce, as_const(table.l_slack, dt), table.eps_ref)
    a_fl = _active_fl(table, act, l_n)
    den = jnp.maximum(a_fl + f_pe_star(l_n, table.w), _DEN_MIN)
    fv = (fse + f_be(l_n, table.w)) / den
    return fv, a_fl


def contraction_velocity(table: MuscleTable, act, l_ce, l_mtu):
    """CE velocity v_ce [m/s], shape (..., M); shortening negative.

    Eq. 2.15 solved for f_v (``force_velocity_balance``), then inverted with eq. 2.16
    (``v_from_fv``): v_ce = v_n v_max l_opt.  Activation below ACT_MIN = 0.01 is treated as
    0.01 (Geyer's pre-activation), since f_v is undefined at A = 0.
    """
    fv, _ = force_velocity_balance(table, act, l_ce, l_mtu)
    dt = fv.dtype
    v_n = v_from_fv(fv, table.N, table.K)
    return v_n * as_const(table.v_max * table.l_opt, dt)


def backward_euler_velocity(table: MuscleTable, act, l_ce, l_mtu, h, iters: int = 100):
    """Reference solution of the backward-Euler CE step by bisection (slow; for checks).

    The root v_n [-] of f_v,balance(l_ce + h v_max l_opt v_n) = f_v(v_n) (eq. 2.15 at the end
    point against the exact inverse of eq. 2.16) in the bracket [0, v_n,explicit], bisected
    ``iters`` times; the value ``muscle_step``'s solver converges to.  act, l_ce, l_mtu are
    (..., M) arrays [-, m, m]; h [s] is the step.  Returns v_n (..., M).
    """
    act, l_ce, l_mtu = jnp.asarray(act), jnp.asarray(l_ce), jnp.asarray(l_mtu)
    fdt = compute_dtype(act, l_ce, l_mtu)
    c = jnp.asarray(h, fdt) * as_const(table.v_max * table.l_opt, fdt)

    def g(v):
        fb = force_velocity_balance(table, act, l_ce + c * v, l_mtu)[0]
        return fb - _f_v_inverse_of_v_from_fv(v, table.N, table.K)

    v_e = v_from_fv(force_velocity_balance(table, act, l_ce, l_mtu)[0], table.N, table.K)

    def halve(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        above = g(mid) > 0.0  # the root lies above mid
        return jnp.where(above, mid, lo), jnp.where(above, hi, mid)

    lo, hi = jax.lax.fori_loop(0, iters, halve, (jnp.minimum(v_e, 0.0), jnp.maximum(v_e, 0.0)))
    return 0.5 * (lo + hi)


def init_lce(table: MuscleTable, l_mtu, act=None):
    """Equilibrium CE length for a given MTU length [m], shape (..., M) (eq. 2.25-2.30).

    With ``act=None`` (the thesis' assumption A = 0, v_ce = 0):
      slack MTU (l_mtu <= l_opt + l_slack): l_ce = l_opt                         (eq. 2.25)
      otherwise F_pe = F_se (eq. 2.27-2.28, f_v = 1):
        l_se = l_slack (l_opt w + eps_ref (l_mtu - l_opt)) / (l_opt w + eps_ref l_slack)
        l_ce = l_mtu - l_se                                                      (eq. 2.29-2.30)
    Both branches give l_ce >= l_opt and meet at l_mtu = l_opt + l_slack, so no clipping is
    needed.

    With ``act`` given ((..., M) or scalar), the exact resting equilibrium of
    ``contraction_velocity`` (v_ce = 0: f_se + f_be = max(A, 0.01) f_l + f_pe*) is found by
    bisection on l_ce in [0.22 l_opt, max(l_mtu - l_slack, (1 - w) l_opt)], where the balance
    changes sign; a simulation started there has v_ce ~ 0.  Its derivatives (w.r.t. l_mtu and
    act) follow from the implicit-function theorem.
    """
    l_mtu = jnp.asarray(l_mtu)
    dt = compute_dtype(l_mtu)
    l_opt, l_slack = as_const(table.l_opt, dt), as_const(table.l_slack, dt)
    w, eps = table.w, table.eps_ref
    l_se = l_slack * (l_opt * w + eps * (l_mtu - l_opt)) / (l_opt * w + eps * l_slack)
    l_ce0 = jnp.where(l_mtu > l_opt + l_slack, l_mtu - l_se, l_opt)
    l_ce0 = jnp.broadcast_to(l_ce0, l_mtu.shape)
    if act is None:
        return l_ce0

    act = jnp.asarray(act, dtype=dt)
    a = jnp.maximum(act, ACT_MIN)

    def residual(l_ce):  # > 0: net force lengthens the CE (v_ce > 0)
        l_n = l_ce / l_opt
        return (
            f_se(l_mtu - l_ce, l_slack, eps)
            + f_be(l_n, w)
            - a * f_l(l_n, w, table.c)
            - f_pe_star(l_n, w)
        )

    shape = jnp.broadcast_shapes(l_mtu.shape, a.shape, l_opt.shape)
    hi = jnp.broadcast_to(jnp.maximum(l_mtu - l_slack, (1.0 - w) * l_opt), shape)
    lo = jnp.minimum(0.5 * (1.0 - w) * l_opt, hi)

    def bisect(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        up = residual(mid) > 0.0  # root lies above mid
        return jnp.where(up, mid, lo), jnp.where(up, hi, mid)

    sg = jax.lax.stop_gradient
    lo, hi = jax.lax.fori_loop(0, 60, bisect, (sg(lo), sg(hi)))
    root = sg(0.5 * (lo + hi))
    # derivatives of the root by the implicit-function theorem (the value is unchanged)
    r, dr = jax.jvp(residual, (root,), (jnp.ones_like(root),))
    dr = sg(dr)
    corr = -r / jnp.where(dr < 0.0, dr, -1.0)
    return root + (corr - sg(corr))


def init_muscle_state(table: MuscleTable, l_mtu, act=ACT_MIN, exact=True):
    """Resting MuscleState for MTU lengths l_mtu (..., M) [m] and activation ``act``.

    exact=True solves the balance at this activation (``init_lce(..., act)``); exact=False uses
    the thesis' closed form (eq. 2.25-2.30, A = 0).
    """
    l_mtu = jnp.asarray(l_mtu)
    dt = compute_dtype(l_mtu)
    a = jnp.broadcast_to(jnp.asarray(act, dtype=dt), l_mtu.shape)
    l_ce = init_lce(table, l_mtu, a if exact else None)
    return MuscleState(act=a, l_ce=l_ce)


def _f_v_inverse_of_v_from_fv(v_n, N, K):
    """Exact inverse of ``v_from_fv`` on v_n >= -1: ``f_v`` up to v_n = 1, then the line
    fv = N + 100 (v_n - 1) of its third branch."""
    return jnp.where(v_n <= 1.0, f_v(v_n, N, K), N + FV_LINE_SLOPE * (v_n - 1.0))


def merge_muscle_axes(table: MuscleTable, *xs):
    """(..., L, M) arrays (e.g. legs x muscles) as (..., L M) against ``table.tiled(L)``.

    XLA's CPU loops vectorise the minor axis, and M = 7 muscles fill less than half of a
    vector register.  Returns (tiled table, merged arrays); arrays of one axis come back as
    they are.  The caller reshapes results back to (..., L, M).
    """
    shape = xs[0].shape
    if len(shape) < 2:
        return table, xs
    merged = shape[:-2] + (shape[-2] * shape[-1],)
    return table.tiled(shape[-2]), tuple(x.reshape(merged) for x in xs)


def stim_upper(table: MuscleTable, dtype):
    """Upper bound of the stimulation, (M,) or the scalar 1 (every source table: the step's
    program is then the one it always was)."""
    if np.all(table.stim_max == 1.0):
        return 1.0
    return as_const(table.stim_max, dtype)


def muscle_step(
    table: MuscleTable,
    state: MuscleState,
    stim,
    l_mtu,
    dt,
    substeps: int = 1,
    implicit: bool = True,
    solve_iters: int = CE_SOLVE_ITERS,
):
    """Advance the MTU state by dt [s] with ``substeps`` fixed sub-steps of h = dt / substeps.

    stim (..., M) is clipped to [0.01, stim_max] (``table.stim_max``: 1 but in a capacity
    study); l_mtu (..., M) [m] is held over the step.  Per sub-step, both updates starting
    from the state at the start of the sub-step:

    * activation, dA/dt = (S - A) / tau (eq. 2.6, tau = 0.01 s), updated exactly for constant S:
      A <- S + (A - S) exp(-h / tau);
    * CE length, dl_ce/dt = v_ce(A, l_ce, l_mtu) (eq. 2.15-2.16).

      ``implicit=True`` (default): backward Euler, l' = l_ce + h v_ce(A, l', l_mtu).  It is
      solved per muscle for the normalised velocity v_n of the step, as the root of
      f_v,balance(l_ce + h v_max l_opt v_n) = f_v(v_n) (eq. 2.15 at the end point against the
      exact inverse of eq. 2.16), inside the bracket [0, v_n,explicit].  Each iteration
      linearises only the balance (value and slope from jax.jvp) and intersects that line with
      the exact f_v: on either side of v_n = 0 a Moebius map (a1 v + 1) / (c1 v + 1), so a
      quadratic solved in closed form, and beyond v_n = 1 the line of eq. 2.16's third branch.
      The intersection is kept in the bracket (its midpoint if there is none).  The first is
      taken at v_n = 0, then ``solve_iters`` more; ``benchmarks/ce_solver_accuracy.py``
      measures how far the default is from the converged step (Newton's method on the whole
      residual, used before, converged slowly where f_v bends sharply just above v_n = 0).
      So the step never exceeds the explicit one, fixed points (v_ce = 0) are those of the
      ODE, and it stays stable and consistent where explicit Euler at h = 0.5 ms is not: low
      activation with a nearly slack tendon (A f_l tiny) and fast eccentric states, where f_v
      is flat and v_ce very sensitive to force.  Cost: 1 + ``solve_iters`` evaluations of
      the force balance with its slope per sub-step.  Derivatives of the step (for
      gradient-based optimisation) come from the implicit-function theorem, not by
      differentiating the iterations.

      ``implicit=False``: explicit Euler, l' = l_ce + h v_ce(A, l_ce, l_mtu); stable only
      while h |dv_ce/dl_ce| < 2.

    Coupling: with l_mtu frozen at its start-of-step value the backward-Euler CE lags the MTU
    by about one step (force error ~ tendon stiffness x h x MTU speed, ~1 % F_max at 0.5 ms in
    gait-like tests).  Computing the torques from ``mtu_force`` at the start of the step and
    passing here the MTU length at the *end* of the step (after the physics step) removes that
    lag.

    Returns:
      (new_state, info), info a dict of (..., M) arrays:
        ``f_mtu`` [N]: MTU (tendon) force at the start of the step, mtu_force(state, l_mtu) --
          the force the joints should receive over the step and the force sensors read;
        ``v_ce`` [m/s]: CE velocity of the first sub-step, (l' - l_ce) / h (for the implicit
          scheme the backward-Euler velocity v_ce(A, l', l_mtu), for the explicit one
          v_ce(A, l_ce, l_mtu));
        ``f_ce`` [N]: active CE force A F_max f_l f_v at the same point as ``v_ce`` (implicit:
          f_l at the end of the step, f_v of its velocity);
        ``act`` [-], ``l_ce`` [m]: the state at the start of the step; ``stim`` [-]: the
          clipped stimulation.
      These are the inputs of ``jaxgait.muscles.energy.metabolic_rate``.
    """
    act0 = jnp.asarray(state.act)
    l_ce0 = jnp.asarray(state.l_ce)
    l_mtu = jnp.asarray(l_mtu)
    fdt = compute_dtype(act0, l_ce0, l_mtu)
    act0, l_ce0, l_mtu = act0.astype(fdt), l_ce0.astype(fdt), l_mtu.astype(fdt)
    stim = jnp.clip(jnp.asarray(stim, dtype=fdt), ACT_MIN, stim_upper(table, fdt))
    shape = jnp.broadcast_shapes(act0.shape, l_ce0.shape, l_mtu.shape, stim.shape)
    act0, l_ce0, l_mtu, stim = (jnp.broadcast_to(x, shape) for x in (act0, l_ce0, l_mtu, stim))
    table, (act0, l_ce0, l_mtu, stim) = merge_muscle_axes(table, act0, l_ce0, l_mtu, stim)
    h = jnp.asarray(dt, dtype=fdt) / substeps
    decay = jnp.exp(-h / table.tau_act)
    vscale = as_const(table.v_max * table.l_opt, fdt)  # [m/s] per unit v_n
    c = h * vscale  # [m] per unit v_n over one sub-step
    l_min = as_const(_LCE_MIN * table.l_opt, fdt)
    N, K = table.N, table.K

    def balance(act, l_ce, l_mtu):
        return force_velocity_balance(table, act, l_ce, l_mtu)[0]

    def balance_jvp(act, l_ce, l_mtu):
        return jax.jvp(lambda x: balance(act, x, l_mtu), (l_ce,), (jnp.ones_like(l_ce),))

    def f_v_inv(v_n):
        return _f_v_inverse_of_v_from_fv(v_n, N, K)

    def solve(act, l_ce, l_mtu, c):
        """Backward-Euler v_n of one sub-step and the slope dg/dv of its residual there."""
        fb0, dfb0 = balance_jvp(act, l_ce, l_mtu)
        v_e = v_from_fv(fb0, N, K)  # explicit step; the root lies in [0, v_e]
        lo, hi = jnp.minimum(v_e, 0.0), jnp.maximum(v_e, 0.0)
        # on the root's side of v_n = 0 (the side of the explicit step), f_v is the Moebius
        # map (a1 v + 1) / (c1 v + 1) (eq. 2.16 inverted; ``f_v``)
        ecc = fb0 > 1.0
        a1 = jnp.where(ecc, N * 7.56 * K + N - 1.0, 1.0)
        c1 = jnp.where(ecc, 7.56 * K, -K)

        def intersect(v, fb, dfb, lo, hi):
            # the balance linearised at v, p + q x with q = c dfb, meets the exact f_v(x)
            # either on its Moebius piece, where qa x^2 + qb x + qc = 0 (the root nearest
            # the bracket), or, eccentric beyond v_n = 1, on the line N + 100 (x - 1) of
            # eq. 2.16's third branch (the line still above f_v(1) = N at x = 1)
            q = c * dfb
            p = fb - q * v
            qa, qb, qc = q * c1, p * c1 + q - a1, p - 1.0
            disc = qb * qb - 4.0 * qa * qc
            den = qb + jnp.where(qb >= 0.0, 1.0, -1.0) * jnp.sqrt(jnp.maximum(disc, 0.0))
            # both roots without cancellation: 2 qc / (-den) and -den / (2 qa)
            r_small = jnp.where(den != 0.0, -2.0 * qc / jnp.where(den != 0.0, den, 1.0), jnp.inf)
            r_large = jnp.where(qa != 0.0, -den / jnp.where(qa != 0.0, 2.0 * qa, 1.0), jnp.inf)

            def outside(r):
                return jnp.maximum(lo - r, 0.0) + jnp.maximum(r - hi, 0.0)

            r = jnp.where(outside(r_small) <= outside(r_large), r_small, r_large)
            r = jnp.where(disc >= 0.0, r, jnp.nan)
            on_line = ecc & (p + q > N) & (q < FV_LINE_SLOPE)
            r = jnp.where(
                on_line, (p - N + FV_LINE_SLOPE) / jnp.where(on_line, FV_LINE_SLOPE - q, 1.0), r
            )
            return jnp.where(jnp.isfinite(r), jnp.clip(r, lo, hi), 0.5 * (lo + hi))

        def iterate(_, carry):
            v, lo, hi = carry
            fb, dfb = balance_jvp(act, l_ce + c * v, l_mtu)
            g = fb - f_v_inv(v)  # decreasing in v wherever the balance decreases with l_ce
            lo = jnp.where(g > 0.0, v, lo)
            hi = jnp.where(g < 0.0, v, hi)
            return intersect(v, fb, dfb, lo, hi), lo, hi

        v = intersect(jnp.zeros_like(fb0), fb0, dfb0, lo, hi)
        v, _, _ = jax.lax.fori_loop(0, solve_iters, iterate, (v, lo, hi), unroll=True)
        # dg/dv at the root, for the implicit-function derivative (XLA drops it from
        # forward-only programs)
        _, dfb = balance_jvp(act, l_ce + c * v, l_mtu)
        _, dfv = jax.jvp(f_v_inv, (v,), (jnp.ones_like(v),))
        return v, c * dfb - dfv

    @jax.custom_jvp
    def root(act, l_ce, l_mtu, c):
        return solve(act, l_ce, l_mtu, c)[0]

    @root.defjvp
    def _root_jvp(primals, tangents):
        # implicit-function theorem on g(theta, v) = balance(l_ce + c v) - f_v^-1(v) = 0:
        # dv = -dg_theta / dg_v (evaluated only when derivatives are asked for)
        v, dg = solve(*primals)
        _, dg_theta = jax.jvp(lambda a, lc, lm, cc: balance(a, lc + cc * v, lm), primals, tangents)
        return v, jnp.where(dg < 0.0, -dg_theta / jnp.where(dg < 0.0, dg, -1.0), 0.0)

    def advance(act, l_ce):
        if not implicit:
            v = v_from_fv(balance(act, l_ce, l_mtu), N, K)
        else:
            v = root(act, l_ce, l_mtu, c)
        l_new = jnp.maximum(l_ce + c * v, l_min)
        return stim + (act - stim) * decay, l_new, v

    act1, l_ce1, v0 = advance(act0, l_ce0)
    if implicit:
        # F_ce = A F_max f_l f_v (eq. 2.2) at the end point and velocity of the step; equal to
        # the force balance there up to the solver's tolerance, without evaluating it again
        a_fl_at = _active_fl(table, act0, l_ce1 / as_const(table.l_opt, fdt))
        fv_at = f_v_inv(v0)
    else:
        fv_at, a_fl_at = force_velocity_balance(table, act0, l_ce0, l_mtu)
    if substeps > 1:

        def body(_, carry):
            a, lc = carry
            a, lc, _ = advance(a, lc)
            return a, lc

        act1, l_ce1 = jax.lax.fori_loop(1, substeps, body, (act1, l_ce1))

    info = {
        "f_mtu": mtu_force(table, act0, l_ce0, l_mtu),
        "v_ce": v0 * vscale,
        "f_ce": as_const(table.f_max, fdt) * a_fl_at * fv_at,
        "act": act0,
        "l_ce": l_ce0,
        "stim": stim,
    }
    info = {k: v.reshape(shape) for k, v in info.items()}
    return MuscleState(act=act1.reshape(shape), l_ce=l_ce1.reshape(shape)), info
