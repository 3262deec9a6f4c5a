"""Parameters and body mechanics of the Taga et al. (1991) biped (Appendices A and D).

Geometry and inertia come from ``models/taga1991.xml`` only.  This module holds the
remaining numbers of Appendix D (joint viscosity, knee stop, ground, torque gains,
neural time constants, weights, feedback gains) in :class:`TagaParams`, and the joint
forces of Appendix A written on the absolute segment angles and mapped to generalised
forces with ``jax.vjp`` through :mod:`jaxgait.body.planar`.

Angle convention: the paper measures the segment angles x5, x8 (thighs), x11, x14 (shanks)
clockwise from the forward horizontal; here th = x - pi/2 is the angle from the downward
vertical, + = segment rotated backwards.  The MJCF hinges give th_thigh = q_hip and
th_shank = q_hip + q_knee.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxgait.body.planar import Body, load_body

MODEL_NAME = "taga1991"
# segment order used for the absolute angles and segment torques
SEGMENTS = ("thigh_r", "thigh_l", "shank_r", "shank_l")


@struct.dataclass
class TagaParams:
    """All non-geometric numbers of Appendix D (SI units); every field may be batched.

    Attributes:
      u0: tonic input from the higher centre (eq. 6) [-]; 5.5 walks, 8.3 runs.
      b1: hip viscosity, torque -b1 |th| dth on the thigh [N m s / rad^2].
      b2: knee viscosity [N m s / rad].
      b_k: knee nonlinear damper, (b2 + b_k f(x5 - x11)) [N m s / rad^2].
      k_k: knee stop stiffness [N m / rad] (see ``Options.knee_stop``).
      k_g, b_g: ground spring [N/m] and damper [N s/m].
      p: (6,) torque gains (p_f^h, p_e^h, p_f^k, p_e^k, p_f^a, p_e^a) [N m].
      tau_hip, tau_hip_adapt: tau, tau' of neurons 1-4 [s].
      tau_ka, tau_ka_adapt: tau, tau' of neurons 5-12 [s].
      beta: adaptation gain.
      w_fe, w_rl, w_hka: connection weights (flexor-extensor, right-left, hip-knee/ankle).
      a: (8,) feedback gains a1..a8 (Appendix C).
      feedback_gain: multiplies every Feed_i; 1 = the paper, 0 = isolated network.
    """

    u0: jax.Array = 5.5
    b1: jax.Array = 10.0
    b2: jax.Array = 10.0
    b_k: jax.Array = 1000.0
    k_k: jax.Array = 10000.0
    k_g: jax.Array = 10000.0
    b_g: jax.Array = 1000.0
    p: jax.Array = dataclasses.field(
        default_factory=lambda: jnp.asarray([15.0, 85.0, 15.0, 15.0, 100.0, 75.0])
    )
    tau_hip: jax.Array = 0.05
    tau_hip_adapt: jax.Array = 0.60
    tau_ka: jax.Array = 0.025
    tau_ka_adapt: jax.Array = 0.30
    beta: jax.Array = 2.5
    w_fe: jax.Array = -2.0
    w_rl: jax.Array = -1.0
    w_hka: jax.Array = -1.0
    a: jax.Array = dataclasses.field(
        default_factory=lambda: jnp.asarray([1.5, 1.0, 1.5, 1.5, 3.0, 1.5, 3.0, 1.5])
    )
    feedback_gain: jax.Array = 1.0

    def as_floats(self, dtype=jnp.float32) -> TagaParams:
        """Every leaf as a ``dtype`` array (so batches and scans see fixed types)."""
        return jax.tree_util.tree_map(lambda v: jnp.asarray(v, dtype), self)


PARAM_NAMES = tuple(f.name for f in dataclasses.fields(TagaParams))
P_NAMES = ("p_f_h", "p_e_h", "p_f_k", "p_e_k", "p_f_a", "p_e_a")


def params_from_dict(d: dict | None = None) -> TagaParams:
    """Build :class:`TagaParams` from a flat dict (preset ``params``).

    Besides the field names, the six torque gains may be given one by one
    (``p_f_h`` ... ``p_e_a``) and the feedback gains as ``a1`` ... ``a8``.
    Unknown keys raise ``KeyError``.
    """
    d = dict(d or {})
    base = TagaParams()
    p = np.asarray(base.p, float).copy()
    a = np.asarray(base.a, float).copy()
    kw = {}
    for k, v in d.items():
        if k in P_NAMES:
            p[P_NAMES.index(k)] = float(v)
        elif len(k) == 2 and k[0] == "a" and k[1] in "12345678":
            a[int(k[1]) - 1] = float(v)
        elif k == "p":
            p = np.asarray(v, float)
        elif k == "a":
            a = np.asarray(v, float)
        elif k in PARAM_NAMES:
            kw[k] = float(v)
        else:
            raise KeyError(f"unknown Taga parameter {k!r}; known: {PARAM_NAMES + P_NAMES}")
    return TagaParams(p=jnp.asarray(p), a=jnp.asarray(a), **kw)


@dataclass(frozen=True)
class Options:
    """Static (structural) choices; the defaults are the reading of the paper used here.

    Attributes:
      knee_stop: ``"ramp"`` applies k_k f(x5 - x11) (a linear stop, the reading used
        here: the paper prints k_k h(x5 - x11), a 10^4 N m step that cannot be an
        "elastic force"); ``"step"`` applies the printed step literally.
      neural_integrator: ``"euler"`` (explicit, default) or ``"rk4"`` for eq. 6.
      fall_height: the rollout is declared fallen when the hip is less than this
        height above the terrain [m], or a knee goes below the terrain.
    """

    knee_stop: str = "ramp"
    neural_integrator: str = "euler"
    fall_height: float = 0.6

    def __post_init__(self):
        if self.knee_stop not in ("ramp", "step"):
            raise ValueError(f"knee_stop must be 'ramp' or 'step', not {self.knee_stop!r}")
        if self.neural_integrator not in ("euler", "rk4"):
            raise ValueError(
                f"neural_integrator must be 'euler' or 'rk4', not {self.neural_integrator!r}"
            )


@dataclass(frozen=True, eq=False)
class TagaBody:
    """The MJCF body plus the index tables the Taga model needs (static)."""

    body: Body

    @cached_property
    def segment_ids(self) -> np.ndarray:
        import mujoco

        m = self.body.mj_model
        return np.asarray([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n) for n in SEGMENTS])

    @cached_property
    def ankle_ids(self) -> np.ndarray:
        return np.asarray([self.body.site_id("ankle_r"), self.body.site_id("ankle_l")])

    @cached_property
    def knee_ids(self) -> np.ndarray:
        return np.asarray([self.body.site_id("knee_r"), self.body.site_id("knee_l")])

    @cached_property
    def push_ids(self) -> np.ndarray:
        """Sites that can be pushed: hip (link 1), right and left shank centres of mass."""
        b = self.body
        return np.asarray([b.site_id("hip"), b.site_id("shank_com_r"), b.site_id("shank_com_l")])

    @cached_property
    def keyframe_qpos(self) -> np.ndarray:
        """Appendix E posture stored in the MJCF keyframe ``appendix_e``."""
        return np.asarray(self.body.mj_model.key_qpos[0]).copy()

    # ------------------------------------------------------------------ kinematics
    def angles(self, qpos) -> jax.Array:
        """(4,) segment angles from the downward vertical, + = backwards:
        (right thigh, left thigh, right shank, left shank) = (x5, x8, x11, x14) - pi/2."""
        return self.body.frames(qpos)[1][self.segment_ids]

    def angles_and_rates(self, qpos, qvel):
        """Segment angles and angular velocities (4,), (4,) [rad, rad/s]."""
        return jax.jvp(self.angles, (qpos,), (qvel,))

    def segment_torques_to_qfrc(self, qpos, seg_torques) -> jax.Array:
        """Generalised force of torques (4,) acting on the segments' absolute angles."""
        _, vjp = jax.vjp(self.angles, qpos)
        return vjp(seg_torques)[0]


