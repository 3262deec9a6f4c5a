"""One pure step of body + muscles + reflex controller + contact, and chunked rollouts.

``step(model, params, env, state) -> state`` advances one physics step of ``model.dt``:

1. planar kinematics of the contact points, ankles, hip, CoM and push point, with their
   analytic Jacobians;
2. muscle-tendon forces and moment arms from the joint angles, the push of ``env.pushes``;
3. Geyer ground contact against ``env.terrain`` and the ligament soft limits as stiff rows;
4. MJX multibody dynamics (mass matrix and bias forces; constraint solver off);
5. the rows' damping resolved linearly-implicitly (:mod:`jaxgait.sim.rows`);
6. ground-load filter, phases, sensors -> neural delay lines -> stimulation law;
7. semi-implicit Euler of the body;
8. muscle activation / CE-length integration and metabolic energy.

``rollout`` scans the step in chunks inside a ``while_loop`` that stops once the rollout
(or, under ``vmap``, every rollout of the batch) is done, logging a decimated
:class:`~jaxgait.sim.trace.Trace`, the touchdown :class:`~jaxgait.sim.trace.Events` and a
:class:`~jaxgait.sim.trace.Summary`.  It is ``vmap``-able over parameter vectors and
environments; ``jit`` it at the edge (see :func:`make_rollout`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property, partial

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxgait.body.joints import SoftLimits, q_to_phi
from jaxgait.body.planar import Body, load_body
from jaxgait.control.fbl import (
    ReflexConfig,
    ReflexState,
    delay_taps_for,
    delayed_stimulation,
    fbl_stimulation,
    init_reflex,
    sensor_array,
    update_phase,
)
from jaxgait.core.linalg import spd_solve
from jaxgait.core.params import FBL, ParamTable
from jaxgait.muscles import energy as energy_mod
from jaxgait.muscles import mtu as mus
from jaxgait.sim.rows import implicit_row_velocities
from jaxgait.sim.trace import Events, Summary, Trace
from jaxgait.world.contact import (
    ContactParams,
    ContactState,
    contact_finalize,
    contact_rows,
    init_contact,
)
from jaxgait.world.envs import Env, push_force

CONTACT_SITES = ("heel_r", "ball_r", "heel_l", "ball_l")
LEG_JOINTS = (("hip_r", "knee_r", "ankle_r"), ("hip_l", "knee_l", "ankle_l"))


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

    def __post_init__(self):
        for name, lo in (("muscle_substeps", 1), ("ce_solve_iters", 0), ("max_events", 1)):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < lo:
                raise ValueError(f"SimConfig.{name} must be an integer >= {lo}, got {v!r}")


#: Initial postures, Winter convention in degrees: (trunk pitch, (hip, knee, ankle) of the
#: stance leg (right), (hip, knee, ankle) of the swing leg (left)).  "geyer" is Geyer's
#: nms_model_ControlInit start (GH angles stance 85/175/175, swing 90/175/140 with the
#: stance foot flat, hence a 5 deg trunk lean); geyer_reference.md section 4.
POSES = {
    "geyer": (5.0, (5.0, 5.0, 5.0), (40.0, 5.0, 0.0)),
}


@struct.dataclass
class SimState:
    """Everything that evolves during a rollout (a pytree; batch it with vmap)."""

    qpos: jax.Array
    qvel: jax.Array
    t: jax.Array
    muscle: mus.MuscleState
    contact: ContactState
    reflex: ReflexState
    energy: jax.Array
    lean_sum: jax.Array
    x0: jax.Array
    done: jax.Array
    fell: jax.Array
    end_t: jax.Array
    end_x: jax.Array
    end_energy: jax.Array
    end_lean: jax.Array
    events: Events
    grf: jax.Array  # (2, 2) last ground force per leg (x, z) [N], for logging
    stim: jax.Array  # (2, M) last stimulation, for logging


@dataclass(frozen=True, eq=False)
class Model:
    """A body, its muscles, the controller and the contact law (static, closed over by jit)."""

    body: Body
    muscles: object
    table: ParamTable
    law: Callable = fbl_stimulation
    contact: ContactParams = field(default_factory=ContactParams)
    limits: SoftLimits = field(default_factory=SoftLimits)
    reflex: ReflexConfig = field(default_factory=ReflexConfig)
    name: str = "fbl"

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
            with jax.ensure_compile_time_eval():  # concrete even if first used while tracing
                cache[key] = mjx.make_data(self.mjx_model)
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

    @property
    def mass(self) -> float:
        return self.body.total_mass

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


def make_model(name: str = "fbl", timestep: float | None = None) -> Model:
    """The FBL model on the planar Geyer body with the 7-muscle Geyer table.

    ``timestep`` [s] overrides the MJCF's physics step (delays must stay whole steps).
    """
    if name == "fblplus":
        from jaxgait.control.fblplus import make_fblplus_model

        return make_fblplus_model(timestep)
    if name != "fbl":
        raise KeyError(f"unknown model {name!r}; available: fbl, fblplus")
    body = load_body("fbl_planar", timestep)
    return Model(body=body, muscles=mus.GEYER7, table=FBL, name="fbl")


# ------------------------------------------------------------------------- init
def initial_state(model: Model, params, env: Env, cfg: SimConfig) -> SimState:
    """Posture ``cfg.pose`` with the stance foot on the ground, moving at ``cfg.v0``."""
    dtype = jnp.asarray(params).dtype
    if cfg.pose not in POSES:
        raise KeyError(f"unknown pose {cfg.pose!r}; available: {sorted(POSES)}")
    pitch, stance, swing = POSES[cfg.pose]
    _, _, _, legq = model._ids
    q = np.zeros(model.body.mj_model.nq)
    q[2] = np.deg2rad(pitch)
    q[legq[0]] = np.deg2rad(stance)
    q[legq[1]] = np.deg2rad(swing)
    qpos = jnp.asarray(q, dtype)
    pts = model.points(qpos, jnp.zeros((), dtype))
    # lift the body so the lowest point of the stance foot is on the ground
    ground = env.terrain.height(pts[:2, 0])
    lift = jnp.max(ground - pts[:2, 1])
    qpos = qpos.at[1].add(lift)
    qvel = jnp.zeros(model.body.mj_model.nv, dtype).at[0].set(cfg.v0)
    pts = model.points(qpos, jnp.zeros((), dtype))

    table = model.muscles
    legq_j = jnp.asarray(legq)
    phi = q_to_phi(qpos[legq_j])
    l_mtu = mus.mtu_length(table, phi)
    l_ce = mus.init_lce(table, l_mtu)
    act = jnp.full_like(l_ce, 0.01)
    mstate = mus.MuscleState(act=act, l_ce=l_ce)
    f_mtu = mus.mtu_force(table, act, l_ce, l_mtu)
    load0 = jnp.asarray([1.0, 0.0], dtype)
    stance0 = jnp.asarray([True, False])
    sensors0 = sensor_array(
        f_mtu / jnp.maximum(jnp.asarray(table.f_max, dtype), 1e-9),
        l_ce / jnp.asarray(table.l_opt, dtype),
        load0,
        stance0,
        jnp.zeros(2, bool),
        qpos[2],
        qvel[2],
        phi,
        jnp.zeros_like(phi),
        jnp.full((2,), qpos[2]),
        (pts[7, 0] - pts[[1, 3], 0]) / model.foot_length,
    )
    rstate = init_reflex(model.reflex, model.dt, sensors0, load0, stance0, qpos[2])
    E = cfg.max_events
    events = Events(
        t=jnp.zeros(E, dtype),
        leg=jnp.zeros(E, jnp.int32),
        x_td=jnp.zeros(E, dtype),
        x_other=jnp.zeros(E, dtype),
        n=jnp.zeros((), jnp.int32),
    )
    zero = jnp.zeros((), dtype)
    return SimState(
        qpos=qpos,
        qvel=qvel,
        t=zero,
        muscle=mstate,
        contact=init_contact(pts[:4]),
        reflex=rstate,
        energy=zero,
        lean_sum=zero,
        x0=pts[7, 0],
        done=jnp.zeros((), bool),
        fell=jnp.zeros((), bool),
        end_t=zero,
        end_x=pts[7, 0],
        end_energy=zero,
        end_lean=zero,
        events=events,
        grf=jnp.zeros((2, 2), dtype),
        stim=jnp.full((2, len(table.names)), 0.01, dtype),
    )


# ------------------------------------------------------------------------- step
def _record_touchdowns(ev: Events, td, t, ankle_x) -> Events:
    """Append this step's touchdowns (at most one per leg) to the event buffer, in place."""
    for leg in (0, 1):
        i = jnp.minimum(ev.n, ev.t.shape[0] - 1)
        write = td[leg] & (ev.n < ev.t.shape[0])
        put = lambda buf, v, i=i, write=write: buf.at[i].set(jnp.where(write, v, buf[i]))
        ev = Events(
            t=put(ev.t, t),
            leg=put(ev.leg, jnp.asarray(leg, ev.leg.dtype)),
            x_td=put(ev.x_td, ankle_x[leg]),
            x_other=put(ev.x_other, ankle_x[1 - leg]),
            n=ev.n + td[leg].astype(jnp.int32),
        )
    return ev


