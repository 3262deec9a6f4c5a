"""FBL+: the FBL reflex walker with Wang-style limb preparation (thesis 2.1.3, Table 2.6).

FBL+ keeps every rule of FBL (:func:`jaxgait.control.fbl.fbl_stimulation`, thesis Table 2.4) and
changes two things (thesis 2.1.3; Wang et al. 2012 section 4):

1. **Stance end** (Wang's *swing initiation*) is entered by contralateral touchdown as in FBL
   (double support, sensor ``S_DS``) **or** when the stance leg's normalised horizontal
   CoM distance exceeds the stance-end threshold::

       stance_end = DS  or  (stance and d > d_st_end)

   with d = ``S_DCOM`` = (x_CoM - x_ball) / foot_length (positive: CoM ahead of this leg's
   ball).  The stance-end rules of Table 2.4 then apply (VAS -= Fb_g(contra),
   GLU -= delta_S, HFL += delta_S).

2. A fourth phase, **swing end** (Wang's *stance preparation*), for a swing leg whose foot is
   ahead of the CoM by more than |d_sw_end| foot lengths::

       swing_end = swing  and  d < d_sw_end          (d_sw_end <= 0)

   During swing end three PD rules (thesis 2.1.3, in the form of thesis eq. 2.36 and Wang's
   muscle-driven PD law u = |{K (theta - theta_m) + D dtheta}_+-|) are *added* to the swing
   stimulation, pulling the hip and knee joints towards reference angles before landing:

       HFL += [k_p^HFL (delta_h - delta_h^ref) + k_d^HFL d(delta_h)/dt]+     (flexes the hip)
       GLU += [k_p^GLU (delta_h^ref - delta_h) - k_d^GLU d(delta_h)/dt]+     (extends the hip)
       VAS += [k_p^VAS (delta_k - delta_k^ref) + k_d^VAS d(delta_k)/dt]+     (extends the knee)

   HFL and GLU share the hip target delta_h^ref (thesis 2.1.3).

Angle conventions of the targets (the GH angles phi_h, phi_k of the sensors, see
:mod:`jaxgait.body.joints`, are converted in the law):

* hip: delta_h = phi_h - pi [rad]: 0 with the thigh in line with the trunk, **negative in
  flexion** (thigh ahead of the trunk).  Table 2.6's range [-1, 0] rad for delta_h^ref spans
  a straight hip to 57 deg of flexion, the late-swing hip flexion of human walking (~20-30
  deg) lying well inside.
* knee: delta_k = pi - phi_k [rad]: knee flexion, 0 at full extension, **positive when
  bent**; Table 2.6's range [0, 1.14] rad spans 0-65 deg of flexion.

Both angles are joint (relative) angles, as the thesis states ("directing the KNEE and HIP
joint angles toward a reference angle"); Wang's SIMBICON adjustment of the hip target
belongs to the 8-muscle Wang controller, not to FBL+.

The phase tests are instantaneous (``jnp.where`` on the delayed sensors, no latch): a swing
leg leaves swing end again if its foot falls back to less than |d_sw_end| foot lengths ahead
of the CoM.  The law is evaluated once per delay group (5/10/20 ms) like FBL's, so every
muscle sees its own group's delayed CoM distance and joint angles.

**Reduction to FBL.**  With the six PD gains at 0 the swing-end additions vanish exactly
(the law selects the FBL value with ``jnp.where``), and with d_st_end above any CoM distance
reached in stance the stance-end set is FBL's double support; then
``fblplus_stimulation(p, s) == fbl_stimulation(p, s)`` bit for bit.  The table's initial
values (:data:`NEUTRAL`) are such a neutral setting (d_st_end = 3 foot lengths, its upper
bound), so :func:`lift_fbl` turns any FBL parameter set into an FBL+ set with the same gait.

Table 2.6 reading (the OCR of the range column is garbled: 12 names and 11 ranges for 10
parameters).  The ranges come in the repeating pattern [0, 2], [0, 1]; we read them as
k_p in [0, 2] and k_d in [0, 1] for each of HFL, GLU and VAS (the sixth range, a second
[0, 2], is taken as an OCR duplicate), then delta_h^ref in [-1, 0] rad,
delta_k^ref in [0, 1.14] rad, d_st_end ("st_end") in [0, 3] and d_sw_end ("sw_end") in
[-2.5, 0] foot lengths.  The threshold signs match S_DCOM: at the end of stance the CoM is
ahead of the stance ball (d > 0), before landing the swing foot is ahead of the CoM (d < 0).
The PD gains are in stimulation per rad (k_p) and per rad/s (k_d), like k_p1, k_d of FBL.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.control.commands import Command
from jaxgait.control.fbl import (
    FBL,
    GLU,
    HFL,
    LEAN_OFFSET,
    N_MUSCLES,
    S_DCOM,
    S_DHIP,
    S_DKNEE,
    S_DS,
    S_HIP,
    S_KNEE,
    S_STANCE,
    VAS,
    fbl_stimulation,
    lift_with_extras,
    packed_sensors,
    reflex_controller,
    reflex_step,
)
from jaxgait.core.params import ParamSpec, ParamTable

_T26 = "thesis Table 2.6 range (reading in jaxgait.control.fblplus)"
_N = "init = neutral (FBL+ reduces to FBL)"

#: The 10 FBL+ parameters of thesis Table 2.6 (section 2.1.3).  Initial values are the
#: neutral setting: PD gains 0 and the stance-end threshold at its upper bound.
EXTRA_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("kp_HFL", 0.0, 0.0, 2.0, "k_p^hf swing-end hip PD; " + _T26 + "; " + _N, "1/rad"),
    ParamSpec("kd_HFL", 0.0, 0.0, 1.0, "k_d^hf swing-end hip PD; " + _T26 + "; " + _N, "s/rad"),
    ParamSpec("kp_GLU", 0.0, 0.0, 2.0, "k_p^glu swing-end hip PD; " + _T26 + "; " + _N, "1/rad"),
    ParamSpec("kd_GLU", 0.0, 0.0, 1.0, "k_d^glu swing-end hip PD; " + _T26 + "; " + _N, "s/rad"),
    ParamSpec("kp_VAS", 0.0, 0.0, 2.0, "k_p^vas swing-end knee PD; " + _T26 + "; " + _N, "1/rad"),
    ParamSpec("kd_VAS", 0.0, 0.0, 1.0, "k_d^vas swing-end knee PD; " + _T26 + "; " + _N, "s/rad"),
    ParamSpec(
        "delta_hip_ref",
        -0.35,
        -1.0,
        0.0,
        "delta_ref^hip, hip target phi_h - pi (flexion < 0), ~20 deg flexion; " + _T26,
        "rad",
    ),
    ParamSpec(
        "delta_knee_ref",
        0.1,
        0.0,
        1.14,
        "delta_ref^knee, knee target pi - phi_k (flexion > 0), ~6 deg flexion; " + _T26,
        "rad",
    ),
    ParamSpec(
        "d_st_end",
        3.0,
        0.0,
        3.0,
        "st_end: stance end when (x_CoM - x_ball)/l_foot > d_st_end; " + _T26 + "; " + _N,
        "foot lengths",
    ),
    ParamSpec(
        "d_sw_end",
        -2.5,
        -2.5,
        0.0,
        "sw_end: swing end when (x_CoM - x_ball)/l_foot < d_sw_end; " + _T26,
        "foot lengths",
    ),
)

#: FBL+ parameter table: the 28 FBL parameters (thesis Table 2.5) then the 10 of Table 2.6.
FBLPLUS = ParamTable("fblplus", FBL.specs + EXTRA_SPECS)

#: Names of the 10 extra parameters, in table order.
EXTRA_NAMES: tuple[str, ...] = tuple(s.name for s in EXTRA_SPECS)

#: Neutral extra values (the table's initial values): no PD push, stance end by double
#: support only in any walking gait (CoM never 3 foot lengths ahead of the stance ball).
NEUTRAL: dict[str, float] = {s.name: s.init for s in EXTRA_SPECS}

#: Extra values that switch every FBL+ rule off for any sensor input (outside the table
#: ranges: for tests and analysis only, not a valid preset).
OFF: dict[str, float] = {**NEUTRAL, "d_st_end": float("inf"), "d_sw_end": -float("inf")}


def lift_fbl(vec_fbl, extras: dict | None = None) -> np.ndarray:
    """FBL+ parameter vector (38,) from an FBL vector (28,) and extra values.

    Args:
      vec_fbl: (28,) FBL parameters in :data:`jaxgait.control.fbl.FBL` order.
      extras: name -> value for some of :data:`EXTRA_NAMES`; the rest take :data:`NEUTRAL`.
    """
    return lift_with_extras(vec_fbl, NEUTRAL, extras, "FBL+")


def phases_plus(p: dict, s: jax.Array) -> tuple[jax.Array, jax.Array]:
    """FBL+ stance-end and swing-end masks (2,) bool from a sensor array s (2, N_SENSORS).

    stance_end = DS or (stance and d > d_st_end); swing_end = swing and d < d_sw_end, with
    d = S_DCOM (thesis 2.1.3; Wang 2012 section 4, d_SI / d_SP).
    """
    stance = s[:, S_STANCE] > 0.5
    d = s[:, S_DCOM]
    stance_end = (s[:, S_DS] > 0.5) | (stance & (d > p["d_st_end"]))
    swing_end = ~stance & (d < p["d_sw_end"])
    return stance_end, swing_end


def swing_end_pd(p: dict, s: jax.Array) -> jax.Array:
    """The swing-end PD additions (2, 7) (HFL, GLU, VAS columns; others 0), thesis 2.1.3.

    Uses delta_h = phi_h - pi (hip flexion < 0) and delta_k = pi - phi_k (knee flexion > 0);
    see the module docstring.  Applied only where the leg is in swing end.
    """
    pos = lambda x: jnp.maximum(x, 0.0)
    dh = s[:, S_HIP] - jnp.pi
    ddh = s[:, S_DHIP]
    dk = jnp.pi - s[:, S_KNEE]
    ddk = -s[:, S_DKNEE]
    e_h = dh - p["delta_hip_ref"]  # > 0: hip less flexed than the target
    e_k = dk - p["delta_knee_ref"]  # > 0: knee more bent than the target
    u_hfl = pos(p["kp_HFL"] * e_h + p["kd_HFL"] * ddh)
    u_glu = pos(-p["kp_GLU"] * e_h - p["kd_GLU"] * ddh)
    u_vas = pos(p["kp_VAS"] * e_k + p["kd_VAS"] * ddk)
    add = jnp.zeros(s.shape[:-1] + (N_MUSCLES,), s.dtype)
    return add.at[:, HFL].set(u_hfl).at[:, GLU].set(u_glu).at[:, VAS].set(u_vas)


def with_stance_end(p: dict, s: jax.Array) -> tuple[jax.Array, jax.Array]:
    """FBL+'s phases on sensors s (rows, N_SENSORS): ``(s with the double-support flag set
    where a leg is in stance end, swing_end (rows,) bool)``, so that FBL's stance-end rules
    apply there (:func:`phases_plus`)."""
    stance_end, swing_end = phases_plus(p, s)
    ds = jnp.where(stance_end & (s[:, S_DS] <= 0.5), jnp.ones_like(s[:, S_DS]), s[:, S_DS])
    return s.at[:, S_DS].set(ds), swing_end


def fblplus_stimulation(p: dict, s: jax.Array) -> jax.Array:
    """FBL+ stimulation (2, 7) from one (delayed) sensor array s (2, N_SENSORS).

    (a) FBL's law (thesis Table 2.4) on the sensors with the double-support flag replaced by
    the FBL+ stance-end mask, (b) plus the swing-end PD rules where a leg is in swing end
    (thesis 2.1.3, Table 2.6).  Branchless; equal to FBL's law when the extra rules are off
    (see the module docstring).
    """
    s_end, swing_end = with_stance_end(p, s)
    stim = fbl_stimulation(p, s_end)
    return jnp.where(swing_end[:, None], stim + swing_end_pd(p, s), stim)


def fblplus_step(ctrl, p: dict, sens, lines, command: dict, dt, pack=packed_sensors):
    """FBL+ step: FBL's reflex step with the ``hip_target_offset`` command [rad] added to the
    swing-end hip target delta_hip_ref (``pack``: the sensor packing, FBL's by default)."""
    p = {**p, "delta_hip_ref": p["delta_hip_ref"] + command["hip_target_offset"]}
    return reflex_step(ctrl, p, sens, lines, command, dt, pack=pack)


#: FBL+ command: an offset of the swing-end hip target (foot placement before landing).
HIP_TARGET_OFFSET = Command(
    "hip_target_offset", 0.0, "rad", "added to delta_hip_ref (swing-end hip target)"
)

#: The FBL+ controller (thesis 2.1.3): FBL's delays and sensors, :func:`fblplus_stimulation`.
FBLPLUS_CONTROLLER = dataclasses.replace(
    reflex_controller(
        "fblplus",
        FBLPLUS,
        fblplus_stimulation,
        commands=(LEAN_OFFSET, HIP_TARGET_OFFSET),
        description="FBL with swing-end PD rules and CoM-distance phases (thesis 2.1.3)",
    ),
    step=fblplus_step,
)
