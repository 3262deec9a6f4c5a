"""Gait-phase detection shared by every controller and by the logs (thesis eq. 2.34-2.35).

Per leg: the ground load filtered at rate ``ground_tau`` (eq. 2.34), stance with hysteresis
(enter above ``stance_on``, leave below ``stance_off``, both in body weights), touchdown and
take-off instants, the trunk pitch at the last take-off (read by FBL's swing lean term) and
the trailing leg of a double support (stance end: both legs loaded, the other leg touched
down last).

The leg-load signal the reflexes read is that filtered load by default (``load_signal =
"grf"``: F_z / (M g), which FBL scales by k_bw).  ``"thigh_sheet"`` is the signal of Geyer's
own Simulink model instead (geyer_reference.md section 3c): a stiff "pressure sheet" splits
each thigh 0.1 m below the hip, and the reflexes read its compression over the compression
under the HAT's weight, Delta x / DeltaThRef = F_sheet / (m_HAT g) (k_pressure = m_HAT g /
DeltaThRef).  :func:`thigh_sheet_load` takes the sheet quasi-static (its spring, k = 105 kN/m
damped at v_max 0.5 m/s, settles within milliseconds): the force the sheet carries is the
leg's ground reaction plus the weight of the leg below the sheet, along the thigh, and the
inertia of that part of the leg is left out.  Stance detection stays on the filtered GRF.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
from flax import struct


@dataclass(frozen=True)
class GaitConfig:
    """Settings of the phase detection (not optimised)."""

    ground_tau: float = 100.0  # 1/s, eq. 2.34 sensor filter rate
    stance_on: float = 0.05  # filtered load / (M g) above which a swing leg enters stance
    stance_off: float = 0.01  # ... below which a stance leg enters swing (hysteresis)
    #: the reflexes' leg-load signal: "grf" (the filtered F_z / (M g)) or "thigh_sheet"
    #: (Geyer's thigh pressure sheet, :func:`thigh_sheet_load`, in HAT weights)
    load_signal: str = "grf"
    sheet_below_hip: float = 0.1  # m, position of the sheet on the thigh (GH ThPos 4/5)

    def __post_init__(self):
        if self.load_signal not in LOAD_SIGNALS:
            raise ValueError(
                f"unknown load_signal {self.load_signal!r}; valid: {', '.join(LOAD_SIGNALS)}"
            )


#: Leg-load signals the reflexes can read (:attr:`GaitConfig.load_signal`).
LOAD_SIGNALS = ("grf", "thigh_sheet")


def thigh_sheet_load(grf, thigh_angle, m_below, m_hat, g: float = 9.81):
    """Geyer's thigh pressure-sheet leg-load signal, quasi-static (geyer_reference.md 3c).

    Args:
      grf: (2, 2) ground reaction (x, z) on each leg [N].
      thigh_angle: (2,) pitch of each thigh in the world [rad] (0: hanging straight down;
        the thigh's axis from knee to hip is (sin a, cos a)).
      m_below: mass of the leg below the sheet [kg] (lower thigh, shank, foot).
      m_hat: mass of the head-arms-trunk [kg]; g: gravity [m/s^2].

    Returns:
      (2,) [F_sheet]+ / (m_HAT g): the sheet's compression over its compression under the
      HAT's weight, where F_sheet = (GRF - m_below g e_z) . u_thigh is the force the sheet
      carries along the thigh when the leg below it is in equilibrium (0 in tension).
    """
    u = jnp.stack([jnp.sin(thigh_angle), jnp.cos(thigh_angle)], -1)
    f = jnp.sum(grf * u, -1) - m_below * g * u[:, 1]
    return jnp.maximum(f, 0.0) / (m_hat * g)


@struct.dataclass
class GaitState:
    """Phase memory.

    Attributes:
      load: (2,) filtered ground load per leg / (M g) (eq. 2.34).
      stance: (2,) bool, leg in stance at the previous step.
      td_time: (2,) time of each leg's last touchdown [s].
      theta_to: (2,) trunk pitch at each leg's last take-off [rad].
    """

    load: jax.Array
    stance: jax.Array
    td_time: jax.Array
    theta_to: jax.Array


def init_gait(load0, stance0, theta0, dtype) -> GaitState:
    """Start state: the given loads and stance flags; the stance legs touched down 0 and
    0.3 s before the start (so the right leg, touched down last, is not the trailing one)."""
    stance0 = jnp.asarray(stance0, bool)
    return GaitState(
        load=jnp.asarray(load0, dtype),
        stance=stance0,
        td_time=jnp.where(stance0, -jnp.asarray([0.0, 0.3], dtype), -1.0),
        theta_to=jnp.full((2,), theta0, dtype),
    )


def update_gait(cfg: GaitConfig, st: GaitState, grf_n, mg, t, theta, dt):
    """Filter the ground load (eq. 2.34) and update stance, touchdown times, theta_TO.

    Args:
      grf_n: (2,) vertical ground force per leg [N]; mg: body weight [N]; t: time [s];
      theta: trunk pitch [rad]; dt: step [s].
    Returns:
      (new state, stance (2,) bool, touchdown (2,) bool, double support (2,) bool).
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
    new = GaitState(load=load, stance=stance, td_time=td_time, theta_to=theta_to)
    return new, stance, touchdown, ds
