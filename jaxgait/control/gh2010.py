"""Geyer & Herr 2010 as Geyer's own Simulink model has it (geyer_reference.md section 2b).

The FBL law of thesis Table 2.4 (:func:`jaxgait.control.fbl.fbl_stimulation`) differs from
the stance block of Geyer's ``nms_model.mdl`` (the "G" source of geyer_reference.md) in the
trunk-balance muscles only; :func:`gh2010_stimulation` is that block:

  u   = k_p1 (theta - theta_ref) + k_d dtheta                       (5 ms delayed)
  HAM = clip((S0_HAM + [u]+) L_ipsi, 0, 1)       the prestimulation is gated by the load too
  HFL = clip((S0_HFL + [-u]+) L_ipsi, 0, 1) + DS delta_S
  GLU = 0.7 HAM - 0.7 DS delta_S                  one Gain block of 0.7, applied to HAM's output

with L = k_bw x the model's leg-load signal (Geyer: the thigh pressure sheet's compression
over DeltaThRef, k_bw = 1; :func:`jaxgait.control.gait.thigh_sheet_load`).  Table 2.4 has
instead HAM = S0 + [u_1]+ Fb, GLU = S0 + [u_2]+ Fb - DS delta_S with its own k_p2 and
ungated S0.  So k_p2 and S0_GLU of the FBL table have no effect here.  Everything else (SOL,
TA, GAS, VAS in stance, the swing laws, the delays) is FBL's, which already follows Geyer.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxgait.control.fbl import (
    FBL,
    GLU,
    HAM,
    HFL,
    S_DS,
    S_DTRUNK,
    S_LOAD,
    S_STANCE,
    S_TRUNK,
    fbl_stimulation,
    reflex_controller,
)

#: GLU's stance stimulation as a fraction of HAM's (Geyer's Gain block; Thatte's ``Kglu``).
GLU_OF_HAM = 0.7


def gh2010_stimulation(p: dict, s: jax.Array) -> jax.Array:
    """Stimulation (2, 7) from one (delayed) sensor array: Table 2.4 with the stance
    trunk-balance block of Geyer's model (module docstring)."""
    stim = fbl_stimulation(p, s)
    stance = s[:, S_STANCE] > 0.5
    ds = s[:, S_DS]
    u = p["k_p1"] * (s[:, S_TRUNK] - p["theta_ref"]) + p["k_d"] * s[:, S_DTRUNK]
    load = p["k_bw"] * s[:, S_LOAD]
    ham = jnp.clip((p["S0_HAM"] + jnp.maximum(u, 0.0)) * load, 0.0, 1.0)
    hfl = jnp.clip((p["S0_HFL"] + jnp.maximum(-u, 0.0)) * load, 0.0, 1.0) + ds * p["delta_S"]
    glu = GLU_OF_HAM * ham - GLU_OF_HAM * ds * p["delta_S"]
    st = stim.at[:, HAM].set(ham).at[:, HFL].set(hfl).at[:, GLU].set(glu)
    return jnp.where(stance[:, None], st, stim)


#: The FBL table's initial values (Geyer's "G" gains) with k_bw = 1: on the thigh-sheet
#: signal that is Geyer's own scaling, 1 / DeltaThRef on the compression.
GH2010_PARAMS = {**dict(zip(FBL.names, FBL.init.tolist(), strict=True)), "k_bw": 1.0}

#: The reflex controller with Geyer's stance balance block (5/10/20 ms delays, FBL's table).
GH2010_CONTROLLER = reflex_controller(
    "fbl_gh2010",
    FBL,
    gh2010_stimulation,
    description=(
        "Geyer-Herr reflex walker as Geyer's Simulink model: its stance balance block and the "
        "thigh pressure-sheet load signal"
    ),
)
