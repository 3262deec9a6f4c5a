"""FBL+ with SIMBICON foot placement (model ``fblplus_bal``).

FBL+ (:mod:`jaxgait.control.fblplus`, thesis 2.1.3) pulls the swing hip towards a fixed
target delta_h^ref before landing.  Wang et al. (2012, section 4.3) move that target with the
balance feedback of SIMBICON (Yin et al. 2007), theta_h = theta_h0 + c_d d + c_v v, where d
and v are the centre of mass's horizontal offset [m] and velocity [m/s] relative to the
stance (other) leg's ankle: a body that is ahead of its support, or moving fast over it,
places the swing foot further forward.  FBL+ has no such term, and its running gaits found
under body-weight support fall once the support is gone (``experiments/running``).  This law
is FBL+'s with the swing-end hip target moved the same way::

    delta_h^target = delta_h^ref - c_d d - c_v v

(delta_h = phi_h - pi is negative in flexion, so a positive offset d or velocity v flexes the
target hip further: the sign of Wang's law in FBL+'s convention).  d and v are packed as two
more sensor columns after FBL's (:data:`S_BAL_D`, :data:`S_BAL_V`), read through the hip
muscles' 5 ms delay like the rest of the swing-end rule.  c_d in [0, 2] rad/m and c_v in
[0, 1] rad s/m, Wang's ranges (:mod:`jaxgait.control.wang_params`).

**Reduction to FBL+.**  With c_d = c_v = 0 (the table's initial values, :data:`NEUTRAL`) the
offset is zero and the law is FBL+'s (:func:`lift_fblplus` turns any FBL+ parameter set
into one with the same gait, to float32 rounding: the wider sensor array may be fused
otherwise by XLA).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.control.fbl import N_SENSORS, lift_with_extras, packed_sensors, reflex_init
from jaxgait.control.fblplus import (
    FBLPLUS,
    FBLPLUS_CONTROLLER,
    fblplus_step,
    fblplus_stimulation,
)
from jaxgait.control.interface import Sensors, com_over_other_ankle
from jaxgait.core.params import ParamSpec, ParamTable, widened

#: Columns packed after FBL's sensors: x_CoM - x_ankle of the other leg [m] and
#: vx_CoM - vx_ankle of the other leg [m/s] (Wang's d and v).
S_BAL_D = N_SENSORS
S_BAL_V = N_SENSORS + 1
N_SENSORS_BAL = N_SENSORS + 2

_W = "SIMBICON gain (Yin et al. 2007) as in Wang 2012 section 4.3; range Wang's"
_N = "init = neutral (the law reduces to FBL+)"

#: The two extra parameters; initial values are the neutral setting.
EXTRA_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("c_d", 0.0, 0.0, 2.0, "swing-end hip target -= c_d d; " + _W + "; " + _N, "rad/m"),
    ParamSpec("c_v", 0.0, 0.0, 1.0, "swing-end hip target -= c_v v; " + _W + "; " + _N, "rad s/m"),
)

#: Parameter table: FBL+'s 38 (thesis Tables 2.5 and 2.6), then c_d and c_v.
FBLPLUS_BAL = ParamTable("fblplus_bal", FBLPLUS.specs + EXTRA_SPECS)

#: Names of the extra parameters, in table order.
EXTRA_NAMES: tuple[str, ...] = tuple(s.name for s in EXTRA_SPECS)

#: Neutral extra values: the law is FBL+'s.
NEUTRAL: dict[str, float] = {s.name: s.init for s in EXTRA_SPECS}


def lift_fblplus(vec_plus, extras: dict | None = None) -> np.ndarray:
    """``fblplus_bal`` parameter vector (40,) from an FBL+ vector (38,) and extra values.

    Raises:
      ValueError: ``vec_plus`` is not 38 values; KeyError: an unknown extra.
    """
    return lift_with_extras(vec_plus, NEUTRAL, extras, "fblplus_bal", FBLPLUS, "FBL+")


def balance_offset(p: dict, s: jax.Array) -> jax.Array:
    """-(c_d d + c_v v) (rows,) [rad]: the shift of the swing-end hip target (flexion < 0)."""
    return -(p["c_d"] * s[:, S_BAL_D] + p["c_v"] * s[:, S_BAL_V])


def fblplus_bal_stimulation(p: dict, s: jax.Array) -> jax.Array:
    """Stimulation (rows, 7) from delayed sensor rows s (rows, N_SENSORS_BAL): FBL+'s law
    (:func:`jaxgait.control.fblplus.fblplus_stimulation`) with each row's swing-end hip
    target moved by :func:`balance_offset`."""
    q = {**p, "delta_hip_ref": p["delta_hip_ref"] + balance_offset(p, s)}
    return fblplus_stimulation(q, s)


def packed_sensors_bal(sens: Sensors) -> jax.Array:
    """FBL's packed sensors (2, N_SENSORS) with Wang's d and v appended: the CoM's horizontal
    offset [m] and velocity [m/s] relative to the other leg's ankle."""
    d, v = com_over_other_ankle(sens)
    return jnp.concatenate([packed_sensors(sens), d[:, None], v[:, None]], axis=1)


