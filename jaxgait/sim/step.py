"""One pure step of body + muscles + controller + contact (for one individual).

``step(model, cfg, params, env, state, commands=None, command_law=None) -> state`` advances
one physics step of ``model.dt``:

1. planar kinematics of the contact points, ankles, hip, CoM and push point, with their
   analytic Jacobians;
2. muscle-tendon forces and moment arms from the joint angles, the push of ``env.pushes``;
3. Geyer ground contact against ``env.terrain`` and the ligament soft limits as stiff rows;
4. MJX multibody dynamics (mass matrix and bias forces; constraint solver off);
5. the rows' damping resolved linearly-implicitly (:mod:`jaxgait.sim.rows`);
6. gait phases (:mod:`jaxgait.control.gait`), the shared
   :class:`~jaxgait.control.interface.Sensors`, the command (schedule, then feedback law,
   :mod:`jaxgait.control.commands`) and the controller's step -> stimulation;
7. semi-implicit Euler of the body;
8. muscle activation / CE-length integration and metabolic energy.

Rollouts are in :mod:`jaxgait.sim.rollout`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.body.joints import SoftLimits, q_to_phi
from jaxgait.control import commands as cmd_mod
from jaxgait.control.commands import CommandLaw, Schedule
from jaxgait.control.gait import init_gait, thigh_sheet_load, update_gait
from jaxgait.control.interface import Sensors
from jaxgait.core.linalg import spd_solve
from jaxgait.muscles import effort as effort_mod
from jaxgait.muscles import energy as energy_mod
from jaxgait.muscles import mtu as mus
from jaxgait.sim.model import POSES, Model, SimConfig, SimState
from jaxgait.sim.rows import implicit_row_velocities
from jaxgait.sim.trace import Events
from jaxgait.world.contact import contact_finalize, contact_rows, init_contact
from jaxgait.world.envs import Env, push_force


def scheduled_command(model: Model, commands: Schedule | None, t, dtype):
    """(C,) control vector from the schedule at time ``t``, or the controller's defaults."""
    ctrl = model.controller
    if commands is None:
        return cmd_mod.defaults(ctrl.commands, dtype)
    n = len(ctrl.commands)
    if commands.values.shape[-1] != n:
        raise cmd_mod.CommandError(
            f"schedule has {commands.values.shape[-1]} command columns, controller "
            f"{ctrl.name!r} takes {n}: {', '.join(ctrl.command_names) or '(none)'}"
        )
    return commands.at(t).astype(dtype)


def sensors_of(
    model: Model,
    t,
    f_mtu,
    l_ce,
    phi,
    dphi,
    qpos,
    qvel,
    gait,
    touchdown,
    ds,
    pts,
    com_vel,
    ankle_vel,
    grf=None,
) -> Sensors:
    """The shared :class:`~jaxgait.control.interface.Sensors` of one step.

    Args: time [s]; f_mtu, l_ce (2, M) [N, m]; phi, dphi (2, 3) GH angles and rates; qpos,
    qvel the generalised state; gait: the updated :class:`~jaxgait.control.gait.GaitState`;
    touchdown, ds (2,) bool; pts (9, 2) the points of :meth:`Model.points`; com_vel (2,);
    ankle_vel (2, 2) the velocities of the ankles (points 4 and 5); grf (2, 2) the ground
    reaction (x, z) per leg [N], read by the thigh-sheet load signal (``model.gait``).
    """
    table = model.muscles
    dtype = qpos.dtype
    return Sensors(
        t=t,
        f_mtu=f_mtu,
        f_norm=f_mtu / jnp.maximum(jnp.asarray(table.f_max, dtype), 1e-9),
        l_ce=l_ce,
        l_norm=l_ce / jnp.asarray(table.l_opt, dtype),
        phi=phi,
        dphi=dphi,
        trunk=qpos[2],
        dtrunk=qvel[2],
        load=leg_load(model, qpos, gait, grf),
        stance=gait.stance,
        touchdown=touchdown,
        double_support=ds,
        theta_to=gait.theta_to,
        com=pts[7],
        com_vel=com_vel,
        feet=pts[:4],
        dcom=(pts[7, 0] - pts[[1, 3], 0]) / model.foot_length,
        ankle=pts[4:6],
        ankle_vel=ankle_vel,
        dleg=(pts[7, 0] - pts[4:6, 0]) / model.leg_length,
    )


