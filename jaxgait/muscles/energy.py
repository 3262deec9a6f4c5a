"""Muscle metabolic energy (thesis section 2.1.2.4, eq. 2.41-2.44; Wang et al. 2012, section 5.1).

The model is Anderson's (1999) as extended by Bhargava et al. (2004) and used by Wang et al.
(2012) and the thesis.  Per muscle, the metabolic rate is

    E = A + M + S + W  [W]                                                     (eq. 2.41)

* A = m f_A(s): activation heat, s the neural stimulation [-],
  f_A(s) = 40 t_I sin(pi s / 2) + 133 (1 - t_I)(1 - cos(pi s / 2))  [W/kg]     (eq. 2.42)
* M = m g(l_ce / l_opt) f_M(a): maintenance heat, a the activation [-],
  g(l) = 0.5 (0 <= l <= 0.5), 1 (0.5 < l <= 1), -2 l + 3 (1 < l <= 1.5), else 0   (eq. 2.43)
  f_M(a) = 74 t_I sin(pi a / 2) + 111 (1 - t_I)(1 - cos(pi a / 2))  [W/kg]     (eq. 2.44)
* S = 0.25 F_mtu |v_ce|: shortening heat, only while the CE shortens;
* W = F_ce |v_ce|: positive work of the active CE force, only while the CE shortens.

t_I is the slow-twitch (type I) fibre fraction (``MuscleTable.type1``); the thesis writes the
fast-twitch fraction 1 - t_I as "t_I I" (SPEC section 1.5).  The muscle mass is
m = F_max / sigma * l_opt * rho with sigma = 0.25 MPa and rho = 1059.7 kg/m^3.

Velocities follow ``jaxgait.muscles.mtu``: v_ce in m/s, shortening negative, so "shortening" is
v_ce < 0 and the shortening speed is max(-v_ce, 0).

Wang et al. 2012 add a basal rate of 1.51 W per kg of body mass and define their effort as
J = w_M J_M + w_R J_R + w_L J_L with (w_M, w_R, w_L) = (100, 1, 0.5) (``wang_effort``).
Wang's own per-muscle rate (its g differs from eq. 2.43), task terms and return are in
:mod:`jaxgait.muscles.effort`.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jaxgait.muscles.mtu import MuscleTable, merge_muscle_axes

__all__ = [
    "BASAL_RATE",
    "DENSITY",
    "SIGMA",
    "WANG_EFFORT_SCALE",
    "WANG_WEIGHTS",
    "activation_heat_rate",
    "basal_rate",
    "cost_of_transport",
    "energy_per_distance",
    "maintenance_heat_rate",
    "maintenance_length_factor",
    "metabolic_components",
    "metabolic_rate",
    "muscle_mass",
    "wang_effort",
]

SIGMA = 0.25e6  # specific tension [Pa] (thesis section 2.1.2.4, SPEC section 1.5)
DENSITY = 1059.7  # muscle density [kg/m^3]
BASAL_RATE = 1.51  # basal metabolic rate per kg of body mass [W/kg] (Wang 2012, Anderson 1999)
WANG_WEIGHTS = (100.0, 1.0, 0.5)  # (w_M, w_R, w_L) of Wang 2012's effort, section 5.1
WANG_EFFORT_SCALE = 0.004  # Wang 2012 section 5: the effort enters the return as (0.004/mass) J


def muscle_mass(table: MuscleTable) -> np.ndarray:
    """Muscle masses m = F_max / sigma * l_opt * rho [kg], shape (M,) (thesis section 2.1.2.4).

    E.g. SOL: 4000 / 0.25e6 * 0.04 * 1059.7 = 0.678 kg.
    """
    return table.f_max / SIGMA * table.l_opt * DENSITY


def activation_heat_rate(s, type1):
    """Activation heat rate per kg, f_A(s) [W/kg], eq. 2.42.

    f_A(s) = 40 t_I sin(pi s/2) + 133 (1 - t_I)(1 - cos(pi s/2)); s (stimulation) clipped to
    [0, 1].
    """
    s = jnp.clip(jnp.asarray(s), 0.0, 1.0)
    x = 0.5 * jnp.pi * s
    return 40.0 * type1 * jnp.sin(x) + 133.0 * (1.0 - type1) * (1.0 - jnp.cos(x))


def maintenance_heat_rate(a, type1):
    """Maintenance heat rate per kg at optimal length, f_M(a) [W/kg], eq. 2.44.

    f_M(a) = 74 t_I sin(pi a/2) + 111 (1 - t_I)(1 - cos(pi a/2)); a (activation) clipped to
    [0, 1].
    """
    a = jnp.clip(jnp.asarray(a), 0.0, 1.0)
    x = 0.5 * jnp.pi * a
    return 74.0 * type1 * jnp.sin(x) + 111.0 * (1.0 - type1) * (1.0 - jnp.cos(x))


def maintenance_length_factor(l_norm):
    """Length dependence of the maintenance heat, g(l_ce / l_opt) [-], eq. 2.43.

    0.5 on [0, 0.5], 1 on (0.5, 1], 3 - 2 l on (1, 1.5], 0 elsewhere.
    """
    l = jnp.asarray(l_norm)
    return jnp.where(
        (l >= 0.0) & (l <= 0.5),
        0.5,
        jnp.where(
            (l > 0.5) & (l <= 1.0), 1.0, jnp.where((l > 1.0) & (l <= 1.5), 3.0 - 2.0 * l, 0.0)
        ),
    )


def metabolic_components(table: MuscleTable, stim, act, l_ce, v_ce, f_ce, f_mtu):
    """The four metabolic heat and work rates [W] per muscle, eq. 2.41-2.44.

    Args:
      table: the muscle table (masses and t_I).
      stim: (..., M) neural stimulation s [-].
      act: (..., M) activation a [-].
      l_ce: (..., M) CE length [m].
      v_ce: (..., M) CE velocity [m/s], shortening negative.
      f_ce: (..., M) active CE force A F_max f_l f_v [N].
      f_mtu: (..., M) total MTU force [N].
      (``jaxgait.muscles.mtu.muscle_step`` returns all of them in its ``info``.)

    Returns:
      dict of (..., M) arrays: ``activation`` A = m f_A(s), ``maintenance``
      M = m g(l_ce/l_opt) f_M(a), ``shortening`` S = 0.25 F_mtu max(-v_ce, 0) and ``work``
      W = F_ce max(-v_ce, 0).
    """
    v_ce = jnp.asarray(v_ce)
    dt = jnp.result_type(v_ce, jnp.float32)
    m = jnp.asarray(muscle_mass(table), dtype=dt)
    t1 = jnp.asarray(table.type1, dtype=dt)
    l_opt = jnp.asarray(table.l_opt, dtype=dt)
    speed = jnp.maximum(-v_ce, 0.0)  # shortening speed [m/s]; 0 while lengthening
    return {
        "activation": m * activation_heat_rate(stim, t1),
        "maintenance": m
        * maintenance_length_factor(jnp.asarray(l_ce) / l_opt)
        * maintenance_heat_rate(act, t1),
        "shortening": 0.25 * jnp.asarray(f_mtu) * speed,
        "work": jnp.asarray(f_ce) * speed,
    }


def metabolic_rate(table: MuscleTable, stim, act, l_ce, v_ce, f_ce, f_mtu):
    """Metabolic rate E = A + M + S + W [W] per muscle, shape (..., M), eq. 2.41.

    Arguments as in ``metabolic_components``.  Sum over muscles (and legs) and integrate over
    time for the energy [J]; the thesis' dE = dt * sum_m E_m.
    """
    xs = jnp.broadcast_arrays(stim, act, l_ce, v_ce, f_ce, f_mtu)
    shape = xs[0].shape
    table, xs = merge_muscle_axes(table, *xs)
    c = metabolic_components(table, *xs)
    return (c["activation"] + c["maintenance"] + c["shortening"] + c["work"]).reshape(shape)


def basal_rate(body_mass):
    """Wang 2012's basal metabolic rate, 1.51 W/kg * body mass [W] (Anderson 1999)."""
    return BASAL_RATE * jnp.asarray(body_mass)