def _limit_rows(lim: SoftLimits, phi):
    """Soft limits (eq. 2.38) as rows in q space: torque a - c q_dot on each leg joint.

    q = offset - phi, so an upper-phi violation Delta pushes q up: a = k Delta, and the
    damping k Delta / omega_ref opposes q_dot; symmetrically for the lower limit.
    """
    lo = jnp.asarray(lim.lower, phi.dtype)
    hi = jnp.asarray(lim.upper, phi.dtype)
    over = jnp.maximum(phi - hi, 0.0)
    under = jnp.maximum(lo - phi, 0.0)
    a = lim.k * (over - under)
    c = lim.k * (over + under) / lim.omega_ref
    return a, c


def step(model: Model, cfg: SimConfig, params, env: Env, s: SimState) -> SimState:
    """Advance the whole body + controller by one physics step (pure)."""
    dt = model.dt
    dtype = s.qpos.dtype
    nv = s.qvel.shape[0]
    p = model.table.unpack(params)
    table = model.muscles
    _, _, _, legq = model._ids
    legq_flat = legq.reshape(-1)
    legq = jnp.asarray(legq)

    # 1. planar kinematics: positions and analytic Jacobians of the points
    push_fx, push_fz, push_h = push_force(env.pushes, s.t)
    pts, jac = model.points_jacobian(s.qpos, push_h)
    vel = jac @ s.qvel

    # 2. muscles (forces from the current state) and the explicit generalised forces
    q_leg = s.qpos[legq]
    phi = q_to_phi(q_leg)
    dphi = -s.qvel[legq]
    l_mtu = mus.mtu_length(table, phi)
    f_mtu = mus.mtu_force(table, s.muscle.act, s.muscle.l_ce, l_mtu)
    tau_q = -mus.joint_torques(table, phi, f_mtu)  # about q (Winter convention)
    qfrc = jnp.zeros(nv, dtype).at[legq].add(tau_q)
    qfrc = qfrc + jac[8].T @ jnp.stack([push_fx, push_fz])

    # 3. stiff spring-dampers (ground contact, soft limits) as rows
    crow = contact_rows(model.contact, env.terrain, s.contact, pts[:4], vel[:4])
    a_lim, c_lim = _limit_rows(model.limits, phi)
    a_lim, c_lim = a_lim.reshape(-1), c_lim.reshape(-1)
    j_n = jnp.einsum("pk,pkn->pn", crow.normal, jac[:4])
    j_t = jnp.einsum("pk,pkn->pn", crow.tangent, jac[:4])
    j_l = jnp.zeros((6, nv), dtype).at[jnp.arange(6), legq_flat].set(1.0)
    J = jnp.concatenate([j_n, j_t, j_l], 0)
    a = jnp.concatenate([crow.a_n, crow.a_t, a_lim])
    c = jnp.concatenate([crow.c_n, crow.c_t, c_lim])

    # 4. MJX multibody dynamics: mass matrix M and bias forces (constraint solver off)
    M, qfrc_smooth = model.mass_and_forces(s.qpos, s.qvel, qfrc)

    # 5. implicit rows, then the forces each law allows, applied through M
    y = implicit_row_velocities(J, a, c, M, s.qvel, qfrc_smooth, dt, model.dof_parents)
    f_c, cstate, _ = contact_finalize(model.contact, crow, s.contact, pts[:4], y[:4], y[4:8])
    f_lim = a_lim - c_lim * y[8:]
    f_lim = jnp.where(a_lim > 0, jnp.maximum(f_lim, 0.0), jnp.minimum(f_lim, 0.0))
    f_rows = jnp.concatenate(
        [(f_c * crow.normal).sum(-1), (f_c * crow.tangent).sum(-1), f_lim]
    )  # row components of the final forces (normal and tangent are orthonormal)
    qacc = spd_solve(M, qfrc_smooth + jnp.sum(J * f_rows[:, None], axis=0), model.dof_parents)
    grf = f_c.reshape(2, 2, 2).sum(1)  # per leg (x, z)
    mg = model.mass * 9.81

    # 6. controller: ground-load filter, phases, sensors -> delay lines -> stimulation
    rstate, stance, td, ds = update_phase(model.reflex, s.reflex, grf[:, 1], mg, s.t, s.qpos[2], dt)
    sensors = sensor_array(
        f_mtu / jnp.maximum(jnp.asarray(table.f_max, dtype), 1e-9),
        s.muscle.l_ce / jnp.asarray(table.l_opt, dtype),
        rstate.load,
        stance,
        ds,
        s.qpos[2],
        s.qvel[2],
        phi,
        dphi,
        rstate.theta_to,
        (pts[7, 0] - pts[[1, 3], 0]) / model.foot_length,
    )
    taps = delay_taps_for(model.reflex, dt)
    stim, lines = delayed_stimulation(p, rstate, sensors, model.law, taps)
    rstate = rstate.replace(lines=lines)

    # 7. semi-implicit Euler (as MuJoCo's Euler integrator; all joints are hinge/slide)
    qvel = s.qvel + dt * qacc
    qpos = s.qpos + dt * qvel

    # 8. muscle state over the same step, against the MTU lengths at its end (the joints
    # have moved with the tendon forces of its start), and metabolic energy
    l_mtu_end = mus.mtu_length(table, q_to_phi(qpos[legq]))
    mstate, info = mus.muscle_step(
        table, s.muscle, stim, l_mtu_end, dt, cfg.muscle_substeps, solve_iters=cfg.ce_solve_iters
    )
    rate = energy_mod.metabolic_rate(
        table, info["stim"], info["act"], info["l_ce"], info["v_ce"], info["f_ce"], info["f_mtu"]
    ).sum()

    # time on the step grid, t = n dt: summing dt in float32 drifted by 27 ms over 60 s
    t = (jnp.round(s.t / dt) + 1.0) * dt
    energy = s.energy + rate * dt
    lean_sum = s.lean_sum + s.qpos[2] * dt
    events = _record_touchdowns(s.events, td & ~s.done, s.t, pts[4:6, 0])

    # 9. fall and stopping criteria; the summary freezes at the first "done"
    hip = pts[6]
    hip_clear = hip[1] - env.terrain.height(hip[0])
    bad = ~jnp.all(jnp.isfinite(qpos)) | ~jnp.all(jnp.isfinite(qvel))
    fell_now = (hip_clear < cfg.fall_hip_height) | (jnp.abs(s.qpos[2]) > cfg.fall_pitch) | bad
    dist = pts[7, 0] - s.x0
    stop_now = (t >= cfg.duration - 0.5 * dt) | (dist >= cfg.d_lim) | (energy >= cfg.e_lim)
    done_now = (fell_now | stop_now) & ~s.done
    freeze = lambda new, old: jnp.where(done_now, new, old)
    return SimState(
        qpos=qpos,
        qvel=qvel,
        t=t,
        muscle=mstate,
        contact=cstate,
        reflex=rstate,
        energy=energy,
        lean_sum=lean_sum,
        x0=s.x0,
        done=s.done | done_now,
        fell=s.fell | (done_now & fell_now),
        end_t=freeze(t, s.end_t),
        end_x=freeze(pts[7, 0], s.end_x),
        end_energy=freeze(energy, s.end_energy),
        end_lean=freeze(lean_sum, s.end_lean),
        events=events,
        grf=grf,
        stim=stim,
    )


