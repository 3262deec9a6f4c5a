"""The elements of Geyer's Hill-type muscle-tendon unit, normalised (thesis eq. 2.4-2.16).

Force-length f_l (eq. 2.4), force-velocity f_v and its inverse (eq. 2.5 / 2.16), tendon f_se
(eq. 2.9-2.10), parallel element f_pe* (eq. 2.12) and buffer element f_be (eq. 2.11, with the
SPEC section 8 erratum), with the shared constants of thesis Table 2.1 / geyer_reference.md
section 1c.  Every function is dimensionless, branchless and broadcasts; the muscle tables
(:mod:`jaxgait.muscles.tables`) and the contraction dynamics (:mod:`jaxgait.muscles.mtu`) build
on them.
"""

from __future__ import annotations

import math

import jax.numpy as jnp

# Shared constants (geyer_reference.md section 1c; thesis Table 2.1 and section 2.1.1.1).
W_DEFAULT = 0.56  # CE force-length width [l_opt]
C_DEFAULT = math.log(0.05)  # f_l = 0.05 at l_ce = l_opt (1 +- w)
N_DEFAULT = 1.5  # eccentric force enhancement [F_max] (SPEC section 8: N = 1.5, K = 5)
K_DEFAULT = 5.0  # force-velocity shape factor
EPS_REF_DEFAULT = 0.04  # tendon reference strain [l_slack]
TAU_ACT_DEFAULT = 0.01  # excitation-contraction time constant [s]


def compute_dtype(*xs):
    """Float dtype for the computation: that of the inputs, at least float32."""
    return jnp.result_type(*xs, jnp.float32)


def as_const(a, dtype):
    """A static table array as a jnp constant of ``dtype``."""
    return jnp.asarray(a, dtype=dtype)


# ----------------------------------------------------------------------------------------------
# element characteristics (all normalised, dimensionless)


def f_l(l_norm, w=W_DEFAULT, c=C_DEFAULT):
    """CE force-length factor, eq. 2.4.

    f_l = exp(c |(l_ce - l_opt) / (l_opt w)|^3) with l_norm = l_ce / l_opt [-];
    f_l(1) = 1 and f_l(1 +- w) = exp(c) = 0.05.
    """
    x = (jnp.asarray(l_norm) - 1.0) / w
    return jnp.exp(c * jnp.abs(x) ** 3)


# slope d f_v / d v_n of eq. 2.16's third branch (Geyer's code: v_n = 0.01 (f_v - N) + 1)
FV_LINE_SLOPE = 100.0


def f_v(v_n, N=N_DEFAULT, K=K_DEFAULT):
    """CE force-velocity factor (forward form of eq. 2.5 / 2.16, shortening negative).

    v_n = v_ce / (v_max l_opt) [-]:
      v_n < 0:  f_v = (1 + v_n) / (1 - K v_n)          (concentric; f_v(-1) = 0)
      v_n >= 0: f_v = N + (N - 1)(v_n - 1) / (7.56 K v_n + 1)   (eccentric; f_v(0) = 1,
                f_v(1) = N, f_v -> N + (N - 1)/(7.56 K) ~ 1.513 for v_n -> inf)
    This is the algebraic inverse of the first two branches of ``v_from_fv``
    (geyer_reference.md section 1c, "equivalent forward form").  For v_n < -1 the concentric
    branch is continued (negative values).
    """
    v_n = jnp.asarray(v_n)
    vc = jnp.minimum(v_n, 0.0)
    ve = jnp.maximum(v_n, 0.0)
    conc = (1.0 + vc) / (1.0 - K * vc)
    ecc = N + (N - 1.0) * (ve - 1.0) / (7.56 * K * ve + 1.0)
    return jnp.where(v_n < 0.0, conc, ecc)


def v_from_fv(fv, N=N_DEFAULT, K=K_DEFAULT):
    """Inverse force-velocity relation, eq. 2.16 as in Geyer's code; returns v_n [-].

    Three branches (geyer_reference.md section 1c):
      fv <= 1:     v_n = (fv - 1) / (K fv + 1)                       (concentric)
      1 < fv <= N: v_n = (x + 1) / (1 - 7.56 K x),  x = (fv - N)/(N - 1)   (eccentric)
      fv > N:      v_n = 0.01 (fv - N) + 1                             (linear continuation)
    The third branch replaces the pole of eq. 2.16 at fv = N + (N - 1)/(7.56 K) by a steep
    line; it is not the inverse of ``f_v`` for v_n > 1.  ``v_from_fv`` and ``f_v`` are exact
    inverses on fv in [0, N] <-> v_n in [-1, 1].  fv < 0 is treated as 0 (v_n = -1).
    Each branch sees its own clipped argument, so values and gradients stay finite.
    """
    fv = jnp.asarray(fv)
    f_lo = jnp.clip(fv, 0.0, 1.0)
    conc = (f_lo - 1.0) / (K * f_lo + 1.0)
    x = (jnp.clip(fv, 1.0, N) - N) / (N - 1.0)
    ecc = (x + 1.0) / (1.0 - 7.56 * K * x)
    lin = (fv - N) / FV_LINE_SLOPE + 1.0
    return jnp.where(fv <= 1.0, conc, jnp.where(fv <= N, ecc, lin))


def f_se(l_se, l_slack, eps_ref=EPS_REF_DEFAULT):
    """Normalised tendon (SE) force F_se / F_max, eq. 2.9/2.10.

    eps = (l_se - l_slack) / l_slack; f_se = (eps / eps_ref)^2 for eps > 0, else 0.
    Lengths in m.
    """
    eps = (jnp.asarray(l_se) / l_slack - 1.0) / eps_ref
    return jnp.maximum(eps, 0.0) ** 2


def f_pe_star(l_norm, w=W_DEFAULT):
    """Normalised parallel-element force F_pe* / F_max, eq. 2.12 (PE reference strain w).

    f_pe* = ((l_norm - 1) / w)^2 for l_norm = l_ce / l_opt > 1, else 0.
    (The PE force is F_max f_pe* f_v, eq. 2.8.)
    """
    return (jnp.maximum(jnp.asarray(l_norm) - 1.0, 0.0) / w) ** 2


def f_be(l_norm, w=W_DEFAULT):
    """Normalised buffer-element force F_be / F_max, eq. 2.11 with the SPEC section 8 erratum.

    The BE engages when l_ce < l_opt (1 - w): f_be = ((l_norm - (1 - w)) / (w/2))^2, else 0.
    """
    return (jnp.maximum((1.0 - w) - jnp.asarray(l_norm), 0.0) / (0.5 * w)) ** 2