#: The ``fblplus_bal`` controller: FBL+'s delays, commands and rules, the hip target moved by
#: SIMBICON's feedback.
FBLPLUS_BAL_CONTROLLER = dataclasses.replace(
    FBLPLUS_CONTROLLER,
    name="fblplus_bal",
    table=FBLPLUS_BAL,
    settings=dataclasses.replace(FBLPLUS_CONTROLLER.settings, law=fblplus_bal_stimulation),
    description="FBL+ with SIMBICON foot placement on the swing-end hip target (Wang 2012 4.3)",
    init=functools.partial(reflex_init, pack=packed_sensors_bal),
    step=functools.partial(fblplus_step, pack=packed_sensors_bal),
)

#: Ranges of :data:`FBLPLUS_BAL_RUN`, widened where the supported runners sat at a bound of
#: Table 2.5 (``experiments/running/fblplus_bal/bws_0.02``: G_GAS 1.58 of 1.6, k_lean 1.95 of
#: 2, theta_ref -0.041 of -0.05 rad).
RUN_RANGES: dict[str, tuple[float, float]] = {
    "G_SOL": (0.8, 3.2),  # Wang 2012 doubles Geyer's plantarflexor gains for running
    "G_GAS": (0.3, 3.2),
    "k_lean": (0.0, 4.0),
    "theta_ref": (-0.2, 0.3),
}

#: :data:`FBLPLUS_BAL` with :data:`RUN_RANGES` (model ``fblplus_bal_run``): the same names in
#: the same order, so an ``fblplus_bal`` vector is an ``fblplus_bal_run`` vector.
FBLPLUS_BAL_RUN = widened(
    FBLPLUS_BAL, "fblplus_bal_run", RUN_RANGES, "; range widened for running (fblplus_bal_run)"
)

#: The same controller with the running searches' box.
FBLPLUS_BAL_RUN_CONTROLLER = dataclasses.replace(
    FBLPLUS_BAL_CONTROLLER,
    name="fblplus_bal_run",
    table=FBLPLUS_BAL_RUN,
    description="fblplus_bal with the running searches' wider ranges (plantarflexor gains, lean)",
)

#: Ranges of the speed-regulated runner (model ``fblplus_bal_run_sr``) widened again where
#: the regulated runner sat at a bound (``experiments/running/speed_lean``: S0_HFL 0.098 of
#: 0.1, S0_VAS 0.19 of 0.2, G_TA 2.9 of 3): a faster swing needs more hip-flexor drive.
SR_RANGES: dict[str, tuple[float, float]] = {
    "S0_HFL": (0.01, 0.3),
    "S0_VAS": (0.01, 0.4),
    "G_TA": (0.5, 5.0),
}

#: :data:`FBLPLUS_BAL_RUN` with :data:`SR_RANGES` (the base of ``fblplus_bal_run_sr``).
FBLPLUS_BAL_RUN_WIDE = widened(
    FBLPLUS_BAL_RUN, "fblplus_bal_run_wide", SR_RANGES, "; range widened for the regulated runner"
)
