"""Wang et al. 2012's effort objective and return (sections 5 and 5.1), on trajectories.

Metabolic rate per muscle (section 5.1, Anderson 1999 as extended by Bhargava et al. 2004):

    E = A + M + S + W  [W]
    A = m f_A(u),          f_A(u) = 40 t_I sin(pi u / 2) + 133 (1 - t_I)(1 - cos(pi u / 2))
    M = m g(l~) f_M(a),    f_M(a) = 74 t_I sin(pi a / 2) + 111 (1 - t_I)(1 - cos(pi a / 2))
    S = 0.25 F_mtu {-v_ce}_+,   W = F_ce {-v_ce}_+
    g(l~) = 0.5 (l~ <= 0.5), l~ (0.5 < l~ <= 1), 3 - 2 l~ (1 < l~ <= 1.5), 0 (l~ > 1.5)

with u the excitation, a the activation, l~ = l_ce / l_opt, v_ce the CE velocity (shortening
negative), F_ce the active CE force, F_mtu the MTU force, t_I the slow-twitch fibre fraction
(``MuscleTable.type1``) and m = F_max / sigma l_opt rho the muscle mass (sigma = 0.25 MPa,
rho = 1059.7 kg/m^3).  Wang's forms of f_A, f_M and g are in his supplement, which is not
available here; the formulas above are those of SCONE's "Wang2012" effort measure
(scone-core ``EffortMeasure::GetWang2012``, which also uses these sigma and rho), which agree
with the paper's section 5.1 wherever it states them.

Where the thesis (Dzeladini 2013, eq. 2.41-2.44; :mod:`jaxgait.muscles.energy`) differs:

* g on (0.5, 1]: the thesis's eq. 2.43 prints g = 1, a jump from 0.5 at l~ = 0.5; Wang's model
  (Bhargava 2004, SCONE) has g = l~, continuous.  At l~ < 0 the thesis gives 0, SCONE 0.5.
* fast-twitch fraction: both weight the fast-twitch terms by 1 - t_I (the thesis writes it
  "t_I I", SPEC 1.5); the fractions t_I themselves are Wang's supplement's, not available, so
  the muscle table's values (thesis Table 2.2, printed row) are used.
* basal rate: the thesis has none; Wang adds B = 1.51 W/kg x body mass to J_M.

Effort (section 5.1): J_effort = w_M J_M + w_R J_R + w_L J_L, (w_M, w_R, w_L) = (100, 1, 0.5),
J_M = B + (1/T) sum_t sum_m E_m,t, J_R the mean summed squared torque of the PD-controlled
DOFs that are not the sagittal hips, knees and ankles, J_L that of the soft joint-limit torques
(:func:`jaxgait.muscles.energy.wang_effort`).  In the planar model J_R covers no actuated DOF:
the only other DOFs (root x, z and trunk pitch) are unactuated, the trunk being balanced by the
hip muscles, so J_R = 0.

Return (section 5): R = sum_t r(s_t) - w_e J_effort, w_e = 0.004 / body mass, r = -sum_i K_i
with the task terms K_i (:func:`task_terms`).  Wang defines the task terms in his supplement
(not available); here they are the three the paper names -- the CoM moving forward at a
target speed, not falling for 10 s, and the upper-body orientation -- in simple squared-error
forms with weights chosen so that the task terms outweigh the effort term, as the paper
requires.  Wang's head-stability term has no counterpart (the planar model has no head).
Wang sums r over 2400 Hz steps; here each sample is weighted by its duration ``dt``, so that a
trace logged at any rate gives the same return (a per-step weight w of Wang's corresponds to a
weight of w / (1/2400 s) per second here).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from jaxgait.body.joints import SoftLimits, soft_limit_torque
from jaxgait.muscles.energy import (
    WANG_EFFORT_SCALE,
    WANG_WEIGHTS,
    activation_heat_rate,
    maintenance_heat_rate,
    muscle_mass,
    wang_effort,
)
from jaxgait.muscles.mtu import MuscleTable, merge_muscle_axes

__all__ = [
    "TaskWeights",
    "effort",
    "limit_torques",
    "task_terms",
    "wang_length_factor",
    "wang_metabolic_components",
    "wang_metabolic_rate",
    "wang_return",
]


def wang_length_factor(l_norm):
    """Maintenance-heat length factor g(l_ce / l_opt) [-] of Wang's model (Bhargava 2004):
    0.5 below 0.5, l~ on (0.5, 1], 3 - 2 l~ on (1, 1.5], 0 above (continuous)."""
    l = jnp.asarray(l_norm)
    return jnp.where(l <= 0.5, 0.5, jnp.where(l <= 1.0, l, jnp.where(l <= 1.5, 3.0 - 2.0 * l, 0.0)))


def wang_metabolic_components(table: MuscleTable, u, a, l_ce, v_ce, f_ce, f_mtu):
    """Wang's four heat and work rates [W] per muscle, section 5.1 (module docstring).

    Args: u excitation [-], a activation [-], l_ce CE length [m], v_ce CE velocity [m/s]
    (shortening negative), f_ce active CE force [N], f_mtu MTU force [N]; all (..., M) in the
    table's muscle order (:func:`jaxgait.muscles.mtu.muscle_step` returns them in its info, u
    as ``stim``).  Returns a dict of (..., M): ``activation``, ``maintenance``, ``shortening``,
    ``work``.
    """
    v_ce = jnp.asarray(v_ce)
    dt = jnp.result_type(v_ce, jnp.float32)
    m = jnp.asarray(muscle_mass(table), dt)
    t1 = jnp.asarray(table.type1, dt)
    speed = jnp.maximum(-v_ce, 0.0)
    l_norm = jnp.asarray(l_ce) / jnp.asarray(table.l_opt, dt)
    return {
        "activation": m * activation_heat_rate(u, t1),
        "maintenance": m * wang_length_factor(l_norm) * maintenance_heat_rate(a, t1),
        "shortening": 0.25 * jnp.asarray(f_mtu) * speed,
        "work": jnp.asarray(f_ce) * speed,
    }


def wang_metabolic_rate(table: MuscleTable, u, a, l_ce, v_ce, f_ce, f_mtu):
    """Wang's metabolic rate E = A + M + S + W [W] per muscle, (..., M) (e.g. (T, 2, M))."""
    xs = jnp.broadcast_arrays(u, a, l_ce, v_ce, f_ce, f_mtu)
    shape = xs[0].shape
    table, xs = merge_muscle_axes(table, *xs)
    c = wang_metabolic_components(table, *xs)
    return (c["activation"] + c["maintenance"] + c["shortening"] + c["work"]).reshape(shape)


