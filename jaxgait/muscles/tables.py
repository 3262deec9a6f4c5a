"""Muscle tables and the muscle-joint geometry they define (thesis Table 2.2, eq. 2.17-2.24, 2.37).

A :class:`MuscleTable` holds the static parameters of M muscles (NumPy, closed over by jit):
per muscle F_max, v_max, l_opt, l_slack and the type-I fibre fraction, and per (muscle, joint)
the moment-arm geometry.  :data:`GEYER7` is Geyer & Herr 2010's seven-muscle leg, :data:`WANG8`
adds rectus femoris for Wang et al. 2012.

Joint angles are in the GH2010 internal convention, radians: ankle 90 deg neutral (smaller =
dorsiflexion), knee 180 deg at full extension, hip 180 deg straight (smaller = flexion).  For a
muscle-joint pair with sign s:

* cosine arm (knee, ankle): r(phi) = r0 cos(phi - phi_max),
  dL = s rho r0 [sin(phi_ref - phi_max) - sin(phi - phi_max)];
* constant arm (hip): r = r0, dL = -s rho r0 (phi - phi_ref);
* l_mtu = l_opt + l_slack + sum over joints of dL (eq. 2.23-2.24);
* torque on the joint in the direction of increasing phi: tau = s r(phi) F_mtu (eq. 2.37).

So tau / F_mtu = -(1/rho) d(dL)/d(phi): the factor rho of eq. 2.23 scales the length change only,
as in GH2010 (it is not a pennation angle).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import jax.numpy as jnp
import numpy as np

from jaxgait.muscles.elements import (
    C_DEFAULT,
    EPS_REF_DEFAULT,
    K_DEFAULT,
    N_DEFAULT,
    TAU_ACT_DEFAULT,
    W_DEFAULT,
    as_const,
    compute_dtype,
)

JOINTS = ("hip", "knee", "ankle")
MUSCLES = ("HFL", "GLU", "HAM", "VAS", "GAS", "SOL", "TA")
MUSCLES8 = MUSCLES + ("RF",)

_NO_ARM, _CONST_ARM, _COS_ARM = 0, 1, 2
_PER_MUSCLE = ("f_max", "v_max", "l_opt", "l_slack", "type1", "stim_max")  # (M,) columns
_PER_JOINT = ("r0", "phi_max", "phi_ref", "rho", "sign", "arm")  # (M, 3) columns


@dataclass(frozen=True, eq=False)
class MuscleTable:
    """Static muscle parameters (NumPy; closed over by jit, not a pytree).

    Per-muscle arrays have shape (M,), geometry arrays shape (M, 3) over (hip, knee, ankle).

    Attributes:
      names: muscle names, length M.
      f_max: maximum isometric force [N].
      v_max: maximum contraction velocity [l_opt/s].
      l_opt: CE optimal length [m].
      l_slack: tendon slack length [m].
      type1: slow-twitch (type I) fibre fraction t_I [-] (thesis Table 2.2).
      r0: maximum moment arm [m]; 0 where the muscle does not span the joint.
      phi_max: angle of maximum moment arm [rad] (cosine arms only).
      phi_ref: angle at which dL = 0 [rad].
      rho: length-change scale factor [-] (eq. 2.23, "pennation" in the thesis).
      sign: +1 if the muscle turns the joint towards larger GH angles, -1 otherwise, 0 if the
        muscle does not span the joint.
      arm: 0 no arm, 1 constant arm, 2 cosine arm.
      w, c, N, K, eps_ref, tau_act: shared constants (see module constants).
      stim_max: (M,) upper bound of the stimulation (and so of the activation) [-]; 1 for
        every muscle of a source's table (``None`` is read as ones).  Above 1 only in a
        capacity study (:func:`with_headroom`).
    """

    names: tuple[str, ...]
    f_max: np.ndarray
    v_max: np.ndarray
    l_opt: np.ndarray
    l_slack: np.ndarray
    type1: np.ndarray
    r0: np.ndarray
    phi_max: np.ndarray
    phi_ref: np.ndarray
    rho: np.ndarray
    sign: np.ndarray
    arm: np.ndarray
    w: float = W_DEFAULT
    c: float = C_DEFAULT
    N: float = N_DEFAULT
    K: float = K_DEFAULT
    eps_ref: float = EPS_REF_DEFAULT
    tau_act: float = TAU_ACT_DEFAULT
    source: str = field(default="", repr=False)
    stim_max: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "names", tuple(self.names))
        m = len(self.names)
        if self.stim_max is None:
            object.__setattr__(self, "stim_max", np.ones(m))
        for k in _PER_MUSCLE:
            a = np.array(getattr(self, k), dtype=np.float64)
            if a.shape != (m,):
                raise ValueError(f"MuscleTable.{k}: shape {a.shape}, expected ({m},)")
            a.setflags(write=False)
            object.__setattr__(self, k, a)
        for k in _PER_JOINT:
            dtype = np.int32 if k == "arm" else np.float64
            a = np.array(getattr(self, k), dtype=dtype)
            if a.shape != (m, 3):
                raise ValueError(f"MuscleTable.{k}: shape {a.shape}, expected ({m}, 3)")
            a.setflags(write=False)
            object.__setattr__(self, k, a)
        if not np.all(np.isfinite(self.stim_max) & (self.stim_max >= 1.0)):
            raise ValueError(
                f"MuscleTable.stim_max: finite values >= 1 expected, got {self.stim_max}"
            )
        spans = self.arm != _NO_ARM
        if np.any(spans != (self.r0 > 0)) or np.any(spans != (self.sign != 0)):
            raise ValueError("MuscleTable: arm, r0 and sign disagree on which joints are spanned")

    @property
    def n(self) -> int:
        """Number of muscles M."""
        return len(self.names)

    def tiled(self, reps: int) -> MuscleTable:
        """This table repeated ``reps`` times: muscle i of copy k at index k M + i, the order
        of a (..., reps, M) array with its last two axes merged (e.g. two legs)."""
        per = {k: np.tile(getattr(self, k), reps) for k in _PER_MUSCLE}
        arms = {k: np.tile(getattr(self, k), (reps, 1)) for k in _PER_JOINT}
        return dataclasses.replace(self, names=self.names * reps, **per, **arms)

    @property
    def spans(self) -> np.ndarray:
        """(M, 3) bool: the muscle spans the joint."""
        return self.arm != _NO_ARM

    def index(self, name: str) -> int:
        """Position of muscle ``name`` in the table."""
        return self.names.index(name)


def _table(names, muscle_rows, joint_rows, source):
    """Build a MuscleTable from readable rows (angles in degrees)."""
    m = len(names)
    geo = {k: np.zeros((m, 3)) for k in ("r0", "phi_max", "phi_ref", "rho", "sign")}
    arm = np.zeros((m, 3), dtype=np.int32)
    for (mus, joint), (kind, r0, phi_max, phi_ref, rho, sign) in joint_rows.items():
        i, j = names.index(mus), JOINTS.index(joint)
        arm[i, j] = {"const": _CONST_ARM, "cos": _COS_ARM}[kind]
        geo["r0"][i, j] = r0
        geo["phi_max"][i, j] = math.radians(phi_max) if phi_max is not None else 0.0
        geo["phi_ref"][i, j] = math.radians(phi_ref)
        geo["rho"][i, j] = rho
        geo["sign"][i, j] = sign
    cols = np.array([muscle_rows[n] for n in names], dtype=np.float64)
    return MuscleTable(
        names=tuple(names),
        f_max=cols[:, 0],
        v_max=cols[:, 1],
        l_opt=cols[:, 2],
        l_slack=cols[:, 3],
        type1=cols[:, 4],
        arm=arm,
        source=source,
        **geo,
    )


# Muscle parameters: F_max [N], v_max [l_opt/s], l_opt [m], l_slack [m], t_I [-].
# F_max, v_max, l_opt, l_slack: thesis Table 2.2 (right by name, SPEC section 8) = GH2010 code
# (geyer_reference.md section 1a).  t_I: thesis Table 2.2 "Type I fibers percentage", read by
# column name.  Note: that printed row (VAS .44, HAM .54, GAS .81, SOL .70, TA .50) looks like
# the row (HFL .50, GLU .50, VAS .50, HAM .44, GAS .54, SOL .81, TA .70) shifted by one column
# from VAS on; the shifted row is the one close to published fibre-type data (e.g. Uchida et
# al. 2016: soleus 0.80, tibialis anterior 0.70, gastrocnemii 0.51-0.57).  The printed values
# are kept here; use ``dataclasses.replace(GEYER7, type1=...)`` to study the alternative.
_GEYER_MUSCLES = {
    "HFL": (2000.0, 12.0, 0.11, 0.10, 0.50),
    "GLU": (1500.0, 12.0, 0.11, 0.13, 0.50),
    "HAM": (3000.0, 12.0, 0.10, 0.31, 0.54),
    "VAS": (6000.0, 12.0, 0.08, 0.23, 0.44),
    "GAS": (1500.0, 12.0, 0.05, 0.40, 0.81),
    "SOL": (4000.0, 6.0, 0.04, 0.26, 0.70),
    "TA": (800.0, 12.0, 0.06, 0.24, 0.50),
}

# Muscle-joint geometry: (arm kind, r0 [m], phi_max [deg], phi_ref [deg], rho, sign).
# GH2010 code (geyer_reference.md section 1b, identical in Geyer's nms_model_MechInit.m, its
# Python port and A's config.py); GAS/SOL as in SPEC section 8.  Signs from the length-change
# formulas there (SOL/GAS-ankle/VAS: +rho r0 [sin(ref - max) - sin(phi - max)];
# TA/HAM-knee/GAS-knee: the opposite; hip: +rho r0 (phi - ref) for HFL, - for GLU/HAM).
_GEYER_JOINTS = {
    ("HFL", "hip"): ("const", 0.10, None, 180.0, 0.5, -1.0),
    ("GLU", "hip"): ("const", 0.10, None, 150.0, 0.5, +1.0),
    ("HAM", "hip"): ("const", 0.08, None, 155.0, 0.7, +1.0),
    ("HAM", "knee"): ("cos", 0.05, 180.0, 180.0, 0.7, -1.0),
    ("VAS", "knee"): ("cos", 0.06, 165.0, 125.0, 0.7, +1.0),
    ("GAS", "knee"): ("cos", 0.05, 140.0, 165.0, 0.7, -1.0),
    ("GAS", "ankle"): ("cos", 0.05, 110.0, 80.0, 0.7, +1.0),
    ("SOL", "ankle"): ("cos", 0.05, 110.0, 80.0, 0.5, +1.0),
    ("TA", "ankle"): ("cos", 0.04, 80.0, 110.0, 0.7, -1.0),
}

# Rectus femoris (RF) for Wang et al. 2012's 8-muscle leg.  Wang 2012 names RF (hip flexor and
# knee extensor, its section 3 and torque sums) but its numbers are in the supplemental material,
# which is not among the seeds; so every RF number below is a cited substitute:
# * F_max 1200 N, v_max 12 l_opt/s, l_opt 0.08 m, l_slack 0.35 m; hip: constant arm 0.08 m,
#   phi_ref 170 deg, rho 0.3; knee: maximum arm 0.06 m at phi_max 165 deg, phi_ref 125 deg,
#   rho 0.5 -- Song & Geyer 2015 model ("nms_MechInit.m", geyer_reference.md section 7), as
#   carried by its public Python port (``MuscleTendonComplex``, function ``REF``).  That model
#   lets the knee arm shrink towards 0.04 m in deep flexion; here the knee arm is the plain GH2010
#   cosine arm r0 cos(phi - phi_max) with r0 = 0.06 m (the same knee geometry as VAS).
# * t_I 0.3865: Uchida et al. 2016 (PLoS ONE 11:e0150378), rectus femoris, as tabulated in
#   KULeuvenNeuromechanics/MuscleRedundancySolver getSlowTwitchRatios_lr.m.
# The other seven muscles keep the GEYER7 values (Wang 2012 starts from GH2010's model).
_RF_MUSCLE = {"RF": (1200.0, 12.0, 0.08, 0.35, 0.3865)}
_RF_JOINTS = {
    ("RF", "hip"): ("const", 0.08, None, 170.0, 0.3, -1.0),
    ("RF", "knee"): ("cos", 0.06, 165.0, 125.0, 0.5, +1.0),
}

#: Geyer & Herr 2010 seven-muscle leg (thesis Table 2.2 with SPEC section 8 errata).
GEYER7 = _table(MUSCLES, _GEYER_MUSCLES, _GEYER_JOINTS, "GH2010 / thesis Table 2.2")
#: Wang et al. 2012 eight-muscle leg: GEYER7 plus rectus femoris (RF) as the 8th muscle.
WANG8 = _table(
    MUSCLES8,
    {**_GEYER_MUSCLES, **_RF_MUSCLE},
    {**_GEYER_JOINTS, **_RF_JOINTS},
    "GEYER7 + RF (Song & Geyer 2015 geometry, Uchida 2016 t_I)",
)


def with_headroom(table: MuscleTable, factors: dict[str, float], label: str) -> MuscleTable:
    """``table`` whose named muscles may be stimulated up to ``factors`` (>= 1) instead of 1.

    The contractile force is linear in the activation (eq. 2.15), so a muscle of this table
    pulls exactly as before while its controller asks for a stimulation of at most 1, and
    delivers what it asks for above that, up to ``factor`` times its active maximum; the
    tendon, parallel and buffer elements (which scale with F_max) are unchanged.  A capacity
    study, not a source's table: would the gait use the force if the muscle had it?  The
    metabolic models' activation and maintenance heat rates count a stimulation or activation
    above 1 as 1 (eq. 2.42, 2.44 are defined on [0, 1]); their shortening and work terms see
    the force delivered.  ``label`` is appended to the table's source.
    """
    unknown = sorted(set(factors) - set(table.names))
    if unknown:
        raise ValueError(f"with_headroom({label!r}): no muscles {unknown} in {table.names}")
    bad = {k: v for k, v in factors.items() if not (np.isfinite(v) and v >= 1.0)}
    if bad:
        raise ValueError(f"with_headroom({label!r}): factors must be finite and >= 1, got {bad}")
    smax = np.array(table.stim_max, dtype=np.float64)
    for name, f in factors.items():
        smax[table.index(name)] = f
    return dataclasses.replace(table, stim_max=smax, source=f"{table.source}; {label}")


# ----------------------------------------------------------------------------------------------
# geometry


def mtu_length_changes(table: MuscleTable, phi):
    """Per-joint MTU length changes dL [m], shape (..., M, 3) (eq. 2.23).

    phi: (..., 3) GH2010 joint angles (hip, knee, ankle) [rad].
      cosine arm:   dL = s rho r0 [sin(phi_ref - phi_max) - sin(phi - phi_max)]
      constant arm: dL = -s rho r0 (phi - phi_ref)
    0 where the muscle does not span the joint.
    """
    phi = jnp.asarray(phi)
    dt = compute_dtype(phi)
    ph = phi.astype(dt)[..., None, :]
    r0, rho, s = as_const(table.r0, dt), as_const(table.rho, dt), as_const(table.sign, dt)
    pmax, pref = as_const(table.phi_max, dt), as_const(table.phi_ref, dt)
    cos_dl = s * rho * r0 * (jnp.sin(pref - pmax) - jnp.sin(ph - pmax))
    const_dl = -s * rho * r0 * (ph - pref)
    arm = table.arm
    return jnp.where(arm == _COS_ARM, cos_dl, jnp.where(arm == _CONST_ARM, const_dl, 0.0))


def mtu_length(table: MuscleTable, phi):
    """MTU length l_mtu = l_opt + l_slack + sum_joints dL [m], shape (..., M) (eq. 2.24).

    phi: (..., 3) GH2010 joint angles [rad].  At phi = phi_ref, l_mtu = l_opt + l_slack.
    """
    dl = mtu_length_changes(table, phi)
    dt = dl.dtype
    return as_const(table.l_opt + table.l_slack, dt) + jnp.sum(dl, axis=-1)


def moment_arms(table: MuscleTable, phi):
    """Signed moment arms s r(phi) [m], shape (..., M, 3) (eq. 2.17-2.19, 2.37).

    Cosine arm r = r0 cos(phi - phi_max), constant arm r = r0, 0 where not spanning.  The
    torque of muscle m on joint j in the direction of increasing GH angle is arm[m, j] F_mtu[m];
    arm = -(1/rho) d(dL)/d(phi).
    """
    phi = jnp.asarray(phi)
    dt = compute_dtype(phi)
    ph = phi.astype(dt)[..., None, :]
    r0, s, pmax = as_const(table.r0, dt), as_const(table.sign, dt), as_const(table.phi_max, dt)
    cos_r = s * r0 * jnp.cos(ph - pmax)
    const_r = jnp.broadcast_to(s * r0, cos_r.shape)
    arm = table.arm
    return jnp.where(arm == _COS_ARM, cos_r, jnp.where(arm == _CONST_ARM, const_r, 0.0))


def joint_torques(table: MuscleTable, phi, f_mtu):
    """Muscle joint torques [N m], shape (..., 3) (eq. 2.37).

    phi: (..., 3) GH2010 joint angles [rad]; f_mtu: (..., M) MTU forces [N].  Positive torque
    turns the joint towards larger GH angles (hip extension, knee extension, plantarflexion).
    """
    arms = moment_arms(table, phi)
    f = jnp.asarray(f_mtu)
    return jnp.sum(arms * f[..., :, None], axis=-2)
