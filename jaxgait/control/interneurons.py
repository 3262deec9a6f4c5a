"""The FBL reflex circuit as sensory interneurons (thesis 6.1, Table 6.1, Fig. 6.1).

Every term of FBL's stimulation law (Table 2.4 and its swing rules, :mod:`jaxgait.control.fbl`)
is one sensory interneuron IN_SEN per leg: it reads one sensor (or two: the ground-and-trunk
feedback reads the ipsilateral load and the trunk PD), is switched on and off by a
state-dependent interneuron IN_SD (stance, swing, stance end; the knee over-extension term is
its own gate: it is zero unless the knee extends past phi_k_off) and projects to one
motoneuron with an excitatory (+1) or inhibitory (-1) synapse.

:data:`IN_SEN` lists them in a fixed order (15 per leg).  It is Table 6.1 plus the TA <- SOL
force term that the table omits (Geyer's TA is inhibited by the SOL force in stance).  The
thesis counts 13 replaceable IN_SEN per leg: the muscle (MFF, MLF) and ground (GIF, GCF)
ones; the trunk-lean (TL) and over-extension (OPF) terms stay sensory in every model
(``replaceable=False``).  Table 6.1 marks OPF as active in swing; FBL applies it in stance
(VAS is silent in swing), which is what is kept here.

Not interneurons (as in the thesis's own code): the basal stimulations S0 and Geyer's swing
initiation in double support (GLU - delta_S, HFL + delta_S), which act on the motoneuron's
output directly (:func:`direct_terms`).

Units: every IN_SEN output is in units of muscle stimulation [-] (the gain times the
normalised sensor).  The magnitudes here are the unsigned outputs; the sign is the synapse's.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.control.fbl import (
    GAS,
    GLU,
    HAM,
    HFL,
    N_MUSCLES,
    S_DKNEE,
    S_DS,
    S_DTRUNK,
    S_F,
    S_KNEE,
    S_L,
    S_LOAD,
    S_LOAD_C,
    S_STANCE,
    S_THETA_TO,
    S_TRUNK,
    SOL,
    TA,
    VAS,
)

GATES = ("stance", "swing", "cycle", "stance_end")
#: Sensor families (thesis Table 6.1): muscle force / length feedback, ground-and-trunk
#: (ipsilateral foot and trunk), contralateral ground, trunk lean, over-extension prevention.
FAMILIES = ("MFF", "MLF", "GIF", "GCF", "TL", "OPF")
MUSCLE_NAMES = ("HFL", "GLU", "HAM", "VAS", "GAS", "SOL", "TA")


@dataclass(frozen=True)
class Interneuron:
    """One sensory interneuron (per leg).

    Attributes:
      name: thesis-style label, "TARGET<-SOURCE FAMILY PHASE".
      target: index of the motoneuron (muscle) it projects to.
      sign: +1 excitatory, -1 inhibitory synapse.
      family: one of :data:`FAMILIES`.
      gate: one of :data:`GATES` (the IN_SD that enables it).
      replaceable: counted among the thesis's 13 IN_SEN that FBL- and 3FBL may replace.
    """

    name: str
    target: int
    sign: int
    family: str
    gate: str
    replaceable: bool = True

    @property
    def muscle_feedback(self) -> bool:
        return self.family in ("MFF", "MLF")


_I = Interneuron
#: The sensory interneurons of FBL (thesis Table 6.1 + TA <- SOL), in the order of every
#: (..., K) interneuron array.
IN_SEN: tuple[Interneuron, ...] = (
    _I("SOL<-SOL MFF ST", SOL, +1, "MFF", "stance"),
    _I("TA<-TA MLF CY", TA, +1, "MLF", "cycle"),
    _I("TA<-SOL MFF ST", TA, -1, "MFF", "stance"),
    _I("GAS<-GAS MFF ST", GAS, +1, "MFF", "stance"),
    _I("VAS<-VAS MFF ST", VAS, +1, "MFF", "stance"),
    _I("VAS<-GCF STend", VAS, -1, "GCF", "stance_end"),
    _I("HAM<-GIF ST", HAM, +1, "GIF", "stance"),
    _I("GLU<-GIF ST", GLU, +1, "GIF", "stance"),
    _I("HF<-GIF ST", HFL, +1, "GIF", "stance"),
    _I("HAM<-HAM MFF SW", HAM, +1, "MFF", "swing"),
    _I("GLU<-GLU MFF SW", GLU, +1, "MFF", "swing"),
    _I("HF<-HF MLF SW", HFL, +1, "MLF", "swing"),
    _I("HF<-HAM MLF SW", HFL, -1, "MLF", "swing"),
    _I("HF<-TL SW", HFL, +1, "TL", "swing", replaceable=False),
    _I("VAS<-KNEE OPF ST", VAS, -1, "OPF", "stance", replaceable=False),
)
N_IN = len(IN_SEN)
IN_NAMES: tuple[str, ...] = tuple(i.name for i in IN_SEN)
#: (K,) motoneuron index and synapse sign of each IN_SEN.
TARGETS = np.array([i.target for i in IN_SEN])
SIGNS = np.array([i.sign for i in IN_SEN], np.float64)
#: (K, 7) synapse matrix IN_SEN -> MN.
SYNAPSES = np.zeros((N_IN, N_MUSCLES))
SYNAPSES[np.arange(N_IN), TARGETS] = SIGNS


def index(name: str) -> int:
    """Position of an IN_SEN in :data:`IN_SEN`; ``KeyError`` listing the names."""
    try:
        return IN_NAMES.index(name)
    except ValueError:
        raise KeyError(
            f"unknown sensory interneuron {name!r}; known: {', '.join(IN_NAMES)}"
        ) from None


def insen_inputs(p: dict, s: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Ungated IN_SEN outputs and their IN_SD gates from a (delayed) sensor array.

    Args:
      p: FBL parameters (name -> value, :data:`jaxgait.control.fbl.FBL`).
      s: (rows, N_SENSORS) packed sensors (:func:`jaxgait.control.fbl.sensor_array`).
    Returns:
      (x (rows, K), gate (rows, K) in {0, 1}): the unsigned outputs in stimulation units
      (Table 2.4's terms) and whether each IN_SEN is enabled.
    """
    pos = lambda v: jnp.maximum(v, 0.0)
    F, L = s[:, S_F], s[:, S_L]
    stance = (s[:, S_STANCE] > 0.5).astype(s.dtype)
    swing = 1.0 - stance
    ds = s[:, S_DS]
    e = s[:, S_TRUNK] - p["theta_ref"]
    u1 = p["k_p1"] * e + p["k_d"] * s[:, S_DTRUNK]
    u2 = p["k_p2"] * e + p["k_d"] * s[:, S_DTRUNK]
    fb = p["k_bw"] * s[:, S_LOAD]
    over = s[:, S_KNEE] - p["phi_k_off"]
    dphi_k = jnp.where((over > 0) & (s[:, S_DKNEE] > 0), over, 0.0)
    x = [
        p["G_SOL"] * F[:, SOL],
        p["G_TA"] * pos(L[:, TA] - p["loff_TA"]),
        p["G_TA_SOL"] * F[:, SOL],
        p["G_GAS"] * F[:, GAS],
        p["G_VAS"] * F[:, VAS],
        p["k_bw"] * s[:, S_LOAD_C],
        pos(u1) * fb,
        pos(u2) * fb,
        pos(-u1) * fb,
        p["G_HAM"] * F[:, HAM],
        p["G_GLU"] * F[:, GLU],
        p["G_HFL"] * pos(L[:, HFL] - p["loff_HFL"]),
        p["G_HAM_HFL"] * pos(L[:, HAM] - p["loff_HAM"]),
        p["k_lean"] * (s[:, S_THETA_TO] - p["theta_ref"]),
        p["k_phi"] * dphi_k,
    ]
    by_gate = {"stance": stance, "swing": swing, "cycle": jnp.ones_like(stance), "stance_end": ds}
    gate = [by_gate[i.gate] for i in IN_SEN]
    return jnp.stack(x, -1), jnp.stack(gate, -1)


def direct_terms(p: dict, s: jax.Array) -> jax.Array:
    """(rows, 7) what FBL adds outside the interneurons: the basal stimulations S0 (VAS's
    only in stance: FBL's VAS is silent in swing) and the swing initiation in double
    support, GLU - delta_S and HFL + delta_S (thesis Table 2.4)."""
    stance = (s[:, S_STANCE] > 0.5).astype(s.dtype)
    ds = s[:, S_DS]
    cols = []
    for m, name in enumerate(MUSCLE_NAMES):
        s0 = p[f"S0_{name}"] * (stance if m == VAS else jnp.ones_like(stance))
        if m == GLU:
            s0 = s0 - ds * p["delta_S"]
        elif m == HFL:
            s0 = s0 + ds * p["delta_S"]
        cols.append(s0)
    return jnp.stack(cols, -1)


def motoneurons(direct: jax.Array, inputs: jax.Array) -> jax.Array:
    """(rows, 7) stimulation: the direct terms plus each motoneuron's sum of its signed
    IN inputs (rows, K) (sums, not a matrix product: no rounding that depends on the
    device's threads)."""
    syn = jnp.asarray(SYNAPSES, inputs.dtype)
    return direct + jnp.sum(inputs[..., :, None] * syn, axis=-2)