# ---------------------------------------------------------------------- rollout
def _log_row(model: Model, s: SimState, alive) -> Trace:
    pts, lin = jax.linearize(lambda q: model.points(q, jnp.zeros((), q.dtype)), s.qpos)
    com_vel = lin(s.qvel)[7]
    return Trace(
        t=s.t,
        qpos=s.qpos,
        com=pts[7],
        com_vel=com_vel,
        grf=s.grf,
        stance=s.reflex.stance,
        act=s.muscle.act,
        stim=s.stim,
        energy=s.energy,
        alive=alive,
    )


def rollout_steps(cfg: SimConfig, dt: float) -> tuple[int, int, int]:
    """(physics steps per log row, rows per chunk, number of chunks)."""
    log_every = round(cfg.log_dt / dt)
    if log_every < 1 or abs(log_every * dt - cfg.log_dt) > 1e-9:
        raise ValueError(f"log_dt {cfg.log_dt} must be a whole multiple of dt {dt}")
    rows_per_chunk = max(1, round(cfg.chunk_s / cfg.log_dt))
    n_rows = math.ceil(cfg.duration / cfg.log_dt)
    n_chunks = math.ceil(n_rows / rows_per_chunk)
    return log_every, rows_per_chunk, n_chunks


def rollout(model: Model, cfg: SimConfig, params, env: Env):
    """Simulate one parameter set in one environment.

    Returns (trace: Trace with leading time axis, events: Events, summary: Summary,
    final state).  Stops at the first chunk end after the rollout is done.
    """
    log_every, rpc, n_chunks = rollout_steps(cfg, model.dt)
    s0 = initial_state(model, params, env, cfg)
    row0 = _log_row(model, s0, jnp.ones((), bool))
    trace0 = jax.tree.map(lambda x: jnp.zeros((n_chunks * rpc,) + x.shape, x.dtype), row0)

    def one_row(s, _):
        s = jax.lax.fori_loop(0, log_every, lambda i, s: step(model, cfg, params, env, s), s)
        return s, _log_row(model, s, ~s.done)

    def chunk(carry):
        k, s, trace = carry
        s, rows = jax.lax.scan(one_row, s, None, length=rpc)
        trace = jax.tree.map(
            lambda buf, r: jax.lax.dynamic_update_slice_in_dim(buf, r, k * rpc, 0), trace, rows
        )
        return k + 1, s, trace

    def cond(carry):
        k, s, _ = carry
        return (k < n_chunks) & ~s.done

    _, s, trace = jax.lax.while_loop(cond, chunk, (jnp.zeros((), jnp.int32), s0, trace0))
    n_rows = math.ceil(cfg.duration / cfg.log_dt)
    trace = jax.tree.map(lambda x: x[:n_rows], trace)
    # a rollout that never reached "done" is closed here (the duration normally stops it)
    summary = Summary(
        duration=jnp.where(s.done, s.end_t, s.t),
        distance=jnp.where(s.done, s.end_x, model.points(s.qpos, 0.0 * s.t)[7, 0]) - s.x0,
        fell=s.fell,
        energy=jnp.where(s.done, s.end_energy, s.energy),
        trunk_lean_sum=jnp.where(s.done, s.end_lean, s.lean_sum),
        mass=jnp.asarray(model.mass, s.t.dtype),
    )
    return trace, s.events, summary, s


def make_rollout(model: Model, cfg: SimConfig, batched: bool = True):
    """jit-compiled rollout; with ``batched`` it maps over (params (B, D), env batch)."""
    f = partial(rollout, model, cfg)
    if batched:
        f = jax.vmap(f)
    return jax.jit(f)
