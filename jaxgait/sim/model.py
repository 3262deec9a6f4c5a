"""The simulated model: body, muscles, controller, contact law; settings and state.

A :class:`Model` is static data closed over by ``jit``: the MJCF body
(:class:`~jaxgait.body.planar.Body`), the muscle table, a
:class:`~jaxgait.control.interface.Controller`, the contact law, the ligament soft limits
and the gait-phase detection.  :func:`planar_model` puts a controller on the planar Geyer
body with the muscle table of its muscle count (7 per leg: Geyer & Herr's
:data:`~jaxgait.muscles.mtu.GEYER7`; 8: Wang et al. 2012's
:data:`~jaxgait.muscles.mtu.WANG8`, with rectus femoris); the registry of named models is
:mod:`jaxgait.models`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxgait.body.joints import SoftLimits
from jaxgait.body.planar import Body, load_body
from jaxgait.control.gait import GaitConfig, GaitState
from jaxgait.control.interface import Controller
from jaxgait.core.params import ParamTable
from jaxgait.muscles import mtu as mus
from jaxgait.muscles.mtu import MuscleTable
from jaxgait.sim.trace import Events
from jaxgait.world.contact import ContactParams, ContactState

CONTACT_SITES = ("heel_r", "ball_r", "heel_l", "ball_l")
LEG_JOINTS = (("hip_r", "knee_r", "ankle_r"), ("hip_l", "knee_l", "ankle_l"))


#: Choices of :attr:`SimConfig.start_activation` and :attr:`SimConfig.start_delays`.
START_ACTIVATIONS = ("rest", "reflex")
START_DELAYS = ("sensors", "zero")
#: How a step gets the mass matrix and bias forces (:attr:`SimConfig.dynamics`).
DYNAMICS = ("mjx", "planar")


@dataclass(frozen=True)
class SimConfig:
    """Static rollout settings (everything that is not an optimised parameter).

    Attributes:
      duration: maximal simulated time [s] (time stopping criterion).
      d_lim: distance stopping criterion [m] (inf = none).
      e_lim: energy stopping criterion [J] (inf = none).
      log_dt: period of the decimated trace [s] (a multiple of the physics step).
      chunk_s: simulated time per while-loop chunk [s]; a batch stops at chunk ends.
      v0: initial forward speed of the whole body [m/s].
      pose: initial posture name (see :data:`POSES`).
      muscle_substeps: sub-steps of the CE-length ODE per physics step.
      ce_solve_iters: iterations of the backward-Euler CE solve after its first intersection
        (``solve_iters`` of :func:`jaxgait.muscles.mtu.muscle_step`; more is closer to the
        converged step and slower, see ``benchmarks/ce_solver_accuracy.py``).
      max_events: capacity of the touchdown event buffer.
      fall_hip_height: fall when the hip is lower than this above the ground [m].
      fall_pitch: fall when |trunk pitch| exceeds this [rad].
      start_activation: the muscles' activation at t = 0: ``"rest"`` (every muscle at the
        minimum 0.01, the thesis's A = 0 start) or ``"reflex"`` (the controller's own
        stimulation of the start sensors, iterated with the muscles' resting force to a fixed
        point, as SCONE's ``initialize_activations_from_controller``).
      start_delays: what the controller's delay lines hold at t = 0: ``"sensors"`` (the start
        sensors, as if the body had stood still in its start pose) or ``"zero"`` (the
        controller initialised on all-zero sensors, as Simulink transport delays whose
        initial output is 0).
      dynamics: where the step's mass matrix M and bias forces come from: ``"mjx"`` (MJX's
        kinematics, composite-rigid-body and recursive Newton-Euler passes,
        :meth:`Model.mass_and_forces`) or ``"planar"`` (the same rigid-body equations of the
        MJCF's bodies written for the planar tree, :meth:`jaxgait.body.planar.Body.mass_and_bias`:
        equal to MJX's to rounding, 1.5x faster a step at the training widths on the CPU,
        ``benchmarks/README.md``).  Documents written without the key (presets, run configs)
        were made with ``"mjx"`` and are evaluated with it.
    """

    duration: float = 20.0
    d_lim: float = math.inf
    e_lim: float = math.inf
    log_dt: float = 0.01
    chunk_s: float = 1.0
    v0: float = 1.3
    pose: str = "geyer"
    muscle_substeps: int = 1
    ce_solve_iters: int = mus.CE_SOLVE_ITERS
    max_events: int = 512
    fall_hip_height: float = 0.6
    fall_pitch: float = 1.0
    start_activation: str = "rest"
    start_delays: str = "sensors"
    dynamics: str = "mjx"

    def __post_init__(self):
        for name, ok in (
            ("start_activation", START_ACTIVATIONS),
            ("start_delays", START_DELAYS),
            ("dynamics", DYNAMICS),
        ):
            if getattr(self, name) not in ok:
                raise ValueError(
                    f"SimConfig.{name} must be one of {ok}, got {getattr(self, name)!r}"
                )
        for name, lo in (("muscle_substeps", 1), ("ce_solve_iters", 0), ("max_events", 1)):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < lo:
                raise ValueError(f"SimConfig.{name} must be an integer >= {lo}, got {v!r}")


#: Metabolic-rate models a rollout can integrate (:attr:`Model.metabolic`).
METABOLIC_MODELS = ("thesis", "wang2012")


#: Initial postures, Winter convention in degrees: (trunk pitch, (hip, knee, ankle) of the
#: stance leg (right), (hip, knee, ankle) of the swing leg (left)).  "geyer" is Geyer's
#: nms_model_ControlInit start (GH angles stance 85/175/175, swing 90/175/140 with the
#: stance foot flat, hence a 5 deg trunk lean); geyer_reference.md section 4.
POSES = {
    "geyer": (5.0, (5.0, 5.0, 5.0), (40.0, 5.0, 0.0)),
    # Thatte's ControlParams.m: the same but the swing hip at 150 deg (section 4)
    "thatte": (5.0, (5.0, 5.0, 5.0), (30.0, 5.0, 0.0)),
    # a running mid-stance (human running near 3 m/s, Novacheck 1998, rounded): the stance
    # knee bent 35 deg and the ankle dorsiflexed 20 deg under a foot about flat, the swing
    # leg behind and high with its knee bent 100 deg
    "run": (8.0, (20.0, 35.0, 20.0), (20.0, 100.0, -10.0)),
}


@struct.dataclass
class SimState:
    """Everything that evolves during a rollout (a pytree; batch it with vmap)."""

    qpos: jax.Array
    qvel: jax.Array
    t: jax.Array
    muscle: mus.MuscleState
    contact: ContactState
    gait: GaitState
    ctrl: Any  # the controller's own state (Controller.init)
    command_state: Any  # the command law's state (None without a law)
    energy: jax.Array
    lean_sum: jax.Array
    limit_sq: jax.Array  # time integral of the summed squared soft-limit torques [N^2 m^2 s]
    x0: jax.Array
    done: jax.Array
    fell: jax.Array
    end_t: jax.Array
    end_x: jax.Array
    end_energy: jax.Array
    end_lean: jax.Array
    end_limit_sq: jax.Array
    events: Events
    grf: jax.Array  # (2, 2) last ground force per leg (x, z) [N], for logging
    stim: jax.Array  # (2, M) last stimulation, for logging


@dataclass(frozen=True, eq=False)
class Model:
    """A body, its muscles, a controller, the contact law and the gait-phase detection
    (static data, closed over by jit)."""

    body: Body
    muscles: MuscleTable
    controller: Controller
    contact: ContactParams = field(default_factory=ContactParams)
    limits: SoftLimits = field(default_factory=SoftLimits)
    gait: GaitConfig = field(default_factory=GaitConfig)
    name: str = "fbl"
    #: The metabolic-rate model integrated into the rollout's energy: ``"thesis"`` (thesis
    #: eq. 2.41-2.44, :func:`jaxgait.muscles.energy.metabolic_rate`) or ``"wang2012"``
    #: (Wang et al. 2012 section 5.1, :func:`jaxgait.muscles.effort.wang_metabolic_rate`).
    metabolic: str = "thesis"

    def __post_init__(self):
        if self.metabolic not in METABOLIC_MODELS:
            raise ValueError(
                f"model {self.name!r}: unknown metabolic model {self.metabolic!r}; "
                f"valid: {', '.join(METABOLIC_MODELS)}"
            )
        n = len(self.muscles.names)
        if self.controller.n_muscles != n:
            raise ValueError(
                f"model {self.name!r}: controller {self.controller.name!r} stimulates "
                f"{self.controller.n_muscles} muscles per leg, the muscle table has {n}"
            )

    @property
    def table(self) -> ParamTable:
        """The controller's parameter table (what the optimisers search)."""
        return self.controller.table

    @property
    def dt(self) -> float:
        return self.body.dt

    @property
    def mjx_model(self):
        return self.body.mjx_model

    @cached_property
    def _ids(self):
        b = self.body
        # plain int32 / int indices: valid in float32 and float64 (x64) runs alike
        sites = np.array([b.site_id(n) for n in CONTACT_SITES], np.int32)
        feet = np.array([b.mj_model.body(n).id for n in ("foot_r", "foot_l")], np.int32)
        trunk = int(b.mj_model.body("trunk").id)
        legq = np.array([[b.qpos_adr(j) for j in leg] for leg in LEG_JOINTS], np.int32)
        return sites, feet, trunk, legq

    @cached_property
    def thigh_ids(self) -> np.ndarray:
        """Body ids of the right and left thighs."""
        return np.array([self.body.mj_model.body(n).id for n in ("thigh_r", "thigh_l")])

    @cached_property
    def sheet_masses(self) -> tuple[float, float]:
        """(mass of a leg below the thigh pressure sheet, HAT mass) [kg] for the sheet's load
        signal (:func:`~jaxgait.control.gait.thigh_sheet_load`): the thigh split by length at
        ``gait.sheet_below_hip`` below the hip, plus shank and foot."""
        m = self.body.mj_model
        thigh, shank, foot = (m.body(f"{n}_r") for n in ("thigh", "shank", "foot"))
        length = float(np.linalg.norm(shank.pos))  # hip to knee
        below = 1.0 - self.gait.sheet_below_hip / length
        leg = float(thigh.mass[0]) * below + float(shank.mass[0]) + float(foot.mass[0])
        return leg, float(m.body("trunk").mass[0])

    @cached_property
    def dof_parents(self) -> tuple[int, ...]:
        """Parent of each degree of freedom in the kinematic tree (-1: none), MuJoCo's
        ``dof_parentid``: the sparsity of M, used by the tree-structured solves
        (:func:`jaxgait.core.linalg.spd_solve`)."""
        return tuple(int(p) for p in self.body.mj_model.dof_parentid)

    @property
    def _template(self):
        """Empty MJX data, one per float mode (see :attr:`Body.mjx_model`)."""
        from mujoco import mjx

        cache = self.__dict__.setdefault("_templates", {})
        key = bool(jax.config.jax_enable_x64)
        if key not in cache:
            # concrete even if first used while tracing; on this process's first device
            # (under jax.distributed the default placement may be another process's)
            with jax.ensure_compile_time_eval():
                cache[key] = mjx.make_data(self.mjx_model, device=jax.local_devices()[0])
        return cache[key]

    def mass_and_forces(self, qpos, qvel, qfrc_applied):
        """Joint-space mass matrix M (nv, nv) and smooth force (nv,) from MJX.

        MJX's kinematics, composite-rigid-body inertia and recursive Newton-Euler give M
        and the bias (Coriolis, centrifugal, gravity) forces; the smooth force is
        qfrc_applied + qfrc_passive - qfrc_bias, as in ``mjx.forward`` (whose own dense
        factorisation and solve are left to :mod:`jaxgait.core.linalg`, which is much faster
        under ``vmap`` on the CPU).  The MJCF's constraint solver is disabled.  These passes
        are MJX's internal functions (``mujoco.mjx._src``); ``tests/test_linalg.py`` checks the
        result against ``mjx.forward`` so that an MJX upgrade that changes them is caught.
        """
        from mujoco.mjx._src import passive, smooth

        m = self.mjx_model
        d = self._template.replace(qpos=qpos, qvel=qvel, qfrc_applied=qfrc_applied)
        d = smooth.kinematics(m, d)
        d = smooth.com_pos(m, d)
        d = smooth.crb(m, d)
        d = smooth.com_vel(m, d)
        d = passive.passive(m, d)
        d = smooth.rne(m, d)
        return d._impl.M, qfrc_applied + d.qfrc_passive - d.qfrc_bias

    def mass_and_forces_of(self, dynamics: str, qpos, qvel, qfrc_applied):
        """M and the smooth force as :meth:`mass_and_forces`, from ``dynamics`` (``"mjx"`` or
        ``"planar"``, :attr:`SimConfig.dynamics`)."""
        if dynamics == "planar":
            M, bias = self.body.mass_and_bias(qpos, qvel)
            return M, qfrc_applied - bias
        if dynamics != "mjx":
            raise ValueError(f"dynamics must be one of {DYNAMICS}, got {dynamics!r}")
        return self.mass_and_forces(qpos, qvel, qfrc_applied)

    @property
    def mass(self) -> float:
        return self.body.total_mass

    @cached_property
    def leg_length(self) -> float:
        """Hip-to-ankle length of the straight right leg (thigh + shank) [m]."""
        m = self.body.mj_model
        shank, foot = m.body("shank_r").id, m.body("foot_r").id
        return float(np.linalg.norm(self.body.pos[shank]) + np.linalg.norm(self.body.pos[foot]))

    @cached_property
    def foot_length(self) -> float:
        """Heel-to-ball distance of the right foot [m]."""
        b = self.body
        return float(
            np.linalg.norm(b.site_pos[b.site_id("ball_r")] - b.site_pos[b.site_id("heel_r")])
        )

    # ------------------------------------------------------------- kinematics
    def _point_parts(self, qpos, push_h):
        b = self.body
        sites, feet, trunk, _ = self._ids
        o, a = b.frames(qpos)
        sb = b.site_body[sites].astype(np.int32)
        cp = b._local_to_world(o[sb], a[sb], jnp.asarray(b.site_pos[sites], qpos.dtype))
        w = b._local_to_world(o[1:], a[1:], jnp.asarray(b.ipos[1:], qpos.dtype))
        push = b._local_to_world(o[trunk], a[trunk], jnp.stack([jnp.zeros_like(push_h), push_h]))
        return o, cp, w, push

    def _com(self, w):
        m = jnp.asarray(self.body.mass[1:], w.dtype)
        return (m[:, None] * w).sum(0) / m.sum()

    def points(self, qpos, push_h):
        """(9, 2): heel_r, ball_r, heel_l, ball_l, ankle_r, ankle_l, hip, CoM, push point."""
        _, feet, trunk, _ = self._ids
        o, cp, w, push = self._point_parts(qpos, push_h)
        com = self._com(w)
        return jnp.concatenate([cp, o[feet], o[trunk][None], com[None], push[None]], 0)

    def points_jacobian(self, qpos, push_h):
        """:meth:`points` (9, 2) and their Jacobian d points / d qpos (9, 2, nv), analytic."""
        b = self.body
        sites, feet, trunk, _ = self._ids
        o, cp, w, push = self._point_parts(qpos, push_h)
        nb = len(b.parent)
        owners = (
            tuple(int(i) for i in b.site_body[sites])
            + tuple(int(i) for i in feet)
            + (trunk,)
            + tuple(range(1, nb))
            + (trunk,)
        )
        allp = jnp.concatenate([cp, o[feet], o[trunk][None], w, push[None]], 0)
        jall = b.point_jacobian(o, allp, owners)
        m = jnp.asarray(b.mass[1:] / b.mass[1:].sum(), qpos.dtype)
        jcom = jnp.einsum("b,bkn->kn", m, jall[7 : 7 + nb - 1])
        pts = jnp.concatenate([cp, o[feet], o[trunk][None], self._com(w)[None], push[None]], 0)
        jac = jnp.concatenate([jall[:7], jcom[None], jall[-1:]], 0)
        return pts, jac