def leg_load(model: Model, qpos, gait, grf):
    """The reflexes' leg-load signal (2,): the gait detection's filtered F_z / (M g), or with
    ``model.gait.load_signal == "thigh_sheet"`` Geyer's thigh pressure sheet
    (:func:`~jaxgait.control.gait.thigh_sheet_load`, in HAT weights) from ``grf`` (2, 2)."""
    if model.gait.load_signal == "grf":
        return gait.load
    _, angles = model.body.frames(qpos)
    m_below, m_hat = model.sheet_masses
    return thigh_sheet_load(grf, angles[model.thigh_ids], m_below, m_hat)


# ------------------------------------------------------------------------- init
#: Fixed-point iterations of the ``start_activation="reflex"`` start (stimulation <-> resting
#: muscle force).  Positive force feedback makes the loop gain G f_l(l) of SOL and GAS close
#: to 1, so the iteration converges slowly; 10 passes left errors of 0.03 with Geyer's gains.
START_REFLEX_ITERS = 500


def initial_state(
    model: Model,
    params,
    env: Env,
    cfg: SimConfig,
    commands: Schedule | None = None,
    command_law: CommandLaw | None = None,
) -> SimState:
    """Posture ``cfg.pose`` with the stance foot on the ground, moving at ``cfg.v0``.

    A controller with ``initial_offsets`` (:class:`~jaxgait.control.interface.Controller`)
    shifts the pose's angles and ``v0`` by parameter-dependent offsets first.
    """
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
    v0 = cfg.v0
    ctrl = model.controller
    if ctrl.initial_offsets is not None:  # parameter-dependent start (e.g. Wang 2012 section 5)
        dq, dv = ctrl.initial_offsets(ctrl, model.table.unpack(jnp.asarray(params)))
        dq = jnp.asarray(dq, dtype)
        qpos = qpos.at[2].add(dq[0]).at[legq[0]].add(dq[1:4]).at[legq[1]].add(dq[4:7])
        v0 = v0 + jnp.asarray(dv, dtype)
    pts = model.points(qpos, jnp.zeros((), dtype))
    # lift the body so the lowest point of the stance foot is on the ground
    ground = env.terrain.height(pts[:2, 0])
    lift = jnp.max(ground - pts[:2, 1])
    qpos = qpos.at[1].add(lift)
    qvel = jnp.zeros(model.body.mj_model.nv, dtype).at[0].set(v0)
    pts = model.points(qpos, jnp.zeros((), dtype))
    _, jac = model.points_jacobian(qpos, jnp.zeros((), dtype))  # CoM and ankle velocities

    table = model.muscles
    legq_j = jnp.asarray(legq)
    phi = q_to_phi(qpos[legq_j])
    l_mtu = mus.mtu_length(table, phi)
    gait = init_gait([1.0, 0.0], [True, False], qpos[2], dtype)

    def start_sensors(act, l_ce):  # the sensors of muscles resting at (act, l_ce)
        return sensors_of(
            model,
            jnp.zeros((), dtype),
            mus.mtu_force(table, act, l_ce, l_mtu),
            l_ce,
            phi,
            jnp.zeros_like(phi),
            qpos,
            qvel,
            gait,
            jnp.zeros(2, bool),
            jnp.zeros(2, bool),
            pts,
            jac[7] @ qvel,
            jac[4:6] @ qvel,
            # the stance leg carries the body's weight (the filtered load's start, 1 and 0 BW)
            jnp.asarray([[0.0, model.mass * 9.81], [0.0, 0.0]], dtype),
        )

    l_ce = mus.init_lce(table, l_mtu)
    act = jnp.full_like(l_ce, 0.01)
    sensors0 = start_sensors(act, l_ce)
    if cfg.start_activation == "reflex":  # the controller's stimulation, to a fixed point
        p = model.table.unpack(jnp.asarray(params))
        cmd = cmd_mod.as_dict(ctrl.commands, scheduled_command(model, commands, 0.0, dtype))

        def settle(_, al):  # the stimulation of the muscles resting at al = (act, l_ce)
            sens = start_sensors(*al)
            stim, _ = ctrl.step(ctrl, p, sens, ctrl.init(ctrl, sens, model.dt), cmd, model.dt)
            a = jnp.clip(stim.astype(dtype), mus.ACT_MIN, mus.stim_upper(table, dtype))
            return a, mus.init_lce(table, l_mtu, a)

        act, l_ce = jax.lax.fori_loop(0, START_REFLEX_ITERS, settle, (act, l_ce))
        sensors0 = start_sensors(act, l_ce)
    mstate = mus.MuscleState(act=act, l_ce=l_ce)
    delay_start = sensors0
    if cfg.start_delays == "zero":  # the delay lines' initial output 0 (Simulink)
        delay_start = jax.tree.map(jnp.zeros_like, sensors0)
    ctrl_state = ctrl.init(ctrl, delay_start, model.dt)
    law_state = None
    if command_law is not None:
        cmd0 = scheduled_command(model, commands, sensors0.t, dtype)
        law_state = command_law.init(command_law, sensors0, cmd0)
    E = cfg.max_events
    events = Events(
        t=jnp.zeros(E, dtype),
        leg=jnp.zeros(E, jnp.int32),
        x_td=jnp.zeros(E, dtype),
        x_other=jnp.zeros(E, dtype),
        n=jnp.zeros((), jnp.int32),
        peak_grf=jnp.zeros(E, dtype),
        peak_t=jnp.zeros(E, dtype),
        loading_rate=jnp.zeros(E, dtype),
        open=jnp.full((2,), -1, jnp.int32),
    )
    zero = jnp.zeros((), dtype)
    return SimState(
        qpos=qpos,
        qvel=qvel,
        t=zero,
        muscle=mstate,
        contact=init_contact(pts[:4]),
        gait=gait,
        ctrl=ctrl_state,
        command_state=law_state,
        energy=zero,
        lean_sum=zero,
        limit_sq=zero,
        x0=pts[7, 0],
        done=jnp.zeros((), bool),
        fell=jnp.zeros((), bool),
        end_t=zero,
        end_x=pts[7, 0],
        end_energy=zero,
        end_lean=zero,
        end_limit_sq=zero,
        events=events,
        grf=jnp.zeros((2, 2), dtype),
        stim=jnp.full((2, len(table.names)), 0.01, dtype),
    )