def load(name: str = MODEL_NAME) -> TagaBody:
    """Load the MJCF (default ``models/taga1991.xml``)."""
    return TagaBody(load_body(name))


def joint_torques(th, dth, tr, params: TagaParams, knee_stop: str = "ramp") -> jax.Array:
    """Segment torques of Appendix A from viscosity, the knee stop and T_r1..T_r6.

    Thigh (x5):  -b1 |x5 - pi/2| dx5 - {b2 + b_k f(x5 - x11)}(dx5 - dx11)
                 - k_k stop(x5 - x11) + T_r1 + T_r3,
    shank (x11): -{b2 + b_k f(x5 - x11)}(dx11 - dx5) + k_k stop(x5 - x11) - T_r3 - T_r5,
    and the same for the left leg (x8, x14, T_r2, T_r4, T_r6).  x5 - x11 > 0 is knee
    hyper-extension; stop(x) = f(x) for ``knee_stop="ramp"``, h(x) for ``"step"``.

    Args:
      th, dth: (4,) segment angles / rates (thigh R, thigh L, shank R, shank L).
      tr: (6,) T_r1..T_r6 [N m], + = extension.
    Returns:
      (4,) torques on (thigh R, thigh L, shank R, shank L) [N m].
    """
    thigh, shank = th[:2], th[2:]
    dthigh, dshank = dth[:2], dth[2:]
    hyper = thigh - shank  # x5 - x11, x8 - x14
    stop = jnp.maximum(hyper, 0.0) if knee_stop == "ramp" else (hyper >= 0.0).astype(th.dtype)
    knee = -(params.b2 + params.b_k * jnp.maximum(hyper, 0.0)) * (dthigh - dshank)
    knee = knee - params.k_k * stop
    t_hip, t_knee, t_ankle = tr[0:2], tr[2:4], tr[4:6]
    q_thigh = -params.b1 * jnp.abs(thigh) * dthigh + knee + t_hip + t_knee
    q_shank = -knee - t_knee - t_ankle
    return jnp.concatenate([q_thigh, q_shank])
