"""The FBL reflex controller (Geyer & Herr 2010; thesis 2.1.2.3, Tables 2.4-2.5).

Sensors (thesis 2.1.1.2) are packed per leg into one vector so that the neural delays are
three ring buffers (5 ms hip, 10 ms knee, 20 ms ankle muscles); the stimulation law is a
pure function of a delayed sensor vector and the parameter dict, evaluated once per delay
group, and each muscle takes the result of its own group.

Phases per leg: stance (filtered ground load above a threshold, with hysteresis), swing, and
stance end (trailing leg in double support: both legs loaded and the other leg touched down
last).

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

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxgait.control.delay import DelayLine, delay_init, delay_taps, steps_for

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
class ReflexConfig:
    """Fixed (non-optimised) controller settings."""

    delays: tuple = (0.005, 0.010, 0.020)  # s, Geyer & Herr 2010
    ground_tau: float = 100.0  # 1/s, eq. 2.34 sensor filter rate
    stance_on: float = 0.05  # filtered load / (M g) above which a swing leg enters stance
    stance_off: float = 0.01  # ... below which a stance leg enters swing (hysteresis)


@struct.dataclass
class ReflexState:
    """Controller memory.

    Attributes:
      load: (2,) filtered ground load per leg / (M g) (eq. 2.34).
      stance: (2,) bool, leg in stance at the previous step.
      td_time: (2,) time of each leg's last touchdown [s].
      theta_to: (2,) trunk pitch at each leg's last take-off [rad].
      lines: one delay line over the (2, N_SENSORS) sensor array, as long as the longest
        delay, read at each group's delay (:func:`jaxgait.control.delay.delay_taps`).
    """

    load: jax.Array
    stance: jax.Array
    td_time: jax.Array
    theta_to: jax.Array
    lines: DelayLine


def init_reflex(
    cfg: ReflexConfig, dt: float, sensors0: jax.Array, load0, stance0, theta0
) -> ReflexState:
    lines = delay_init(max(steps_for(d, dt) for d in cfg.delays), sensors0)
    stance0 = jnp.asarray(stance0, bool)
    return ReflexState(
        load=jnp.asarray(load0, sensors0.dtype),
        stance=stance0,
        td_time=jnp.where(stance0, -jnp.asarray([0.0, 0.3], sensors0.dtype), -1.0),
        theta_to=jnp.full((2,), theta0, sensors0.dtype),
        lines=lines,
    )


def delay_taps_for(cfg: ReflexConfig, dt: float) -> tuple[int, ...]:
    """The delay of each muscle group in whole steps of dt (static)."""
    return tuple(steps_for(d, dt) for d in cfg.delays)


def update_phase(cfg: ReflexConfig, st: ReflexState, grf_n, mg, t, theta, dt):
    """Filter the ground load (eq. 2.34) and update stance, touchdown times, theta_TO.

    Returns (new state without delay lines changed, stance, touchdown (2,) bool, DS (2,)).
    """
    load = st.load + dt * cfg.ground_tau * (grf_n / mg - st.load)
    thresh = jnp.where(st.stance, cfg.stance_off, cfg.stance_on)
    stance = load > thresh
    touchdown = stance & ~st.stance
    takeoff = ~stance & st.stance
    td_time = jnp.where(touchdown, t, st.td_time)
    theta_to = jnp.where(takeoff, theta, st.theta_to)
    other = td_time[::-1]
    ds = stance & stance[::-1] & (other > td_time)
    new = st.replace(load=load, stance=stance, td_time=td_time, theta_to=theta_to)
    return new, stance, touchdown, ds


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
    p: dict, st: ReflexState, sensors: jax.Array, law=fbl_stimulation, taps=None
):
    """Push the current sensors into the delay line; stimulation from the delayed copies.

    Each muscle takes the law evaluated on its own delay group's sensors (5 / 10 / 20 ms by
    default; ``taps`` overrides the delays in steps).  The law acts row by row (one row per
    leg), so it is evaluated once on the stacked delayed copies of all groups.
    Returns (stim (2, 7), new delay line).
    """
    if taps is None:  # the default delays, scaled to the line (its length is the longest)
        n, ds = st.lines.n_steps, ReflexConfig().delays
        taps = tuple(round(n * d / max(ds)) for d in ds)
    outs, lines = delay_taps(st.lines, sensors, taps)  # (3, 2, S)
    g, legs, ns = outs.shape
    stim = law(p, outs.reshape(g * legs, ns)).reshape(g, legs, -1)  # (3, 2, 7)
    stim = jnp.take_along_axis(
        stim, jnp.asarray(MUSCLE_DELAY_GROUP)[None, None, :].repeat(2, 1), axis=0
    )[0]
    return stim, lines