def limit_torques(limits: SoftLimits, phi, dphi):
    """Soft joint-limit torques [N m] of the hips, knees and ankles, (..., 3), from GH joint
    angles [rad] and rates [rad/s] (thesis eq. 2.38, Geyer & Herr 2010): the J_L input."""
    return soft_limit_torque(limits, jnp.asarray(phi), jnp.asarray(dphi))


def effort(muscle_rate, limit_torque, body_mass, other_torque=None, mask=None):
    """J_effort = w_M J_M + w_R J_R + w_L J_L with Wang's weights (100, 1, 0.5), section 5.1.

    muscle_rate (T, ...) [W], e.g. :func:`wang_metabolic_rate` of a trajectory;
    limit_torque (T, ...) [N m]; body_mass [kg] for the basal rate; other_torque (T, ...) or
    None (the planar model: J_R = 0); mask (T,) valid samples.  Returns the dict of
    :func:`jaxgait.muscles.energy.wang_effort` (J_M [W], J_R, J_L [N^2 m^2], J).
    """
    return wang_effort(muscle_rate, limit_torque, body_mass, other_torque, WANG_WEIGHTS, mask)


@dataclass(frozen=True)
class TaskWeights:
    """Weights of the task terms, per second of simulated time (chosen; see the module).

    Attributes:
      speed: per (m/s)^2 s, on the squared error of the trailing-mean CoM speed.
      upright: per rad^2 s, on the squared error of the trunk pitch.
      fall: per s of the horizon not survived.
    """

    speed: float = 100.0
    upright: float = 100.0
    fall: float = 1000.0


def _trailing_mean(x, n: int):
    """Mean of the last n samples (fewer at the start) along axis 0."""
    c = jnp.cumsum(x, axis=0)
    lag = jnp.concatenate([jnp.zeros((n,), c.dtype), c[:-n]]) if n < x.shape[0] else 0.0 * c
    count = jnp.minimum(jnp.arange(1, x.shape[0] + 1), n).astype(c.dtype)
    return (c - lag) / count


def task_terms(
    t,
    com_vx,
    trunk,
    target_speed: float,
    dt: float,
    t_fall=np.inf,
    trunk_target: float = 0.0,
    weights: TaskWeights = TaskWeights(),
    horizon: float = 10.0,
    speed_window: float = 1.0,
):
    """Task terms of the return (section 5), each already summed over the trajectory.

    Args:
      t: (T,) sample times [s], spaced ``dt`` [s] (a Python float).
      com_vx: (T,) CoM forward velocity [m/s]; trunk: (T,) trunk pitch [rad].
      target_speed: v* [m/s]; t_fall: time of the fall [s] (inf: none); trunk_target [rad].
      horizon: the time to survive [s] (Wang: 10 s); speed_window: the trailing window of the
        speed mean [s] (about a gait cycle, so that the speed within a stride may vary).
    Returns:
      dict of scalars: ``speed`` = w_v dt sum_t (vbar_t - v*)^2, ``upright`` =
      w_u dt sum_t (Theta_t - Theta*)^2, both over the samples before the fall (t < t_fall)
      and the horizon; ``fall`` = w_f max(horizon - t_fall, 0); ``total`` their sum.
    """
    t, com_vx, trunk = jnp.asarray(t), jnp.asarray(com_vx), jnp.asarray(trunk)
    alive = ((t < t_fall) & (t < horizon)).astype(com_vx.dtype)
    vbar = _trailing_mean(com_vx, max(1, round(speed_window / dt)))
    speed = weights.speed * dt * jnp.sum(alive * (vbar - target_speed) ** 2)
    upright = weights.upright * dt * jnp.sum(alive * (trunk - trunk_target) ** 2)
    fall = weights.fall * jnp.clip(horizon - jnp.asarray(t_fall, com_vx.dtype), 0.0, horizon)
    return {"speed": speed, "upright": upright, "fall": fall, "total": speed + upright + fall}


def wang_return(task: dict, effort_terms: dict, body_mass):
    """R = sum_t r(s_t) - w_e J_effort with r = -sum_i K_i and w_e = 0.004 / body mass.

    task: :func:`task_terms`; effort_terms: :func:`effort`.  Returns a dict: ``R``, ``w_e``
    [1/kg], ``effort_penalty`` = w_e J_effort and ``task`` = sum_t sum_i K_i.
    """
    w_e = WANG_EFFORT_SCALE / jnp.asarray(body_mass)
    penalty = w_e * effort_terms["J"]
    return {
        "R": -task["total"] - penalty,
        "w_e": w_e,
        "effort_penalty": penalty,
        "task": task["total"],
    }