# ------------------------------------------------------------------------- step
def _record_touchdowns(ev: Events, td, t, ankle_x) -> Events:
    """Append this step's touchdowns (at most one per leg) to the event buffer, in place;
    a recorded touchdown opens the measurement of its stance's GRF peak."""
    for leg in (0, 1):
        i = jnp.minimum(ev.n, ev.t.shape[0] - 1)
        write = td[leg] & (ev.n < ev.t.shape[0])
        put = lambda buf, v, i=i, write=write: buf.at[i].set(jnp.where(write, v, buf[i]))
        zero = jnp.zeros((), ev.peak_grf.dtype)
        ev = Events(
            t=put(ev.t, t),
            leg=put(ev.leg, jnp.asarray(leg, ev.leg.dtype)),
            x_td=put(ev.x_td, ankle_x[leg]),
            x_other=put(ev.x_other, ankle_x[1 - leg]),
            n=ev.n + td[leg].astype(jnp.int32),
            peak_grf=put(ev.peak_grf, zero),
            peak_t=put(ev.peak_t, zero),
            loading_rate=put(ev.loading_rate, zero),
            open=ev.open.at[leg].set(
                jnp.where(td[leg], jnp.where(write, i, -1), ev.open[leg]).astype(jnp.int32)
            ),
        )
    return ev


def _stance_peaks(ev: Events, stance, fz, fz_prev, t, dt, active) -> Events:
    """Per-stance peak vertical GRF [N], its time after touchdown [s] and the largest
    one-step loading rate [N/s] of each leg in stance, at the physics step."""
    peak, peak_t, rate = ev.peak_grf, ev.peak_t, ev.loading_rate
    for leg in (0, 1):
        j = jnp.maximum(ev.open[leg], 0)
        on = active & stance[leg] & (ev.open[leg] >= 0)
        higher = on & (fz[leg] > peak[j])
        peak = peak.at[j].set(jnp.where(higher, fz[leg], peak[j]))
        peak_t = peak_t.at[j].set(jnp.where(higher, t - ev.t[j], peak_t[j]))
        r = (fz[leg] - fz_prev[leg]) / dt
        rate = rate.at[j].set(jnp.where(on, jnp.maximum(rate[j], r), rate[j]))
    return ev.replace(peak_grf=peak, peak_t=peak_t, loading_rate=rate)


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


