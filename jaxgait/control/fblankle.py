"""FBL with a human-like ankle: a separate swing drive of the plantarflexors and a damped
foot lowering after heel strike (model ``fbl_ankle``).

Every optimised FBL gait lands on a plantarflexed foot: the plantarflexors' basal
stimulation S0_SOL, S0_GAS (0.04-0.09 in the shipped presets, Geyer's 0.01) acts in swing
too, where it holds the foot at about -9 deg against TA (Winter: about 0 deg).  Lowering it
alone makes the foot land on its heel, and the forefoot then slaps the ground (3.7 BW
instead of 1.8 BW, ``experiments/humanlike/README.md``): FBL has no rule for what a human's
TA does after heel strike, lowering the foot under control while it lengthens.

This law keeps every rule of FBL (:func:`jaxgait.control.fbl.fbl_stimulation`, thesis
Table 2.4) and changes two (three parameters, appended to FBL's 28):

1. **Swing plantarflexor drive.**  In swing ``SOL = k_sw_SOL S0_SOL`` and
   ``GAS = k_sw_GAS S0_GAS`` (FBL: k = 1), so the stance basal drive and the swing foot
   angle are chosen apart.  k in [0, 1] [-].
2. **Foot-lowering damping.**  In stance, outside double support (DS = 0: not the trailing
   leg's push-off),

       TA += G_TA_v [d phi_a / dt]+

   where phi_a is the Geyer-Herr ankle angle (90 deg with the foot at right angles to the
   shank, **larger in plantarflexion**, :mod:`jaxgait.body.joints`), so [d phi_a/dt]+ is the
   plantarflexion rate [rad/s]: TA's stretch velocity, the Ia-like velocity feedback that
   brakes the foot as it rolls down after heel strike.  G_TA_v in [0, 1] [s/rad].  It acts
   on the ankle group's delayed sensors (20 ms) like TA's other feedback.

The ankle angle and rate are not in FBL's packed sensors, so this controller packs two
more columns (:data:`S_ANKLE`, :data:`S_DANKLE`) after FBL's :data:`~jaxgait.control.fbl.N_SENSORS`;
FBL's law reads its own columns and ignores them.

**Reduction to FBL.**  With k_sw_SOL = k_sw_GAS = 1 and G_TA_v = 0 (the table's initial
values, :data:`NEUTRAL`) the law is FBL's bit for bit evaluated op by op (``jnp.where``
selects FBL's values), so :func:`lift_fbl_ankle` turns any FBL parameter set into one with
the same gait, the start of a search for a human-like ankle.  Compiled into a rollout, XLA
may fuse the wider graph otherwise than FBL's: the rollouts then agree to float32 rounding,
not bit for bit (unlike FBL+, whose sensors are FBL's).

The rules are this project's (not from the thesis or Geyer & Herr 2010); their ranges are
chosen wide: k spans the swing drive from none to FBL's, and G_TA_v = 1 s/rad gives full
TA stimulation at a plantarflexion rate of 1 rad/s (the foot slap of ``fbl_walk`` reaches
several rad/s).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.control.fbl import (
    FBL,
    GAS,
    N_SENSORS,
    S_DS,
    S_STANCE,
    SOL,
    TA,
    fbl_stimulation,
    lift_with_extras,
    packed_sensors,
    reflex_controller,
    reflex_init,
    reflex_step,
)
from jaxgait.control.interface import Sensors
from jaxgait.core.params import ParamSpec, ParamTable

#: Columns packed after FBL's sensors: Geyer-Herr ankle angle phi_a [rad] and its rate
#: [rad/s] (plantarflexion +).
S_ANKLE = N_SENSORS
S_DANKLE = N_SENSORS + 1
N_SENSORS_ANKLE = N_SENSORS + 2

_N = "init = neutral (the law reduces to FBL)"
_R = "this project's rule (jaxgait.control.fblankle)"

#: The three extra parameters; initial values are the neutral setting.
EXTRA_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("k_sw_SOL", 1.0, 0.0, 1.0, "swing SOL = k_sw_SOL S0_SOL; " + _R + "; " + _N),
    ParamSpec("k_sw_GAS", 1.0, 0.0, 1.0, "swing GAS = k_sw_GAS S0_GAS; " + _R + "; " + _N),
    ParamSpec(
        "G_TA_v",
        0.0,
        0.0,
        1.0,
        "stance TA += G_TA_v [dphi_a/dt]+ outside double support; " + _R + "; " + _N,
        "s/rad",
    ),
)

#: Parameter table: FBL's 28 (thesis Table 2.5), then the 3 extras.
FBL_ANKLE = ParamTable("fbl_ankle", FBL.specs + EXTRA_SPECS)

#: Names of the extra parameters, in table order.
EXTRA_NAMES: tuple[str, ...] = tuple(s.name for s in EXTRA_SPECS)

#: Neutral extra values: the law is FBL's.
NEUTRAL: dict[str, float] = {s.name: s.init for s in EXTRA_SPECS}


def lift_fbl_ankle(vec_fbl, extras: dict | None = None) -> np.ndarray:
    """``fbl_ankle`` parameter vector (31,) from an FBL vector (28,) and extra values.

    Args:
      vec_fbl: (28,) FBL parameters in :data:`jaxgait.control.fbl.FBL` order.
      extras: name -> value for some of :data:`EXTRA_NAMES`; the rest take :data:`NEUTRAL`.
    """
    return lift_with_extras(vec_fbl, NEUTRAL, extras, "fbl_ankle")


def fbl_ankle_stimulation(p: dict, s: jax.Array) -> jax.Array:
    """Stimulation (rows, 7) from delayed sensor rows s (rows, N_SENSORS_ANKLE).

    FBL's law (thesis Table 2.4) with the swing SOL and GAS drive scaled by k_sw and the
    stance TA foot-lowering term G_TA_v [dphi_a/dt]+ (1 - DS) added (module docstring).
    """
    stim = fbl_stimulation(p, s)
    stance = s[:, S_STANCE] > 0.5
    sol = jnp.where(stance, stim[:, SOL], p["k_sw_SOL"] * p["S0_SOL"])
    gas = jnp.where(stance, stim[:, GAS], p["k_sw_GAS"] * p["S0_GAS"])
    lower = p["G_TA_v"] * jnp.maximum(s[:, S_DANKLE], 0.0) * (1.0 - s[:, S_DS])
    ta = jnp.where(stance, stim[:, TA] + lower, stim[:, TA])
    return stim.at[:, SOL].set(sol).at[:, GAS].set(gas).at[:, TA].set(ta)


def packed_sensors_ankle(sens: Sensors) -> jax.Array:
    """FBL's packed sensors (2, N_SENSORS) with the ankle angle and rate appended."""
    return jnp.concatenate([packed_sensors(sens), sens.phi[:, 2:3], sens.dphi[:, 2:3]], axis=1)


#: The ``fbl_ankle`` controller: FBL's delays, command and rules plus the two ankle rules.
FBL_ANKLE_CONTROLLER = dataclasses.replace(
    reflex_controller(
        "fbl_ankle",
        FBL_ANKLE,
        fbl_ankle_stimulation,
        description="FBL with a swing plantarflexor drive and TA foot-lowering damping",
    ),
    init=functools.partial(reflex_init, pack=packed_sensors_ankle),
    step=functools.partial(reflex_step, pack=packed_sensors_ankle),
)
