"""Geyer Hill-type muscle-tendon units (MTUs), batched over muscles.

The model is Geyer's MTU (Geyer, Seyfarth & Blickhan 2003; Geyer & Herr 2010, "GH2010") as
written up in Dzeladini's thesis (2013), section 2.1.1.1, eq. 2.1-2.30 and Tables 2.1/2.2, with
the seed errata of SPEC section 8 applied:

* N = 1.5 (eccentric force enhancement) and K = 5 (shape factor), not the swapped nomenclature;
* one force-velocity convention: shortening is negative, v_n = v_ce / (v_max * l_opt);
* the buffer element engages when l_ce < l_opt (1 - w) (eq. 2.7/2.11 print another condition);
* SOL is the uniarticular ankle plantarflexor and GAS spans knee and ankle (Table 2.2 swaps the
  joint rows; the geometry below is GH2010's, see ``geyer_reference.md`` section 1b).

Each MTU is a contractile element (CE) with a parallel element (PE) and a buffer element (BE), in
series with a tendon (SE).  The state is the activation A and the CE length l_ce.  Given the MTU
length from the joint angles (eq. 2.23-2.24), the force balance F_se + F_be = F_ce + F_pe is
solved for the force-velocity factor (eq. 2.15), inverted to the CE velocity (eq. 2.16) and
integrated.

Shapes: every muscle quantity has shape (..., M) with the muscle order of the table (for GEYER7
``MUSCLES = ("HFL", "GLU", "HAM", "VAS", "GAS", "SOL", "TA")``); joint quantities have shape
(..., 3) ordered (hip, knee, ankle).  The simulator uses (2, M) [leg, muscle] and (2, 3)
[leg, joint].  All functions broadcast over leading axes, are branchless and jit/vmap/grad safe.

Joint angles are in the GH2010 internal convention, radians: ankle 90 deg neutral (smaller =
dorsiflexion), knee 180 deg at full extension, hip 180 deg straight (smaller = flexion).

Geometry (one formula for lengths and torques).  For a muscle-joint pair with sign s:

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

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

__all__ = [
    "ACT_MIN",
    "GEYER7",
    "JOINTS",
    "MUSCLES",
    "MUSCLES8",
    "WANG8",
    "MuscleState",
    "MuscleTable",
    "contraction_velocity",
    "f_be",
    "f_l",
    "f_pe_star",
    "f_se",
    "f_v",
    "force_velocity_balance",
    "init_lce",
    "init_muscle_state",
    "merge_muscle_axes",
    "joint_torques",
    "moment_arms",
    "mtu_force",
    "mtu_length",
    "mtu_length_changes",
    "muscle_step",
    "v_from_fv",
]

JOINTS = ("hip", "knee", "ankle")
MUSCLES = ("HFL", "GLU", "HAM", "VAS", "GAS", "SOL", "TA")
MUSCLES8 = MUSCLES + ("RF",)

# Shared constants (geyer_reference.md section 1c; thesis Table 2.1 and section 2.1.1.1).
W_DEFAULT = 0.56  # CE force-length width [l_opt]
C_DEFAULT = math.log(0.05)  # f_l = 0.05 at l_ce = l_opt (1 +- w)
N_DEFAULT = 1.5  # eccentric force enhancement [F_max] (SPEC section 8: N = 1.5, K = 5)
K_DEFAULT = 5.0  # force-velocity shape factor
EPS_REF_DEFAULT = 0.04  # tendon reference strain [l_slack]
TAU_ACT_DEFAULT = 0.01  # excitation-contraction time constant [s]

#: Lower bound of activation and stimulation (Geyer's pre-activation ``preA``).  f_v is
#: undefined at zero activation, so the force balance always uses max(A, ACT_MIN).
ACT_MIN = 0.01
# Floor on A f_l + f_pe in eq. 2.15.  With A >= 0.01 it binds only when f_l < 0.01, i.e.
# l_ce < 0.35 l_opt, deep inside the buffer-element range where no equilibrium exists; it
# bounds the (then huge) lengthening speed the buffer element commands.
_DEN_MIN = 1e-4
# Safety floor on l_ce [l_opt]; never reached in normal operation (the BE engages at 1 - w).
_LCE_MIN = 0.05

_NO_ARM, _CONST_ARM, _COS_ARM = 0, 1, 2
_PER_MUSCLE = ("f_max", "v_max", "l_opt", "l_slack", "type1")  # (M,) columns
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

    def __post_init__(self):
        object.__setattr__(self, "names", tuple(self.names))
        m = len(self.names)
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


# ----------------------------------------------------------------------------------------------
# helpers


def _dtype(*xs):
    """Float dtype for the computation: that of the inputs, at least float32."""
    return jnp.result_type(*xs, jnp.float32)


def _p(a, dtype):
    """A static table array as a jnp constant of ``dtype``."""
    return jnp.asarray(a, dtype=dtype)


# ----------------------------------------------------------------------------------------------
# element characteristics (all normalised, dimensionless)


def f_l(l_norm, w=W_DEFAULT, c=C_DEFAULT):
    """CE force-length factor, eq. 2.4.

    f_l = exp(c |(l_ce - l_opt) / (l_opt w)|^3) with l_norm = l_ce / l_opt [-];
    f_l(1) = 1 and f_l(1 +- w) = exp(c) = 0.05.
    """
    x = (jnp.asarray(l_norm) - 1.0) / w
    return jnp.exp(c * jnp.abs(x) ** 3)


#: default iterations of the backward-Euler CE solve after its first intersection
#: (``muscle_step``); per-step accuracy in ``benchmarks/ce_solver_accuracy.py``
CE_SOLVE_ITERS = 1

# slope d f_v / d v_n of eq. 2.16's third branch (Geyer's code: v_n = 0.01 (f_v - N) + 1)
FV_LINE_SLOPE = 100.0


def f_v(v_n, N=N_DEFAULT, K=K_DEFAULT):
    """CE force-velocity factor (forward form of eq. 2.5 / 2.16, shortening negative).

    v_n = v_ce / (v_max l_opt) [-]:
      v_n < 0:  f_v = (1 + v_n) / (1 - K v_n)          (concentric; f_v(-1) = 0)
      v_n >= 0: f_v = N + (N - 1)(v_n - 1) / (7.56 K v_n + 1)   (eccentric; f_v(0) = 1,
                f_v(1) = N, f_v -> N + (N - 1)/(7.56 K) ~ 1.513 for v_n -> inf)
    This is the algebraic inverse of the first two branches of ``v_from_fv``
    (geyer_reference.md section 1c, "equivalent forward form").  For v_n < -1 the concentric
    branch is continued (negative values).
    """
    v_n = jnp.asarray(v_n)
    vc = jnp.minimum(v_n, 0.0)
    ve = jnp.maximum(v_n, 0.0)
    conc = (1.0 + vc) / (1.0 - K * vc)
    ecc = N + (N - 1.0) * (ve - 1.0) / (7.56 * K * ve + 1.0)
    return jnp.where(v_n < 0.0, conc, ecc)


def v_from_fv(fv, N=N_DEFAULT, K=K_DEFAULT):
    """Inverse force-velocity relation, eq. 2.16 as in Geyer's code; returns v_n [-].

    Three branches (geyer_reference.md section 1c):
      fv <= 1:     v_n = (fv - 1) / (K fv + 1)                       (concentric)
      1 < fv <= N: v_n = (x + 1) / (1 - 7.56 K x),  x = (fv - N)/(N - 1)   (eccentric)
      fv > N:      v_n = 0.01 (fv - N) + 1                             (linear continuation)
    The third branch replaces the pole of eq. 2.16 at fv = N + (N - 1)/(7.56 K) by a steep
    line; it is not the inverse of ``f_v`` for v_n > 1.  ``v_from_fv`` and ``f_v`` are exact
    inverses on fv in [0, N] <-> v_n in [-1, 1].  fv < 0 is treated as 0 (v_n = -1).
    Each branch sees its own clipped argument, so values and gradients stay finite.
    """
    fv = jnp.asarray(fv)
    f_lo = jnp.clip(fv, 0.0, 1.0)
    conc = (f_lo - 1.0) / (K * f_lo + 1.0)
    x = (jnp.clip(fv, 1.0, N) - N) / (N - 1.0)
    ecc = (x + 1.0) / (1.0 - 7.56 * K * x)
    lin = (fv - N) / FV_LINE_SLOPE + 1.0
    return jnp.where(fv <= 1.0, conc, jnp.where(fv <= N, ecc, lin))


def f_se(l_se, l_slack, eps_ref=EPS_REF_DEFAULT):
    """Normalised tendon (SE) force F_se / F_max, eq. 2.9/2.10.

    eps = (l_se - l_slack) / l_slack; f_se = (eps / eps_ref)^2 for eps > 0, else 0.
    Lengths in m.
    """
    eps = (jnp.asarray(l_se) / l_slack - 1.0) / eps_ref
    return jnp.maximum(eps, 0.0) ** 2


def f_pe_star(l_norm, w=W_DEFAULT):
    """Normalised parallel-element force F_pe* / F_max, eq. 2.12 (PE reference strain w).

    f_pe* = ((l_norm - 1) / w)^2 for l_norm = l_ce / l_opt > 1, else 0.
    (The PE force is F_max f_pe* f_v, eq. 2.8.)
    """
    return (jnp.maximum(jnp.asarray(l_norm) - 1.0, 0.0) / w) ** 2


def f_be(l_norm, w=W_DEFAULT):
    """Normalised buffer-element force F_be / F_max, eq. 2.11 with the SPEC section 8 erratum.

    The BE engages when l_ce < l_opt (1 - w): f_be = ((l_norm - (1 - w)) / (w/2))^2, else 0.
    """
    return (jnp.maximum((1.0 - w) - jnp.asarray(l_norm), 0.0) / (0.5 * w)) ** 2


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
    dt = _dtype(phi)
    ph = phi.astype(dt)[..., None, :]
    r0, rho, s = _p(table.r0, dt), _p(table.rho, dt), _p(table.sign, dt)
    pmax, pref = _p(table.phi_max, dt), _p(table.phi_ref, dt)
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
    return _p(table.l_opt + table.l_slack, dt) + jnp.sum(dl, axis=-1)


def moment_arms(table: MuscleTable, phi):
    """Signed moment arms s r(phi) [m], shape (..., M, 3) (eq. 2.17-2.19, 2.37).

    Cosine arm r = r0 cos(phi - phi_max), constant arm r = r0, 0 where not spanning.  The
    torque of muscle m on joint j in the direction of increasing GH angle is arm[m, j] F_mtu[m];
    arm = -(1/rho) d(dL)/d(phi).
    """
    phi = jnp.asarray(phi)
    dt = _dtype(phi)
    ph = phi.astype(dt)[..., None, :]
    r0, s, pmax = _p(table.r0, dt), _p(table.sign, dt), _p(table.phi_max, dt)
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


# ----------------------------------------------------------------------------------------------
# contraction dynamics


@struct.dataclass
class MuscleState:
    """MTU state (pytree).

    Attributes:
      act: (..., M) activation A [-].
      l_ce: (..., M) contractile-element length [m].
    """

    act: jax.Array
    l_ce: jax.Array


def mtu_force(table: MuscleTable, act, l_ce, l_mtu):
    """MTU force F_mtu = F_se = F_max f_se(l_mtu - l_ce) [N], shape (..., M) (eq. 2.1, 2.9).

    act is not needed (the tendon force depends on lengths only); it is accepted so that all
    MTU functions share one signature.  Lengths in m.
    """
    del act
    l_ce, l_mtu = jnp.asarray(l_ce), jnp.asarray(l_mtu)
    dt = _dtype(l_ce, l_mtu)
    fse = f_se(l_mtu - l_ce, _p(table.l_slack, dt), table.eps_ref)
    return _p(table.f_max, dt) * fse


def _active_fl(table: MuscleTable, act, l_norm):
    """A f_l(l_ce / l_opt) with A floored at ACT_MIN (Geyer's pre-activation) [-]."""
    return jnp.maximum(act, ACT_MIN) * f_l(l_norm, table.w, table.c)


def force_velocity_balance(table: MuscleTable, act, l_ce, l_mtu):
    """Solve the force balance for the force-velocity factor, eq. 2.13-2.15.

    f_v = (f_se + f_be) / (A f_l + f_pe*), with A >= ACT_MIN and the denominator floored.

    Returns:
      (fv, a_fl): fv (..., M) [-] and the activation-length term A f_l (..., M) [-] used, so
      that the active CE force is F_ce = F_max a_fl fv.
    """
    act, l_ce, l_mtu = jnp.asarray(act), jnp.asarray(l_ce), jnp.asarray(l_mtu)
    dt = _dtype(act, l_ce, l_mtu)
    l_opt = _p(table.l_opt, dt)
    l_n = l_ce / l_opt
    fse = f_se(l_mtu - l_ce, _p(table.l_slack, dt), table.eps_ref)
    a_fl = _active_fl(table, act, l_n)
    den = jnp.maximum(a_fl + f_pe_star(l_n, table.w), _DEN_MIN)
    fv = (fse + f_be(l_n, table.w)) / den
    return fv, a_fl


def contraction_velocity(table: MuscleTable, act, l_ce, l_mtu):
    """CE velocity v_ce [m/s], shape (..., M); shortening negative.

    Eq. 2.15 solved for f_v (``force_velocity_balance``), then inverted with eq. 2.16
    (``v_from_fv``): v_ce = v_n v_max l_opt.  Activation below ACT_MIN = 0.01 is treated as
    0.01 (Geyer's pre-activation), since f_v is undefined at A = 0.
    """
    fv, _ = force_velocity_balance(table, act, l_ce, l_mtu)
    dt = fv.dtype
    v_n = v_from_fv(fv, table.N, table.K)
    return v_n * _p(table.v_max * table.l_opt, dt)


def backward_euler_velocity(table: MuscleTable, act, l_ce, l_mtu, h, iters: int = 100):
    """Reference solution of the backward-Euler CE step by bisection (slow; for checks).

    The root v_n [-] of f_v,balance(l_ce + h v_max l_opt v_n) = f_v(v_n) (eq. 2.15 at the end
    point against the exact inverse of eq. 2.16) in the bracket [0, v_n,explicit], bisected
    ``iters`` times; the value ``muscle_step``'s solver converges to.  act, l_ce, l_mtu are
    (..., M) arrays [-, m, m]; h [s] is the step.  Returns v_n (..., M).
    """
    act, l_ce, l_mtu = jnp.asarray(act), jnp.asarray(l_ce), jnp.asarray(l_mtu)
    fdt = _dtype(act, l_ce, l_mtu)
    c = jnp.asarray(h, fdt) * _p(table.v_max * table.l_opt, fdt)

    def g(v):
        fb = force_velocity_balance(table, act, l_ce + c * v, l_mtu)[0]
        return fb - _f_v_inverse_of_v_from_fv(v, table.N, table.K)

    v_e = v_from_fv(force_velocity_balance(table, act, l_ce, l_mtu)[0], table.N, table.K)

    def halve(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        above = g(mid) > 0.0  # the root lies above mid
        return jnp.where(above, mid, lo), jnp.where(above, hi, mid)

    lo, hi = jax.lax.fori_loop(0, iters, halve, (jnp.minimum(v_e, 0.0), jnp.maximum(v_e, 0.0)))
    return 0.5 * (lo + hi)


def init_lce(table: MuscleTable, l_mtu, act=None):
    """Equilibrium CE length for a given MTU length [m], shape (..., M) (eq. 2.25-2.30).

    With ``act=None`` (the thesis' assumption A = 0, v_ce = 0):
      slack MTU (l_mtu <= l_opt + l_slack): l_ce = l_opt                         (eq. 2.25)
      otherwise F_pe = F_se (eq. 2.27-2.28, f_v = 1):
        l_se = l_slack (l_opt w + eps_ref (l_mtu - l_opt)) / (l_opt w + eps_ref l_slack)
        l_ce = l_mtu - l_se                                                      (eq. 2.29-2.30)
    Both branches give l_ce >= l_opt and meet at l_mtu = l_opt + l_slack, so no clipping is
    needed.

    With ``act`` given ((..., M) or scalar), the exact resting equilibrium of
    ``contraction_velocity`` (v_ce = 0: f_se + f_be = max(A, 0.01) f_l + f_pe*) is found by
    bisection on l_ce in [0.22 l_opt, max(l_mtu - l_slack, (1 - w) l_opt)], where the balance
    changes sign; a simulation started there has v_ce ~ 0.  Its derivatives (w.r.t. l_mtu and
    act) follow from the implicit-function theorem.
    """
    l_mtu = jnp.asarray(l_mtu)
    dt = _dtype(l_mtu)
    l_opt, l_slack = _p(table.l_opt, dt), _p(table.l_slack, dt)
    w, eps = table.w, table.eps_ref
    l_se = l_slack * (l_opt * w + eps * (l_mtu - l_opt)) / (l_opt * w + eps * l_slack)
    l_ce0 = jnp.where(l_mtu > l_opt + l_slack, l_mtu - l_se, l_opt)
    l_ce0 = jnp.broadcast_to(l_ce0, l_mtu.shape)
    if act is None:
        return l_ce0

    act = jnp.asarray(act, dtype=dt)
    a = jnp.maximum(act, ACT_MIN)

    def residual(l_ce):  # > 0: net force lengthens the CE (v_ce > 0)
        l_n = l_ce / l_opt
        return (
            f_se(l_mtu - l_ce, l_slack, eps)
            + f_be(l_n, w)
            - a * f_l(l_n, w, table.c)
            - f_pe_star(l_n, w)
        )

    shape = jnp.broadcast_shapes(l_mtu.shape, a.shape, l_opt.shape)
    hi = jnp.broadcast_to(jnp.maximum(l_mtu - l_slack, (1.0 - w) * l_opt), shape)
    lo = jnp.minimum(0.5 * (1.0 - w) * l_opt, hi)

    def bisect(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        up = residual(mid) > 0.0  # root lies above mid
        return jnp.where(up, mid, lo), jnp.where(up, hi, mid)

    sg = jax.lax.stop_gradient
    lo, hi = jax.lax.fori_loop(0, 60, bisect, (sg(lo), sg(hi)))
    root = sg(0.5 * (lo + hi))
    # derivatives of the root by the implicit-function theorem (the value is unchanged)
    r, dr = jax.jvp(residual, (root,), (jnp.ones_like(root),))
    dr = sg(dr)
    corr = -r / jnp.where(dr < 0.0, dr, -1.0)
    return root + (corr - sg(corr))


def init_muscle_state(table: MuscleTable, l_mtu, act=ACT_MIN, exact=True):
    """Resting MuscleState for MTU lengths l_mtu (..., M) [m] and activation ``act``.

    exact=True solves the balance at this activation (``init_lce(..., act)``); exact=False uses
    the thesis' closed form (eq. 2.25-2.30, A = 0).
    """
    l_mtu = jnp.asarray(l_mtu)
    dt = _dtype(l_mtu)
    a = jnp.broadcast_to(jnp.asarray(act, dtype=dt), l_mtu.shape)
    l_ce = init_lce(table, l_mtu, a if exact else None)
    return MuscleState(act=a, l_ce=l_ce)


def _f_v_inverse_of_v_from_fv(v_n, N, K):
    """Exact inverse of ``v_from_fv`` on v_n >= -1: ``f_v`` up to v_n = 1, then the line
    fv = N + 100 (v_n - 1) of its third branch."""
    return jnp.where(v_n <= 1.0, f_v(v_n, N, K), N + FV_LINE_SLOPE * (v_n - 1.0))


def merge_muscle_axes(table: MuscleTable, *xs):
    """(..., L, M) arrays (e.g. legs x muscles) as (..., L M) against ``table.tiled(L)``.

    XLA's CPU loops vectorise the minor axis, and M = 7 muscles fill less than half of a
    vector register.  Returns (tiled table, merged arrays); arrays of one axis come back as
    they are.  The caller reshapes results back to (..., L, M).
    """
    shape = xs[0].shape
    if len(shape) < 2:
        return table, xs
    merged = shape[:-2] + (shape[-2] * shape[-1],)
    return table.tiled(shape[-2]), tuple(x.reshape(merged) for x in xs)


def muscle_step(
    table: MuscleTable,
    state: MuscleState,
    stim,
    l_mtu,
    dt,
    substeps: int = 1,
    implicit: bool = True,
    solve_iters: int = CE_SOLVE_ITERS,
):
    """Advance the MTU state by dt [s] with ``substeps`` fixed sub-steps of h = dt / substeps.

    stim (..., M) is clipped to [0.01, 1]; l_mtu (..., M) [m] is held over the step.  Per
    sub-step, both updates starting from the state at the start of the sub-step:

    * activation, dA/dt = (S - A) / tau (eq. 2.6, tau = 0.01 s), updated exactly for constant S:
      A <- S + (A - S) exp(-h / tau);
    * CE length, dl_ce/dt = v_ce(A, l_ce, l_mtu) (eq. 2.15-2.16).

      ``implicit=True`` (default): backward Euler, l' = l_ce + h v_ce(A, l', l_mtu).  It is
      solved per muscle for the normalised velocity v_n of the step, as the root of
      f_v,balance(l_ce + h v_max l_opt v_n) = f_v(v_n) (eq. 2.15 at the end point against the
      exact inverse of eq. 2.16), inside the bracket [0, v_n,explicit].  Each iteration
      linearises only the balance (value and slope from jax.jvp) and intersects that line with
      the exact f_v: on either side of v_n = 0 a Moebius map (a1 v + 1) / (c1 v + 1), so a
      quadratic solved in closed form, and beyond v_n = 1 the line of eq. 2.16's third branch.
      The intersection is kept in the bracket (its midpoint if there is none).  The first is
      taken at v_n = 0, then ``solve_iters`` more; ``benchmarks/ce_solver_accuracy.py``
      measures how far the default is from the converged step (Newton's method on the whole
      residual, used before, converged slowly where f_v bends sharply just above v_n = 0).
      So the step never exceeds the explicit one, fixed points (v_ce = 0) are those of the
      ODE, and it stays stable and consistent where explicit Euler at h = 0.5 ms is not: low
      activation with a nearly slack tendon (A f_l tiny) and fast eccentric states, where f_v
      is flat and v_ce very sensitive to force.  Cost: 1 + ``solve_iters`` evaluations of
      the force balance with its slope per sub-step.  Derivatives of the step (for
      gradient-based optimisation) come from the implicit-function theorem, not by
      differentiating the iterations.

      ``implicit=False``: explicit Euler, l' = l_ce + h v_ce(A, l_ce, l_mtu); stable only
      while h |dv_ce/dl_ce| < 2.

    Coupling: with l_mtu frozen at its start-of-step value the backward-Euler CE lags the MTU
    by about one step (force error ~ tendon stiffness x h x MTU speed, ~1 % F_max at 0.5 ms in
    gait-like tests).  Computing the torques from ``mtu_force`` at the start of the step and
    passing here the MTU length at the *end* of the step (after the physics step) removes that
    lag.

    Returns:
      (new_state, info), info a dict of (..., M) arrays:
        ``f_mtu`` [N]: MTU (tendon) force at the start of the step, mtu_force(state, l_mtu) --
          the force the joints should receive over the step and the force sensors read;
        ``v_ce`` [m/s]: CE velocity of the first sub-step, (l' - l_ce) / h (for the implicit
          scheme the backward-Euler velocity v_ce(A, l', l_mtu), for the explicit one
          v_ce(A, l_ce, l_mtu));
        ``f_ce`` [N]: active CE force A F_max f_l f_v at the same point as ``v_ce`` (implicit:
          f_l at the end of the step, f_v of its velocity);
        ``act`` [-], ``l_ce`` [m]: the state at the start of the step; ``stim`` [-]: the
          clipped stimulation.
      These are the inputs of ``jaxgait.muscles.energy.metabolic_rate``.
    """
    act0 = jnp.asarray(state.act)
    l_ce0 = jnp.asarray(state.l_ce)
    l_mtu = jnp.asarray(l_mtu)
    fdt = _dtype(act0, l_ce0, l_mtu)
    act0, l_ce0, l_mtu = act0.astype(fdt), l_ce0.astype(fdt), l_mtu.astype(fdt)
    stim = jnp.clip(jnp.asarray(stim, dtype=fdt), ACT_MIN, 1.0)
    shape = jnp.broadcast_shapes(act0.shape, l_ce0.shape, l_mtu.shape, stim.shape)
    act0, l_ce0, l_mtu, stim = (jnp.broadcast_to(x, shape) for x in (act0, l_ce0, l_mtu, stim))
    table, (act0, l_ce0, l_mtu, stim) = merge_muscle_axes(table, act0, l_ce0, l_mtu, stim)
    h = jnp.asarray(dt, dtype=fdt) / substeps
    decay = jnp.exp(-h / table.tau_act)
    vscale = _p(table.v_max * table.l_opt, fdt)  # [m/s] per unit v_n
    c = h * vscale  # [m] per unit v_n over one sub-step
    l_min = _p(_LCE_MIN * table.l_opt, fdt)
    N, K = table.N, table.K

    def balance(act, l_ce, l_mtu):
        return force_velocity_balance(table, act, l_ce, l_mtu)[0]

    def balance_jvp(act, l_ce, l_mtu):
        return jax.jvp(lambda x: balance(act, x, l_mtu), (l_ce,), (jnp.ones_like(l_ce),))

    def f_v_inv(v_n):
        return _f_v_inverse_of_v_from_fv(v_n, N, K)

    def solve(act, l_ce, l_mtu, c):
        """Backward-Euler v_n of one sub-step and the slope dg/dv of its residual there."""
        fb0, dfb0 = balance_jvp(act, l_ce, l_mtu)
        v_e = v_from_fv(fb0, N, K)  # explicit step; the root lies in [0, v_e]
        lo, hi = jnp.minimum(v_e, 0.0), jnp.maximum(v_e, 0.0)
        # on the root's side of v_n = 0 (the side of the explicit step), f_v is the Moebius
        # map (a1 v + 1) / (c1 v + 1) (eq. 2.16 inverted; ``f_v``)
        ecc = fb0 > 1.0
        a1 = jnp.where(ecc, N * 7.56 * K + N - 1.0, 1.0)
        c1 = jnp.where(ecc, 7.56 * K, -K)

        def intersect(v, fb, dfb, lo, hi):
            # the balance linearised at v, p + q x with q = c dfb, meets the exact f_v(x)
            # either on its Moebius piece, where qa x^2 + qb x + qc = 0 (the root nearest
            # the bracket), or, eccentric beyond v_n = 1, on the line N + 100 (x - 1) of
            # eq. 2.16's third branch (the line still above f_v(1) = N at x = 1)
            q = c * dfb
            p = fb - q * v
            qa, qb, qc = q * c1, p * c1 + q - a1, p - 1.0
            disc = qb * qb - 4.0 * qa * qc
            den = qb + jnp.where(qb >= 0.0, 1.0, -1.0) * jnp.sqrt(jnp.maximum(disc, 0.0))
            # both roots without cancellation: 2 qc / (-den) and -den / (2 qa)
            r_small = jnp.where(den != 0.0, -2.0 * qc / jnp.where(den != 0.0, den, 1.0), jnp.inf)
            r_large = jnp.where(qa != 0.0, -den / jnp.where(qa != 0.0, 2.0 * qa, 1.0), jnp.inf)

            def outside(r):
                return jnp.maximum(lo - r, 0.0) + jnp.maximum(r - hi, 0.0)

            r = jnp.where(outside(r_small) <= outside(r_large), r_small, r_large)
            r = jnp.where(disc >= 0.0, r, jnp.nan)
            on_line = ecc & (p + q > N) & (q < FV_LINE_SLOPE)
            r = jnp.where(
                on_line, (p - N + FV_LINE_SLOPE) / jnp.where(on_line, FV_LINE_SLOPE - q, 1.0), r
            )
            return jnp.where(jnp.isfinite(r), jnp.clip(r, lo, hi), 0.5 * (lo + hi))

        def iterate(_, carry):
            v, lo, hi = carry
            fb, dfb = balance_jvp(act, l_ce + c * v, l_mtu)
            g = fb - f_v_inv(v)  # decreasing in v wherever the balance decreases with l_ce
            lo = jnp.where(g > 0.0, v, lo)
            hi = jnp.where(g < 0.0, v, hi)
            return intersect(v, fb, dfb, lo, hi), lo, hi

        v = intersect(jnp.zeros_like(fb0), fb0, dfb0, lo, hi)
        v, _, _ = jax.lax.fori_loop(0, solve_iters, iterate, (v, lo, hi), unroll=True)
        # dg/dv at the root, for the implicit-function derivative (XLA drops it from
        # forward-only programs)
        _, dfb = balance_jvp(act, l_ce + c * v, l_mtu)
        _, dfv = jax.jvp(f_v_inv, (v,), (jnp.ones_like(v),))
        return v, c * dfb - dfv

    @jax.custom_jvp
    def root(act, l_ce, l_mtu, c):
        return solve(act, l_ce, l_mtu, c)[0]

    @root.defjvp
    def _root_jvp(primals, tangents):
        # implicit-function theorem on g(theta, v) = balance(l_ce + c v) - f_v^-1(v) = 0:
        # dv = -dg_theta / dg_v (evaluated only when derivatives are asked for)
        v, dg = solve(*primals)
        _, dg_theta = jax.jvp(lambda a, lc, lm, cc: balance(a, lc + cc * v, lm), primals, tangents)
        return v, jnp.where(dg < 0.0, -dg_theta / jnp.where(dg < 0.0, dg, -1.0), 0.0)

    def advance(act, l_ce):
        if not implicit:
            v = v_from_fv(balance(act, l_ce, l_mtu), N, K)
        else:
            v = root(act, l_ce, l_mtu, c)
        l_new = jnp.maximum(l_ce + c * v, l_min)
        return stim + (act - stim) * decay, l_new, v

    act1, l_ce1, v0 = advance(act0, l_ce0)
    if implicit:
        # F_ce = A F_max f_l f_v (eq. 2.2) at the end point and velocity of the step; equal to
        # the force balance there up to the solver's tolerance, without evaluating it again
        a_fl_at = _active_fl(table, act0, l_ce1 / _p(table.l_opt, fdt))
        fv_at = f_v_inv(v0)
    else:
        fv_at, a_fl_at = force_velocity_balance(table, act0, l_ce0, l_mtu)
    if substeps > 1:

        def body(_, carry):
            a, lc = carry
            a, lc, _ = advance(a, lc)
            return a, lc

        act1, l_ce1 = jax.lax.fori_loop(1, substeps, body, (act1, l_ce1))

    info = {
        "f_mtu": mtu_force(table, act0, l_ce0, l_mtu),
        "v_ce": v0 * vscale,
        "f_ce": _p(table.f_max, fdt) * a_fl_at * fv_at,
        "act": act0,
        "l_ce": l_ce0,
        "stim": stim,
    }
    info = {k: v.reshape(shape) for k, v in info.items()}
    return MuscleState(act=act1.reshape(shape), l_ce=l_ce1.reshape(shape)), info