def step(
    model: Model,
    cfg: SimConfig,
    params,
    env: Env,
    s: SimState,
    commands: Schedule | None = None,
    command_law: CommandLaw | None = None,
) -> SimState:
    """Advance the whole body + controller by one physics step (pure).

    Args:
      model, cfg: static model and settings; params: (D,) the controller's parameters in
        table order; env: terrain and pushes; s: the state.
      commands: the control vector as a function of time (default: the controller's
        defaults); command_law: a feedback law on it, run after the sensors (its state is
        ``s.command_state``).
    """
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

    # 4. multibody dynamics: mass matrix M and bias forces (MJX's passes or the planar tree's)
    M, qfrc_smooth = model.mass_and_forces_of(cfg.dynamics, s.qpos, s.qvel, qfrc)

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

    # 6. gait phases, the shared sensors, the command, then the controller
    gait, _, td, ds = update_gait(model.gait, s.gait, grf[:, 1], mg, s.t, s.qpos[2], dt)
    sensors = sensors_of(
        model,
        s.t,
        f_mtu,
        s.muscle.l_ce,
        phi,
        dphi,
        s.qpos,
        s.qvel,
        gait,
        td,
        ds,
        pts,
        vel[7],
        vel[4:6],
        grf,
    )
    command = scheduled_command(model, commands, s.t, dtype)
    law_state = s.command_state
    if command_law is not None:
        command, law_state = command_law.step(command_law, law_state, sensors, command, dt)
    ctrl = model.controller
    stim, ctrl_state = ctrl.step(
        ctrl, p, sensors, s.ctrl, cmd_mod.as_dict(ctrl.commands, command), dt
    )

    # 7. semi-implicit Euler (as MuJoCo's Euler integrator; all joints are hinge/slide)
    qvel = s.qvel + dt * qacc
    qpos = s.qpos + dt * qvel

    # 8. muscle state over the same step, against the MTU lengths at its end (the joints
    # have moved with the tendon forces of its start), and metabolic energy
    l_mtu_end = mus.mtu_length(table, q_to_phi(qpos[legq]))
    mstate, info = mus.muscle_step(
        table, s.muscle, stim, l_mtu_end, dt, cfg.muscle_substeps, solve_iters=cfg.ce_solve_iters
    )
    rate_fn = (
        effort_mod.wang_metabolic_rate
        if model.metabolic == "wang2012"
        else energy_mod.metabolic_rate
    )
    rate = rate_fn(
        table, info["stim"], info["act"], info["l_ce"], info["v_ce"], info["f_ce"], info["f_mtu"]
    ).sum()

    # time on the step grid, t = n dt: summing dt in float32 drifted by 27 ms over 60 s
    t = (jnp.round(s.t / dt) + 1.0) * dt
    energy = s.energy + rate * dt
    lean_sum = s.lean_sum + s.qpos[2] * dt
    limit_sq = s.limit_sq + jnp.sum(jnp.square(f_lim)) * dt  # Wang's J_L integrand
    events = _record_touchdowns(s.events, td & ~s.done, s.t, pts[4:6, 0])
    events = _stance_peaks(events, gait.stance, grf[:, 1], s.grf[:, 1], s.t, dt, ~s.done)

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
        gait=gait,
        ctrl=ctrl_state,
        command_state=law_state,
        energy=energy,
        lean_sum=lean_sum,
        limit_sq=limit_sq,
        x0=s.x0,
        done=s.done | done_now,
        fell=s.fell | (done_now & fell_now),
        end_t=freeze(t, s.end_t),
        end_x=freeze(pts[7, 0], s.end_x),
        end_energy=freeze(energy, s.end_energy),
        end_lean=freeze(lean_sum, s.end_lean),
        end_limit_sq=freeze(limit_sq, s.end_limit_sq),
        events=events,
        grf=grf,
        stim=stim,
    )