def _time_mean(x, mask):
    """Mean over axis 0 of the per-step sums over all other axes, optionally masked."""
    x = jnp.asarray(x)
    per_step = jnp.sum(x.reshape(x.shape[0], -1), axis=-1)
    if mask is None:
        return jnp.mean(per_step)
    mask = jnp.asarray(mask, dtype=per_step.dtype)
    return jnp.sum(mask * per_step) / jnp.maximum(jnp.sum(mask), 1.0)


def wang_effort(
    muscle_rate,
    limit_torque,
    body_mass,
    other_torque=None,
    weights=WANG_WEIGHTS,
    mask=None,
):
    """Wang et al. 2012 effort (section 5.1): J = w_M J_M + w_R J_R + w_L J_L.

    Args:
      muscle_rate: (T, ...) metabolic rates E_m,t [W] of all muscles at each time step (all
        axes after the first are summed, e.g. (T, 2, M)).
      limit_torque: (T, ...) joint soft-limit torques of the hips, knees and ankles [N m].
      body_mass: body mass [kg] for the basal rate.
      other_torque: (T, ...) torques of the remaining actuated DOFs [N m]; Wang's upper body
        and non-sagittal DOFs.  None (the planar models here have none) gives J_R = 0.
      weights: (w_M, w_R, w_L), default (100, 1, 0.5).
      mask: optional (T,) weights of valid steps (e.g. before a fall); the means are taken over
        them.

    Returns:
      dict with
        ``J_M`` = B + (1/T) sum_t sum_m E_m,t [W], mean metabolic power with the basal rate
          B = 1.51 W/kg * body_mass;
        ``J_R`` = (1/T) sum_t sum_j tau_j,t^2 over ``other_torque`` [N^2 m^2];
        ``J_L`` = (1/T) sum_t sum_j tau_lim,j,t^2 [N^2 m^2];
        ``J`` the weighted sum.  Wang's return uses (0.004 / mass) J (``WANG_EFFORT_SCALE``).
    """
    w_m, w_r, w_l = weights
    j_m = basal_rate(body_mass) + _time_mean(muscle_rate, mask)
    j_l = _time_mean(jnp.square(jnp.asarray(limit_torque)), mask)
    j_r = (
        jnp.zeros_like(j_l)
        if other_torque is None
        else _time_mean(jnp.square(jnp.asarray(other_torque)), mask)
    )
    return {"J_M": j_m, "J_R": j_r, "J_L": j_l, "J": w_m * j_m + w_r * j_r + w_l * j_l}


def energy_per_distance(energy, distance):
    """Metabolic energy per distance travelled [J/m] (thesis: 131-257 J/m at 1.3 m/s)."""
    return jnp.asarray(energy) / jnp.maximum(jnp.asarray(distance), 1e-9)


def cost_of_transport(energy, distance, body_mass):
    """Metabolic cost of transport [J/(kg m)]: energy / (body mass * distance)."""
    return energy_per_distance(energy, distance) / jnp.asarray(body_mass)