#: The muscle table of each muscle count per leg (:func:`planar_model`).
MUSCLE_TABLES: dict[int, MuscleTable] = {7: mus.GEYER7, 8: mus.WANG8}


def planar_model(
    controller: Controller,
    timestep: float | None = None,
    name: str | None = None,
    muscles: MuscleTable | None = None,
    metabolic: str | None = None,
    gait: GaitConfig | None = None,
) -> Model:
    """``controller`` on the planar Geyer body (``models/fbl_planar.xml``).

    ``muscles`` defaults to the table of the controller's muscle count
    (:data:`MUSCLE_TABLES`: 7 -> GEYER7, 8 -> WANG8).  ``timestep`` [s] overrides the MJCF's
    physics step (delays must stay whole steps).  ``gait`` is the phase detection and the
    leg-load signal (default :class:`~jaxgait.control.gait.GaitConfig`).  ``metabolic``
    (:attr:`Model.metabolic`) defaults to Wang's model for the 8-muscle table (Wang's
    controller is optimised on his effort) and to the thesis's for the others.
    """
    if muscles is None:
        if controller.n_muscles not in MUSCLE_TABLES:
            raise ValueError(
                f"controller {controller.name!r} stimulates {controller.n_muscles} muscles per "
                f"leg; no default muscle table for that count (known: "
                f"{sorted(MUSCLE_TABLES)}); pass muscles=<MuscleTable>"
            )
        muscles = MUSCLE_TABLES[controller.n_muscles]
    if metabolic is None:
        metabolic = "wang2012" if muscles.names == mus.WANG8.names else "thesis"
    body = load_body("fbl_planar", timestep)
    return Model(
        body=body,
        muscles=muscles,
        controller=controller,
        name=name or controller.name,
        metabolic=metabolic,
        gait=GaitConfig() if gait is None else gait,
    )
