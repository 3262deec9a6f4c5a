"""The FBL reflex controller (Geyer & Herr 2010; thesis 2.1.2.3, Tables 2.4-2.5).

Sensors (thesis 2.1.1.2) are packed per leg into one vector so that the neural delays are
three ring buffers (5 ms hip, 10 ms knee, 20 ms ankle muscles); the stimulation law is a
pure function of a delayed sensor vector and the parameter dict, evaluated once per delay
group, and each muscle takes the result of its own group.

It is one instance of the controller interface (:data:`FBL_CONTROLLER`, built by
:func:`reflex_controller`; FBL+ is another).  The phases per leg come from the shared
gait-phase detection (:mod:`jaxgait.control.gait`): stance (filtered ground load above a
threshold, with hysteresis), swing, and stance end (trailing leg in double support: both
legs loaded and the other leg touched down last).  The command ``lean_offset`` [rad] is
added to theta_ref (0 by default).

Stance (Table 2.4), with e = theta - theta_ref, u_i = k_pi e + k_d dtheta, Fb_g = k_bw F/(Mg):
  SOL = S0 + G_SOL F_SOL
  TA  = S0 + G_TA [l_TA - loff_TA]+ - G_TA_SOL F_SOL
  GAS = S0 + G_GAS F_GAS
  VAS = S0 + G_VAS F_VAS - k_phi dphi_knee - DS Fb_g(contra)
  HAM = S0 + [u_1]+ Fb_g(ipsi)
  GLU = S0 + [u_2]+ Fb_g(ipsi) - DS delta_S
  HFL = S0 + [u_1]- Fb_g(ipsi) + DS delta_S
Swing (the thesis table is blank; Geyer & Herr 2010 as in SPEC 1.3):
  HFL = S0 + k_lean (theta_TO - theta_ref) + G_HFL [l_HFL - loff_HFL]+
            - G_HAM_HFL [l_HAM - loff_HAM]+
  HAM = S0 + G_HAM F_HAM;  GLU = S0 + G_GLU F_GLU;  TA = S0 + G_TA [l_TA - loff_TA]+
  SOL = S0;  GAS = S0;  VAS = 0.
Force feedback F is F_mtu / F_max, length feedback l is l_ce / l_opt (eq. 2.31-2.32);
dphi_knee = phi_k - phi_k_off while the knee extends past phi_k_off (eq. 2.33 as intended,
SPEC errata).  Stimulations are clipped to [0.01, 1] by the muscle model.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.control.commands import Command
from jaxgait.control.delay import DelayLine, delay_init, delay_taps, steps_for
from jaxgait.control.interface import Controller, Sensors
from jaxgait.core.params import ParamSpec, ParamTable

# muscle order (per leg) shared with jaxgait.muscles.mtu
HFL, GLU, HAM, VAS, GAS, SOL, TA = range(7)
N_MUSCLES = 7

# per-leg sensor vector layout
S_F = slice(0, 7)  # F_mtu / F_max
S_L = slice(7, 14)  # l_ce / l_opt
S_LOAD = 14  # filtered own-leg load / (M g)
S_LOAD_C = 15  # filtered contralateral load / (M g)
S_STANCE = 16  # 1 in stance
S_DS = 17  # 1 when trailing leg in double support (stance end)
S_TRUNK = 18  # trunk pitch theta [rad], forward lean +
S_DTRUNK = 19  # d theta / dt [rad/s]
S_KNEE = 20  # knee angle phi_k (GH convention) [rad]
S_DKNEE = 21  # d phi_k / dt [rad/s]
S_THETA_TO = 22  # trunk pitch at this leg's last take-off [rad]
S_HIP = 23  # hip angle phi_h (GH convention: 180 deg straight, smaller = flexion) [rad]
S_DHIP = 24  # d phi_h / dt [rad/s]
S_KNEE_W = 25  # (unused by FBL) knee angle again, kept for symmetric PD laws [rad]
S_DCOM = 26  # (x_CoM - x_ball) / foot length: CoM ahead of this leg's ball, + [-]
N_SENSORS = 27

#: delay group of each muscle: 0 = 5 ms (hip), 1 = 10 ms (knee), 2 = 20 ms (ankle)
MUSCLE_DELAY_GROUP = np.array([0, 0, 0, 1, 2, 2, 2])


@dataclass(frozen=True)
class ReflexSettings:
    """Static data of a reflex controller: its neural delays and its stimulation law.

    Attributes:
      delays: (hip, knee, ankle) muscle-group delays [s] (Geyer & Herr 2010: 5, 10, 20 ms).
      law: ``(p, sensors (rows, N_SENSORS)) -> stim (rows, 7)``, evaluated on the delayed
        sensor arrays (FBL: :func:`fbl_stimulation`).
    """

    delays: tuple = (0.005, 0.010, 0.020)
    law: Callable = None  # set by reflex_controller


def delay_taps_for(settings: ReflexSettings, dt: float) -> tuple[int, ...]:
    """The delay of each muscle group in whole steps of dt (static)."""
    return tuple(steps_for(d, dt) for d in settings.delays)


def sensor_array(f_norm, l_norm, load, stance, ds, theta, dtheta, phi, dphi, theta_to, dcom):
    """Pack the per-leg sensors into (2, N_SENSORS) (see the S_* layout).

    phi, dphi: (2, 3) GH joint angles (hip, knee, ankle) and rates; dcom: (2,) normalised
    horizontal CoM-to-ball distance.
    """
    phi_knee, dphi_knee = phi[:, 1], dphi[:, 1]
    one = jnp.ones((2,), f_norm.dtype)
    cols = [
        f_norm,
        l_norm,
        load[:, None],
        load[::-1, None],
        stance.astype(f_norm.dtype)[:, None],
        ds.astype(f_norm.dtype)[:, None],
        (theta * one)[:, None],
        (dtheta * one)[:, None],
        phi_knee[:, None],
        dphi_knee[:, None],
        theta_to[:, None],
        phi[:, 0:1],
        dphi[:, 0:1],
        phi[:, 1:2],
        dcom[:, None],
    ]
    return jnp.concatenate(cols, axis=1)


def fbl_stimulation(p: dict, s: jax.Array) -> jax.Array:
    """Stimulation (2, 7) from one (delayed) sensor array s (2, N_SENSORS); thesis Table 2.4."""
    pos = lambda x: jnp.maximum(x, 0.0)
    F = s[:, S_F]
    L = s[:, S_L]
    stance = s[:, S_STANCE] > 0.5
    ds = s[:, S_DS]
    e = s[:, S_TRUNK] - p["theta_ref"]
    u1 = p["k_p1"] * e + p["k_d"] * s[:, S_DTRUNK]
    u2 = p["k_p2"] * e + p["k_d"] * s[:, S_DTRUNK]
    fb_ipsi = p["k_bw"] * s[:, S_LOAD]
    fb_contra = p["k_bw"] * s[:, S_LOAD_C]
    over = s[:, S_KNEE] - p["phi_k_off"]
    dphi_k = jnp.where((over > 0) & (s[:, S_DKNEE] > 0), over, 0.0)
    l_ta = pos(L[:, TA] - p["loff_TA"])

    st = [None] * 7
    st[SOL] = p["S0_SOL"] + p["G_SOL"] * F[:, SOL]
    st[TA] = p["S0_TA"] + p["G_TA"] * l_ta - p["G_TA_SOL"] * F[:, SOL]
    st[GAS] = p["S0_GAS"] + p["G_GAS"] * F[:, GAS]
    st[VAS] = p["S0_VAS"] + p["G_VAS"] * F[:, VAS] - p["k_phi"] * dphi_k - ds * fb_contra
    st[HAM] = p["S0_HAM"] + pos(u1) * fb_ipsi
    st[GLU] = p["S0_GLU"] + pos(u2) * fb_ipsi - ds * p["delta_S"]
    st[HFL] = p["S0_HFL"] + pos(-u1) * fb_ipsi + ds * p["delta_S"]

    sw = [None] * 7
    sw[SOL] = p["S0_SOL"] * jnp.ones_like(e)
    sw[GAS] = p["S0_GAS"] * jnp.ones_like(e)
    sw[VAS] = jnp.zeros_like(e)
    sw[TA] = p["S0_TA"] + p["G_TA"] * l_ta
    sw[HAM] = p["S0_HAM"] + p["G_HAM"] * F[:, HAM]
    sw[GLU] = p["S0_GLU"] + p["G_GLU"] * F[:, GLU]
    sw[HFL] = (
        p["S0_HFL"]
        + p["k_lean"] * (s[:, S_THETA_TO] - p["theta_ref"])
        + p["G_HFL"] * pos(L[:, HFL] - p["loff_HFL"])
        - p["G_HAM_HFL"] * pos(L[:, HAM] - p["loff_HAM"])
    )
    stance_stim = jnp.stack(st, -1)
    swing_stim = jnp.stack(sw, -1)
    return jnp.where(stance[:, None], stance_stim, swing_stim)


def delayed_stimulation(
    p: dict, lines: DelayLine, sensors: jax.Array, law=fbl_stimulation, taps=None
):
    """Push the current sensors into the delay line; stimulation from the delayed copies.

    Each muscle takes the law evaluated on its own delay group's sensors (5 / 10 / 20 ms by
    default; ``taps`` overrides the delays in steps).  The law acts row by row (one row per
    leg), so it is evaluated once on the stacked delayed copies of all groups.
    Returns (stim (2, 7), new delay line).
    """
    if taps is None:  # the default delays, scaled to the line (its length is the longest)
        n, ds = lines.n_steps, ReflexSettings().delays
        taps = tuple(round(n * d / max(ds)) for d in ds)
    outs, lines = delay_taps(lines, sensors, taps)  # (3, 2, S)
    g, legs, ns = outs.shape
    stim = law(p, outs.reshape(g * legs, ns)).reshape(g, legs, -1)  # (3, 2, 7)
    stim = jnp.take_along_axis(
        stim, jnp.asarray(MUSCLE_DELAY_GROUP)[None, None, :].repeat(2, 1), axis=0
    )[0]
    return stim, lines


def packed_sensors(sens: Sensors) -> jax.Array:
    """The (2, N_SENSORS) array of the reflex laws from the shared :class:`Sensors`."""
    return sensor_array(
        sens.f_norm,
        sens.l_norm,
        sens.load,
        sens.stance,
        sens.double_support,
        sens.trunk,
        sens.dtrunk,
        sens.phi,
        sens.dphi,
        sens.theta_to,
        sens.dcom,
    )


def reflex_init(ctrl: Controller, sens: Sensors, dt: float, pack=packed_sensors) -> DelayLine:
    """State of a reflex controller: one delay line over the packed sensors (``pack``: FBL's
    by default), as long as the longest delay, filled with the start sensors."""
    return delay_init(max(delay_taps_for(ctrl.settings, dt)), pack(sens))


def with_commands(p: dict, command: dict) -> dict:
    """Parameters as the law sees them: the ``lean_offset`` command [rad] added to
    theta_ref."""
    return {**p, "theta_ref": p["theta_ref"] + command["lean_offset"]}


def reflex_step(
    ctrl: Controller,
    p: dict,
    sens: Sensors,
    lines: DelayLine,
    command: dict,
    dt,
    pack=packed_sensors,
):
    """Stimulation (2, 7) of a reflex controller: the packed sensors (``pack``: FBL's by
    default) through the delay line, the law on each group's delayed copy
    (:func:`delayed_stimulation`)."""
    taps = delay_taps_for(ctrl.settings, dt)
    return delayed_stimulation(
        with_commands(p, command), lines, pack(sens), ctrl.settings.law, taps
    )


#: Command of the reflex walkers: an offset of the trunk-lean reference theta_ref (a forward
#: lean makes Geyer's walker walk faster).
LEAN_OFFSET = Command(
    "lean_offset", 0.0, "rad", "added to theta_ref (trunk-lean reference of the hip PD)"
)


def reflex_controller(
    name: str,
    table: ParamTable,
    law: Callable,
    commands: tuple[Command, ...] = (LEAN_OFFSET,),
    delays: tuple = ReflexSettings.delays,
    description: str = "",
) -> Controller:
    """A reflex controller on the 7 Geyer muscles: ``law`` on the delayed packed sensors."""
    return Controller(
        name=name,
        table=table,
        n_muscles=N_MUSCLES,
        init=reflex_init,
        step=reflex_step,
        commands=commands,
        settings=ReflexSettings(delays=delays, law=law),
        description=description,
    )


_G = "Geyer nms_model_ControlInit.m (geyer_reference 2c, G family)"
_T25 = "thesis Table 2.5 range"
_R = "range: Geyer value +- a wide margin (Table 2.5 range illegible)"

#: The 28 FBL parameters of thesis Table 2.5, initial values from Geyer's own Simulink
#: model (the "G" gain family of geyer_reference.md 2c), expressed in the thesis's
#: normalised units (force feedback per F/F_max, length feedback per l_opt).
FBL = ParamTable(
    "fbl",
    (
        # stance-phase trunk stability (eq. 2.35-2.36)
        ParamSpec("k_bw", 1.2, 0.8, 1.4, "A/GH2010 KBW 1.2; " + _T25),
        ParamSpec("k_p1", 1.9099, 0.5, 3.0, "k_p = 1/30deg " + _G + "; " + _R, "1/rad"),
        ParamSpec("k_p2", 1.3369, 0.3, 3.0, "0.7 k_p (GLU = 0.7 HAM) " + _G + "; " + _R, "1/rad"),
        ParamSpec("k_d", 0.2, 0.0, 0.8, "k_d " + _G + "; " + _R, "s/rad"),
        ParamSpec("theta_ref", 0.1047, -0.05, 0.3, "6 deg " + _G + "; " + _R, "rad"),
        # force feedback (per F/F_max)
        ParamSpec("G_SOL", 1.2, 0.8, 1.6, _G + "; " + _T25),
        ParamSpec("G_TA_SOL", 0.4, 0.1, 0.8, _G + "; " + _T25),
        ParamSpec("G_GAS", 1.1, 0.3, 1.6, _G + "; " + _T25),
        ParamSpec("G_VAS", 1.2, 0.9, 1.8, _G + "; " + _T25),
        ParamSpec("G_HAM", 0.65, 0.2, 1.0, _G + "; " + _T25),
        ParamSpec("G_GLU", 0.5, 0.2, 0.9, _G + "; " + _T25),
        # length feedback (per l_opt)
        ParamSpec("G_TA", 1.1, 0.5, 3.0, _G + "; " + _R),
        ParamSpec("G_HFL", 0.5, 0.1, 1.5, _G + "; " + _R),
        ParamSpec("G_HAM_HFL", 4.0, 0.0, 6.0, _G + "; " + _R),
        ParamSpec("loff_TA", 0.72, 0.5, 1.0, "1 - 0.5 w " + _G + "; " + _R, "l_opt"),
        ParamSpec("loff_HFL", 0.65, 0.3, 1.0, _G + "; " + _R, "l_opt"),
        ParamSpec("loff_HAM", 0.85, 0.5, 1.0, _G + "; " + _R, "l_opt"),
        # basal activity
        ParamSpec("S0_SOL", 0.01, 0.01, 0.1, _G + "; " + _T25),
        ParamSpec("S0_TA", 0.01, 0.01, 0.1, _G + "; " + _T25),
        ParamSpec("S0_GAS", 0.01, 0.01, 0.1, _G + "; " + _T25),
        ParamSpec("S0_VAS", 0.08, 0.01, 0.2, _G + "; " + _R),
        ParamSpec("S0_HAM", 0.05, 0.01, 0.1, "S0_BAL " + _G + "; " + _T25),
        ParamSpec("S0_GLU", 0.05, 0.01, 0.1, "S0_BAL " + _G + "; " + _T25),
        ParamSpec("S0_HFL", 0.05, 0.01, 0.1, "S0_BAL " + _G + "; " + _T25),
        # others
        ParamSpec("k_lean", 1.1459, 0.0, 2.0, "2 %/deg " + _G + "; " + _T25, "1/rad"),
        ParamSpec("k_phi", 2.0, 0.0, 3.0, _G + "; " + _T25, "1/rad"),
        ParamSpec("phi_k_off", 2.9671, 2.8, float(np.pi), "170 deg " + _G + "; " + _T25, "rad"),
        ParamSpec("delta_S", 0.25, 0.0, 1.05, "K_swing " + _G + "; " + _T25),
    ),
)


def lift_with_extras(
    vec_fbl, neutral: dict, extras: dict | None, label: str, base=None, base_label: str = "FBL"
) -> np.ndarray:
    """A ``base`` vector (default FBL's 28) followed by extra parameters: ``neutral``'s names
    in order, each the value ``extras`` gives, else its neutral one (the lift of FBL+,
    ``fbl_ankle`` and, from FBL+, ``fblplus_bal``).

    Raises:
      ValueError: ``vec_fbl`` is not ``base.size`` values (the message names ``base_label``);
      KeyError: an unknown extra (named, with ``label``, the model's name).
    """
    base = FBL if base is None else base
    vec_fbl = np.asarray(vec_fbl, dtype=float)
    if vec_fbl.shape != (base.size,):
        raise ValueError(
            f"expected an {base_label} vector of {base.size} values, got {vec_fbl.shape}"
        )
    unknown = sorted(set(extras or {}) - set(neutral))
    if unknown:
        raise KeyError(f"unknown {label} extra parameter(s): {', '.join(unknown)}")
    values = {**neutral, **(extras or {})}
    return np.concatenate([vec_fbl, [float(values[n]) for n in neutral]])


#: The FBL controller (thesis 2.1.2.3): Table 2.4's law, 5/10/20 ms delays.
FBL_CONTROLLER = reflex_controller(
    "fbl", FBL, fbl_stimulation, description="Geyer-Herr reflex walker (thesis 2.1.2, Table 2.4)"
)
