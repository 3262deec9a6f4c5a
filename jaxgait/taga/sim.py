"""State, one pure step and ``lax.scan`` rollouts of the Taga et al. (1991) biped.

Per step of length dt (all forces from the state at the start of the step):

  1. ankle positions/velocities (forward-mode AD through :mod:`jaxgait.body.planar`);
  2. ground forces, Appendix A, with the touchdown reset of the rest point
     (:mod:`jaxgait.taga.ground`) and the somatic sense h(F_g2), h(F_g4);
  3. feedback Feed1-12 (Appendix C) and torques T_r1..T_r6 from the current outputs y;
  4. joint viscosity, knee damper and stop (Appendix A) -> generalised forces (J^T, vjp);
  5. MJX multibody step (MuJoCo semi-implicit Euler, constraints and contacts off);
  6. neural ODE eq. 6 advanced by explicit Euler (or RK4, ``Options.neural_integrator``)
     with the same dt and the feedback of step 3.

The paper integrated eqs. 4 and 6 with fourth-order Runge-Kutta-Gill (step not given);
here the default dt = 0.5 ms (the MJCF timestep), checked against 0.25 ms (README).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property, partial

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct
from mujoco import mjx

from jaxgait.control.commands import Command, CommandError, Schedule
from jaxgait.taga import ground, model, network
from jaxgait.taga.model import Options, TagaBody, TagaParams
from jaxgait.world.terrain import Terrain

EVENT_CAPACITY = 512


@struct.dataclass
class Push:
    """External forces held on for t0 <= t < t1 (Fig. 7 perturbations).

    Attributes:
      force: (3, 2) world force (x, z) [N] on the hip point (link 1), the right shank
        centre of mass and the left shank centre of mass.
      t0, t1: () on / off time [s].
    """

    force: jax.Array
    t0: jax.Array
    t1: jax.Array


def no_push(dtype=jnp.float32) -> Push:
    return Push(
        force=jnp.zeros((3, 2), dtype), t0=jnp.asarray(0.0, dtype), t1=jnp.asarray(0.0, dtype)
    )


def push_on(site: str, fx: float, t0: float, duration: float, dtype=jnp.float32) -> Push:
    """A horizontal push ``fx`` [N] on ``site`` in {"hip", "shank_r", "shank_l"}."""
    k = ("hip", "shank_r", "shank_l").index(site)
    f = np.zeros((3, 2))
    f[k, 0] = fx
    return Push(
        force=jnp.asarray(f, dtype), t0=jnp.asarray(t0, dtype), t1=jnp.asarray(t0 + duration, dtype)
    )


@struct.dataclass
class Events:
    """Touchdowns (rest-point resets) recorded at the physics rate, capacity E.

    Attributes:
      t: (E,) time [s]; leg: (E,) 0 right / 1 left; x: (E,) touchdown point x0 [m];
      n: () number of touchdowns so far (those beyond E are not stored).
    """

    t: jax.Array
    leg: jax.Array
    x: jax.Array
    n: jax.Array


@struct.dataclass
class TagaState:
    """Whole simulation state.

    Attributes:
      data: MJX data (qpos = (x_hip, z_hip, hip_r, knee_r, hip_l, knee_l)).
      neural: Matsuoka neuron states.
      ground: ground contact memory (rest points).
      events: touchdown record.
      t: () time [s] (= n_steps * dt, so it does not accumulate rounding).
      n_steps: () number of steps taken, int32.
      fell: () the biped has fallen (state frozen from then on), bool.
      t_end: () time of the fall, or +inf.
    """

    data: mjx.Data
    neural: network.NeuralState
    ground: ground.GroundState
    events: Events
    t: jax.Array
    n_steps: jax.Array
    fell: jax.Array
    t_end: jax.Array


@struct.dataclass
class Log:
    """Decimated samples, one row per ``log_every`` steps; shape (T, ...).

    Attributes:
      t: time at the end of the interval [s]; qpos, qvel: (T, 6);
      u: (T, 12) neuron inner states; contact: (T, 2) ankle below terrain;
      grf: (T, 2, 2) ground force (x, y) [N]; torque: (T, 6) T_r1..T_r6 [N m];
      double: (T,) fraction of the interval's steps with both ankles in contact;
      flight: (T,) fraction with neither; alive: (T,) not fallen; u0: (T,) tonic input.
    """

    t: jax.Array
    qpos: jax.Array
    qvel: jax.Array
    u: jax.Array
    contact: jax.Array
    grf: jax.Array
    torque: jax.Array
    double: jax.Array
    flight: jax.Array
    alive: jax.Array
    u0: jax.Array


@dataclass(frozen=True, eq=False)
class Taga:
    """The simulator: static model, options and time step (closed over by ``jit``).

    Use :meth:`init` for the Appendix E state, :meth:`step` for one step and
    :meth:`rollout` for a scanned simulation.  Nothing here is batched: ``vmap`` the
    rollout over parameters / terrains / pushes.
    """

    tb: TagaBody = field(default_factory=model.load)
    options: Options = field(default_factory=Options)
    dt: float | None = None  # None: the MJCF timestep

    @cached_property
    def timestep(self) -> float:
        return float(self.dt if self.dt is not None else self.tb.body.dt)

    @cached_property
    def mjx_model(self):
        m = self.tb.body.mj_model
        if abs(m.opt.timestep - self.timestep) > 0:
            m = _copy_with_timestep(m, self.timestep)
        return mjx.put_model(m)

    # ------------------------------------------------------------------ state
    def init(
        self, qpos=None, qvel=None, neural=None, dtype=jnp.float32, event_capacity=EVENT_CAPACITY
    ) -> TagaState:
        """Appendix E: x1 = 0, x2 = 1.09, x5 = x11 = 0.45 pi, x8 = x14 = 0.57 pi, all
        velocities zero, u_i = v_i = 0 (or the given posture / neural state).
        ``event_capacity`` touchdowns are stored (about 4 per second of gait)."""
        q = self.tb.keyframe_qpos if qpos is None else np.asarray(qpos)
        dq = np.zeros_like(q) if qvel is None else np.asarray(qvel)
        data = mjx.make_data(self.mjx_model)
        data = data.replace(
            qpos=jnp.asarray(q, data.qpos.dtype), qvel=jnp.asarray(dq, data.qvel.dtype)
        )
        e = int(event_capacity)
        ev = Events(
            t=jnp.zeros(e, dtype),
            leg=jnp.zeros(e, jnp.int32),
            x=jnp.zeros(e, dtype),
            n=jnp.asarray(0, jnp.int32),
        )
        return TagaState(
            data=data,
            neural=network.zeros(dtype) if neural is None else neural,
            ground=ground.initial(dtype),
            events=ev,
            t=jnp.asarray(0.0, dtype),
            n_steps=jnp.asarray(0, jnp.int32),
            fell=jnp.asarray(False),
            t_end=jnp.asarray(jnp.inf, dtype),
        )

    # ------------------------------------------------------------------ step
    def forces(self, params: TagaParams, state: TagaState, terrain: Terrain, push: Push):
        """Everything computed from the state at the start of a step (items 1-4 above).

        Returns:
          dict with qfrc (6,), feed (12,), grf (2, 2), contact (2,), torque (6,),
          ground (new GroundState), touchdown (2,).
        """
        body, tb = self.tb.body, self.tb
        qpos, qvel = state.data.qpos, state.data.qvel
        apos, avel = body.sites_and_velocities(qpos, qvel, tb.ankle_ids)
        fg, gstate, td = ground.contact_forces(
            apos, avel, state.ground, terrain, params.k_g, params.b_g
        )
        c = ground.somatic_sense(fg)
        th, dth = tb.angles_and_rates(qpos, qvel)
        feed = params.feedback_gain * network.feedback(th, dth[2:], c, params.a)
        tr = network.torques(state.neural.y, c, params.p)
        seg = model.joint_torques(th, dth, tr, params, self.options.knee_stop)
        qfrc = tb.segment_torques_to_qfrc(qpos, seg) + body.site_forces_to_qfrc(
            qpos, fg, tb.ankle_ids
        )
        on = (state.t >= push.t0) & (state.t < push.t1)
        qfrc_push = body.site_forces_to_qfrc(qpos, push.force, tb.push_ids)
        qfrc = qfrc + jnp.where(on, qfrc_push, 0.0)
        return dict(qfrc=qfrc, feed=feed, grf=fg, contact=c, torque=tr, ground=gstate, touchdown=td)

    def step(self, params: TagaParams, state: TagaState, terrain: Terrain, push: Push, u0=None):
        """Advance by one time step dt.  ``u0`` overrides ``params.u0`` (for sweeps).

        Returns:
          (new state, forces dict of :meth:`forces`).
        """
        u0 = params.u0 if u0 is None else u0
        dt = self.timestep
        f = self.forces(params, state, terrain, push)
        data = mjx.step(self.mjx_model, state.data.replace(qfrc_applied=f["qfrc"]))
        w = network.weight_matrix(params.w_fe, params.w_rl, params.w_hka)
        tau, tau_a = network.time_constants(
            params.tau_hip, params.tau_hip_adapt, params.tau_ka, params.tau_ka_adapt
        )
        integ = (
            network.euler_step if self.options.neural_integrator == "euler" else network.rk4_step
        )
        neural = integ(state.neural, dt, w, tau, tau_a, params.beta, u0, f["feed"])
        events = _record(state.events, f["touchdown"], state.t, f["ground"].rest[:, 0])
        n = state.n_steps + 1
        t_new = n.astype(state.t.dtype) * jnp.asarray(dt, state.t.dtype)
        new = TagaState(
            data=data,
            neural=neural,
            ground=f["ground"],
            events=events,
            t=t_new,
            n_steps=n,
            fell=state.fell,
            t_end=state.t_end,
        )
        fell = self._fallen(data.qpos, terrain) | ~jnp.all(jnp.isfinite(data.qpos))
        new = new.replace(fell=fell, t_end=jnp.where(fell, new.t, state.t_end))
        # once fallen, the state is frozen (only the clock runs)
        frozen = jax.tree_util.tree_map(lambda a, b: jnp.where(state.fell, a, b), state, new)
        return frozen.replace(t=t_new, n_steps=n), f

    def _fallen(self, qpos, terrain: Terrain):
        tb = self.tb
        hip = qpos[:2]
        knees = tb.body.sites(qpos, tb.knee_ids)
        low_hip = hip[1] - terrain.height(hip[0]) < self.options.fall_height
        knee_down = jnp.any(knees[:, 1] < terrain.height(knees[:, 0]))
        return low_hip | knee_down

    # ------------------------------------------------------------------ rollout
    def rollout(
        self,
        params: TagaParams,
        state: TagaState,
        terrain: Terrain,
        n_log: int,
        log_every: int,
        push: Push | None = None,
        commands: Schedule | None = None,
    ):
        """Scan ``n_log * log_every`` steps, logging one row every ``log_every`` steps.

        Args:
          commands: optional :class:`~jaxgait.control.commands.Schedule` of the command
            vector (:data:`COMMANDS`: the tonic drive u0), e.g. the up/down sweep of Fig. 11;
            default ``params.u0`` throughout.  It is read once per logged interval, at the
            interval's midpoint (the drive is constant within an interval).
        Returns:
          (final state, :class:`Log`).
        """
        push = no_push(state.t.dtype) if push is None else push
        u0_series = u0_per_interval(params, state.t, n_log, log_every * self.timestep, commands)

        def inner(carry, _):
            s, nd, nf, u0 = carry
            s, f = self.step(params, s, terrain, push, u0)
            below = s.ground.below
            nd = nd + jnp.all(below)
            nf = nf + ~jnp.any(below)
            return (s, nd, nf, u0), f

        def outer(s, u0):
            zero = jnp.asarray(0, jnp.int32)
            (s, nd, nf, _), f = jax.lax.scan(inner, (s, zero, zero, u0), None, length=log_every)
            last = jax.tree_util.tree_map(lambda a: a[-1], f)
            row = Log(
                t=s.t,
                qpos=s.data.qpos,
                qvel=s.data.qvel,
                u=s.neural.u,
                contact=s.ground.below,
                grf=last["grf"],
                torque=last["torque"],
                double=nd / log_every,
                flight=nf / log_every,
                alive=~s.fell,
                u0=u0,
            )
            return s, row

        return jax.lax.scan(outer, state, jnp.asarray(u0_series, state.t.dtype), length=n_log)


def _copy_with_timestep(m: mujoco.MjModel, dt: float) -> mujoco.MjModel:
    import copy

    m2 = copy.copy(m)
    m2.opt.timestep = dt
    return m2


def _record(ev: Events, touchdown, t, x) -> Events:
    """Append the touchdowns of this step (right first) to the event record."""
    e = ev.t.shape[0]
    n = ev.n
    for leg in (0, 1):
        write = touchdown[leg] & (n < e)
        i = jnp.minimum(n, e - 1)
        ev = ev.replace(
            t=ev.t.at[i].set(jnp.where(write, t, ev.t[i])),
            leg=ev.leg.at[i].set(jnp.where(write, leg, ev.leg[i])),
            x=ev.x.at[i].set(jnp.where(write, x[leg], ev.x[i])),
        )
        n = n + touchdown[leg].astype(jnp.int32)
    return ev.replace(n=n)


#: Command inputs of the Taga biped (a :class:`~jaxgait.control.commands.Schedule` has one
#: column per entry).
COMMANDS = (
    Command("u0", 5.5, "-", "tonic descending drive of the oscillators (default: params.u0)"),
)


def u0_per_interval(params: TagaParams, t0, n_log: int, interval: float, commands=None):
    """(n_log,) tonic drive of each logged interval: ``params.u0``, or the schedule at the
    interval midpoints t0 + (k + 1/2) interval."""
    dtype = jnp.asarray(t0).dtype
    if commands is None:
        return jnp.full((n_log,), params.u0, dtype)
    if commands.values.shape[-1] != len(COMMANDS):
        raise CommandError(
            f"a Taga schedule has {len(COMMANDS)} column (u0), got {commands.values.shape[-1]}"
        )
    mid = t0 + (jnp.arange(n_log, dtype=dtype) + 0.5) * interval
    return jax.vmap(commands.at)(mid)[:, 0].astype(dtype)


@partial(jax.jit, static_argnums=(0, 4, 5))
def _jit_rollout(sim: Taga, params, state, terrain, n_log, log_every, push, commands):
    return sim.rollout(params, state, terrain, n_log, log_every, push, commands)


def simulate(
    params: TagaParams | None = None,
    duration: float = 20.0,
    terrain: Terrain | None = None,
    push: Push | None = None,
    state: TagaState | None = None,
    sim: Taga | None = None,
    log_dt: float = 0.01,
    commands: Schedule | None = None,
):
    """Jitted convenience rollout from Appendix E (or ``state``) for ``duration`` seconds.

    ``commands``: optional schedule of the tonic drive u0 (see :meth:`Taga.rollout`).

    Returns:
      (final state, :class:`Log`) with one log row every ``log_dt`` seconds.
    """
    from jaxgait.world.terrain import flat

    sim = default_sim() if sim is None else sim
    state = sim.init() if state is None else state
    dtype = state.t.dtype
    params = (TagaParams() if params is None else params).as_floats(dtype)
    terrain = flat(dtype=dtype) if terrain is None else terrain
    log_every = max(1, int(round(log_dt / sim.timestep)))
    n_log = int(round(duration / (log_every * sim.timestep)))
    push = no_push(dtype) if push is None else push
    return _jit_rollout(sim, params, state, terrain, n_log, log_every, push, commands)


_SIMS: dict = {}


def default_sim(dt: float | None = None, **options) -> Taga:
    """A cached :class:`Taga` (one per dt / options, so jitted code is reused)."""
    key = (dt, tuple(sorted(options.items())))
    if key not in _SIMS:
        _SIMS[key] = Taga(options=replace(Options(), **options), dt=dt)
    return _SIMS[key]
