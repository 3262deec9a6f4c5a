"""Experiments of Taga, Yamaguchi & Shimizu (1991), section 4, as commands.

    python -m jaxgait.taga.experiments {fig5,fig6,fig7,ground,slope,fig11,all}
        [--out DIR] [--quick]

Each command writes PNG plots and ``NAME.json`` (measured figures next to the paper's)
into ``--out`` (default ``taga_results/``); ``all`` also writes ``summary.json``.
``--quick`` runs small versions (shorter, coarser) for smoke tests.

  fig5   walking limit cycle from Appendix E (u0 = 5.5): stick figures (Fig. 5A, B),
         thigh phase portrait, steady measures, time-step and integrator cross-checks;
         the running stick figure of Fig. 9 (taga_run preset).
  fig6   neural activity while walking (Fig. 6A) and running (Fig. 10), isolated network
         (Feed_i = 0, Fig. 6B): entrained vs isolated frequency, left/right phase.
  fig7   200 N forward on the left shank (link 5) for 0.2 s from its lift-off, and 288 N
         forward on the hip (link 1) for 0.2 s (Fig. 7); recovery and force tolerance.
  ground walking for k_g and b_g around Appendix D (section 4.1.3), one vmapped batch.
  slope  uphill and downhill grades (section 4.1.3, Fig. 8), one vmapped batch.
  fig11  one continuous simulation sweeping u0 up then down (Fig. 11): stride length,
         stride duration and speed; walking/running coexistence; u0 survey from Appendix E.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.control import commands
from jaxgait.taga import measures, network, plots
from jaxgait.taga.model import TagaParams
from jaxgait.taga.sim import COMMANDS as DRIVE
from jaxgait.taga.sim import default_sim, no_push, push_on, simulate
from jaxgait.world import terrain as terr

WALK_U0 = 5.5  # Fig. 5
PAPER_RUN_U0 = 8.3  # Fig. 9
RUN_U0 = 7.75  # taga_run preset (see README: 8.3 is past this implementation's running branch)
REGULAR_SD_M = 0.05  # stride-length SD below which walking counts as steady [m]
COMMANDS = ("fig5", "fig6", "fig7", "ground", "slope", "fig11")


# ---------------------------------------------------------------------------- helpers
def _clean(x):
    """JSON-able copy: numpy scalars to Python, NaN/inf to None."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, (np.ndarray, jax.Array)):
        return _clean(np.asarray(x).tolist())
    if isinstance(x, (np.floating, float)):
        x = float(x)
        return x if math.isfinite(x) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def _write(out: Path, name: str, data: dict) -> dict:
    data = _clean(data)
    (out / f"{name}.json").write_text(json.dumps(data, indent=1))
    return data


def _batch(n: int, base: TagaParams | None = None, **fields) -> TagaParams:
    """``n`` copies of ``base`` (float32 leaves) with the given fields set per member."""
    p = (TagaParams() if base is None else base).as_floats()
    pb = jax.tree_util.tree_map(lambda a: jnp.broadcast_to(a, (n,) + a.shape), p)
    return pb.replace(**{k: jnp.asarray(v, jnp.float32) for k, v in fields.items()})


@partial(jax.jit, static_argnums=(0, 1, 2, 3))
def _vrollout(sim, n_log, log_every, axes, params, state, terrain, push):
    def one(p, s, g, pu):
        return sim.rollout(p, s, g, n_log, log_every, pu)

    return jax.vmap(one, in_axes=axes)(params, state, terrain, push)


def batched(
    sim, params, state, terrain, duration, log_dt=0.01, push=None, axes=(0, None, None, None)
):
    """vmapped rollout; ``axes`` = in_axes of (params, state, terrain, push)."""
    log_every = max(1, int(round(log_dt / sim.timestep)))
    n_log = int(round(duration / (log_every * sim.timestep)))
    push = no_push() if push is None else push
    return _vrollout(sim, n_log, log_every, axes, params, state, terrain, push)


def _member(tree, i):
    return jax.tree_util.tree_map(lambda a: a[i], tree)


def _gait(sim, duration=20.0, u0=WALK_U0, state=None):
    """Walk (or run, by ``u0``) from Appendix E (or ``state``) for ``duration`` s; returns
    (state, log)."""
    if state is None:
        state = sim.init(event_capacity=256)
    return simulate(TagaParams(u0=u0), duration, sim=sim, state=state)


def _measured_gait(sim, duration=20.0, u0=WALK_U0, state=None):
    """:func:`_gait` and its gait measures; returns (state, log, measures)."""
    st, log = _gait(sim, duration, u0, state)
    return st, log, measures.gait_measures(log, st.events, st)


def _cycle_panels(pos, cyc, panels, title, path):
    """Stick figures of one gait cycle ``cyc`` (log indices), split into two panels by
    ``panels`` ((mask over the log, name), ...), every second sample."""
    fig = plots.figure(10, 3.5)
    for k, (sel, name) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), k + 1)
        idx = cyc[sel[cyc]][::2]
        if len(idx):
            plots.stick_figure(ax, pos, idx, lw=0.7)
        ax.set_title(f"{title}: {name} (every 0.02 s)", fontsize=9)
    plots.save(fig, path)


def _gait_class(m: dict) -> str:
    if m.get("fell"):
        return "fell"
    sp = m.get("speed_mps") or 0.0
    if sp < 0.1:
        return "stopped"
    if (m.get("flight_fraction") or 0.0) > 0.01 and (
        m.get("double_support_fraction") or 0.0
    ) == 0.0:
        return "run"
    if (m.get("double_support_fraction") or 0.0) > 0.0:
        return "walk"
    return "other"


def _step_indices(log, td, t_from):
    """Log indices of one step: from the first right touchdown after ``t_from`` to the
    next left touchdown (the "stepping cycle" drawn in Figs. 5B and 9B)."""
    t = np.asarray(log.t)
    tr = td["t"][(td["leg"] == 0) & (td["t"] >= t_from)]
    if len(tr) == 0:
        return np.arange(0)
    tl = td["t"][(td["leg"] == 1) & (td["t"] > tr[0])]
    if len(tl) == 0:
        return np.arange(0)
    return np.nonzero((t >= tr[0]) & (t <= tl[0]))[0]


# ---------------------------------------------------------------------------- fig5 / fig9
def fig5(out: Path, quick: bool = False) -> dict:
    """Walking limit cycle from Appendix E (Fig. 5) and the running figure (Fig. 9)."""
    sim = default_sim()
    dur = 12.0 if quick else 20.0
    st, log, m = _measured_gait(sim, dur)
    td = measures.touchdowns(st.events)
    t = np.asarray(log.t)
    pos = plots.joint_positions(sim.tb, log.qpos)
    # convergence to the limit cycle: first right stride within 1 % of the final stride
    dur_r, len_r = [], []
    tr = td["t"][td["leg"] == 0]
    xr = td["x"][td["leg"] == 0]
    dur_r, len_r = np.diff(tr), np.diff(xr)
    ok = (np.abs(dur_r / dur_r[-1] - 1) < 0.01) & (np.abs(len_r / len_r[-1] - 1) < 0.01)
    conv = next((k for k in range(len(ok)) if ok[k:].all()), None)
    t_conv = float(tr[conv]) if conv is not None else None

    fig = plots.figure(14, 2.8)
    ax = fig.add_subplot(111)
    plots.stick_figure(ax, pos, np.nonzero(t <= 10.0 + 1e-6)[0][::10])
    ax.set_title(f"Fig. 5A: walking from Appendix E, u0 = {WALK_U0}, 0-10 s every 0.1 s")
    plots.save(fig, out / "fig5a_walk_stick.png")

    cyc = _step_indices(log, td, dur - 3.0)
    both = np.asarray(log.contact)[:, 0] & np.asarray(log.contact)[:, 1]
    panels = ((both, "double support"), (~both, "single support"))
    _cycle_panels(pos, cyc, panels, "Fig. 5B", out / "fig5b_walk_cycle.png")

    q, dq = np.asarray(log.qpos), np.asarray(log.qvel)
    fig = plots.figure(6, 5)
    ax = fig.add_subplot(111)
    ax.plot(q[:, 2], dq[:, 2], lw=0.5, color=plots.RIGHT, label="right thigh")
    ax.plot(q[:, 4], dq[:, 4], lw=0.5, color=plots.LEFT, alpha=0.6, label="left thigh")
    ax.set_xlabel("thigh angle from vertical, x5 - pi/2 [rad]")
    ax.set_ylabel("angular velocity [rad/s]")
    ax.set_title("walking limit cycle from the Appendix E start")
    ax.legend(fontsize=8)
    plots.save(fig, out / "fig5_phase_portrait.png")

    # numerical cross-checks of the steady walk: halved time step, the paper's own
    # Newton-Euler equations integrated with RK4
    checks = {}
    if not quick:
        checks["dt_0.25ms"] = _measured_gait(default_sim(0.00025), dur)[2]
        checks["paper_equations_rk4_0.5ms"] = _reference_walk(dur)
        checks["neural_rk4"] = _measured_gait(default_sim(neural_integrator="rk4"), dur)[2]

    # alternative readings of the text, each run from Appendix E at u0 = 5.5
    readings = {}
    if not quick:
        knee_step = default_sim(knee_stop="step")
        readings["knee_stop_step_as_printed"] = _measured_gait(knee_step, dur)[2]
        s0 = sim.init(event_capacity=256)
        p0 = TagaParams(u0=WALK_U0).as_floats()
        th = sim.tb.angles(s0.data.qpos)
        feed0 = network.feedback(th, jnp.zeros(2), jnp.zeros(2), p0.a)  # no contact at t = 0
        wm0 = network.weight_matrix(p0.w_fe, p0.w_rl, p0.w_hka)
        s0 = s0.replace(neural=network.equilibrium(wm0, p0.beta, p0.u0, feed0))
        readings["neurons_start_at_equilibrium"] = _measured_gait(sim, dur, state=s0)[2]

    # Fig. 9: running
    st_r, log_r, m_run = _measured_gait(sim, dur, RUN_U0)
    m_paper_u0 = _measured_gait(sim, dur, PAPER_RUN_U0)[2]
    pos_r = plots.joint_positions(sim.tb, log_r.qpos)
    tr_ = np.asarray(log_r.t)
    fig = plots.figure(14, 2.8)
    ax = fig.add_subplot(111)
    plots.stick_figure(ax, pos_r, np.nonzero(tr_ <= 10.0 + 1e-6)[0][::10])
    ax.set_title(f"Fig. 9A: running from Appendix E, u0 = {RUN_U0}, 0-10 s every 0.1 s")
    plots.save(fig, out / "fig9a_run_stick.png")
    td_r = measures.touchdowns(st_r.events)
    cyc = _step_indices(log_r, td_r, dur - 3.0)
    none = ~(np.asarray(log_r.contact)[:, 0] | np.asarray(log_r.contact)[:, 1])
    panels = ((none, "flight"), (~none, "single support"))
    _cycle_panels(pos_r, cyc, panels, "Fig. 9B", out / "fig9b_run_cycle.png")

    return _write(
        out,
        "fig5",
        dict(
            walk_u0=WALK_U0,
            dt_s=sim.timestep,
            walk=m,
            limit_cycle_reached_at_s=t_conv,
            strides_to_limit_cycle=conv,
            cross_checks=checks,
            alternative_readings=readings,
            run_u0=RUN_U0,
            run=m_run,
            run_at_paper_u0=m_paper_u0,
            paper=dict(
                walk="stable limit cycle from Appendix E at u0 = 5.5 (Fig. 5); double support",
                run="running (flight, no double support) at u0 = 8.3 from Appendix E (Fig. 9)",
            ),
        ),
    )


def _reference_walk(duration: float) -> dict:
    """Steady hip speed of the paper's Newton-Euler equations (RK4, 0.5 ms)."""
    from jaxgait.taga import reference

    dt = 0.0005
    run = reference.make_rollout(
        TagaParams(u0=WALK_U0).as_floats(), terr.flat(), dt, int(duration / dt)
    )
    x0 = jnp.asarray(reference.appendix_e(), jnp.float32)
    z12 = jnp.zeros(12, jnp.float32)
    _, _, _, _, xs = run(x0, jnp.zeros(14, jnp.float32), z12, z12)
    xs = np.asarray(xs)
    half = len(xs) // 2
    return dict(
        speed_mps=float((xs[-1, 0] - xs[half, 0]) / ((len(xs) - half) * dt)),
        fell=bool(xs[:, 1].min() < 0.6),
        hip_height_range_m=[float(xs[half:, 1].min()), float(xs[half:, 1].max())],
    )


# ---------------------------------------------------------------------------- fig6 / fig10
def fig6(out: Path, quick: bool = False) -> dict:
    """Neural activity walking / running / isolated; entrained vs isolated frequency."""
    sim = default_sim()
    dur = 12.0 if quick else 20.0
    st, log = _gait(sim, dur)
    m = measures.gait_measures(log, st.events, st)
    t, u = np.asarray(log.t), np.asarray(log.u)
    dt_log = float(t[1] - t[0])
    w = t >= dur - 3.0
    fig = plots.figure(8, 10)
    plots.network_activity(fig, t[w], u[w], f"Fig. 6A: u_i while walking (u0 = {WALK_U0})")
    plots.save(fig, out / "fig6a_walk_network.png")
    half = t >= dur / 2
    ent_period = measures.dominant_period(u[half, 0] - u[half, 1], dt_log)

    # isolated network, Feed_i = 0 (Fig. 6B), classical RK4 at the same step, started from
    # the walking network's final state (from the all-zero state the flexor and extensor
    # hip neurons stay identical by symmetry and never oscillate)
    p = TagaParams(u0=WALK_U0).as_floats()
    wm = network.weight_matrix(p.w_fe, p.w_rl, p.w_hka)
    tau, tau_a = network.time_constants(p.tau_hip, p.tau_hip_adapt, p.tau_ka, p.tau_ka_adapt)
    iso_dur = 30.0
    n = int(iso_dur / sim.timestep)
    _, ui = jax.jit(network.isolated_rollout, static_argnums=1)(
        st.neural, n, sim.timestep, wm, tau, tau_a, p.beta, p.u0
    )
    ui = np.asarray(ui)[:: int(round(dt_log / sim.timestep))]
    ti = (np.arange(len(ui)) + 1) * dt_log
    wi = ti >= iso_dur - 6.0
    fig = plots.figure(8, 10)
    plots.network_activity(fig, ti[wi], ui[wi], "Fig. 6B: isolated network, Feed_i = 0")
    plots.save(fig, out / "fig6b_isolated_network.png")
    hi = ti >= 10.0
    iso_hip = measures.dominant_period(ui[hi, 0] - ui[hi, 1], dt_log)
    iso_knee = measures.dominant_period(ui[hi, 4] - ui[hi, 5], dt_log)
    iso_ankle = measures.dominant_period(ui[hi, 8] - ui[hi, 9], dt_log)

    def lr_phase(uu, tt, period):
        a, b = uu[:, 0] - uu[:, 1], uu[:, 2] - uu[:, 3]
        a, b = a - a.mean(), b - b.mean()
        ca = tt[:-1][(a[:-1] < 0) & (a[1:] >= 0)]
        cb = tt[:-1][(b[:-1] < 0) & (b[1:] >= 0)]
        if len(ca) < 2 or len(cb) < 2:
            return float("nan")
        lag = [((cb[cb >= x][0] - x) / period) % 1.0 for x in ca if (cb >= x).any()]
        return float(np.mean(lag))

    # Fig. 10: running
    st_r, log_r = _gait(sim, dur, RUN_U0)
    tr, ur = np.asarray(log_r.t), np.asarray(log_r.u)
    wr = tr >= dur - 3.0
    fig = plots.figure(8, 10)
    plots.network_activity(fig, tr[wr], ur[wr], f"Fig. 10: u_i while running (u0 = {RUN_U0})")
    plots.save(fig, out / "fig10_run_network.png")
    hr = tr >= dur / 2
    run_period = measures.dominant_period(ur[hr, 0] - ur[hr, 1], dt_log)

    return _write(
        out,
        "fig6",
        dict(
            u0=WALK_U0,
            entrained_hip_period_s=ent_period,
            entrained_frequency_hz=1 / ent_period,
            walking_stride_duration_s=m["stride_duration_s"],
            isolated_hip_period_s=iso_hip,
            isolated_frequency_hz=1 / iso_hip,
            isolated_knee_period_s=iso_knee,
            isolated_ankle_period_s=iso_ankle,
            entrained_over_isolated_frequency=iso_hip / ent_period,
            left_right_hip_phase_isolated_cycles=lr_phase(ui[hi], ti[hi], iso_hip),
            left_right_hip_phase_walking_cycles=lr_phase(u[half], t[half], ent_period),
            running_u0=RUN_U0,
            running_hip_period_s=run_period,
            paper=dict(
                frequency="walking frequency higher than the isolated network's (Fig. 6)",
                knee_ankle="knee/ankle time constants half the hip's: twice the frequency",
            ),
        ),
    )


# ---------------------------------------------------------------------------- fig7
def _push_batch(site: str, forces, onsets, duration=0.2):
    """A batch of horizontal pushes on ``site`` (forces and onsets broadcast together)."""
    forces, onsets = np.broadcast_arrays(np.asarray(forces, float), np.asarray(onsets, float))
    k = ("hip", "shank_r", "shank_l").index(site)
    fb = np.zeros((forces.size, 3, 2), np.float32)
    fb[:, k, 0] = forces.ravel()
    t0 = jnp.asarray(onsets.ravel(), jnp.float32)
    return push_on(site, 0.0, 0.0, duration).replace(force=jnp.asarray(fb), t0=t0, t1=t0 + duration)


def fig7(out: Path, quick: bool = False) -> dict:
    """Perturbations during steady walking (Fig. 7), their onset-phase dependence and the
    largest pushes survived.

    A: 200 N forward on the centre of mass of link 5 (the left shank, x12-x14 of
    Appendix A) for 0.2 s from its lift-off (start of swing).  B: 288 N forward on link 1
    (hip) for 0.2 s; the paper gives no phase, the drawing uses the right touchdown and a
    map over 20 onsets spread over one stride is reported (10 with ``--quick``).
    """
    sim = default_sim()
    warm = 12.0 if quick else 20.0
    after = 8.0 if quick else 15.0
    st0, _ = _gait(sim, warm)
    st0 = st0.replace(events=sim.init(event_capacity=256).events)
    p = TagaParams(u0=WALK_U0)
    stb, logb = simulate(p, after, sim=sim, state=st0)
    base = measures.window_measures(logb, stb.events, warm + after / 2, warm + after)
    tdb = measures.touchdowns(stb.events)
    t_ref = float(tdb["t"][(tdb["leg"] == 0) & (tdb["t"] > warm + 0.5)][0])  # right touchdown
    tb_, cont = np.asarray(logb.t), np.asarray(logb.contact)
    lift = np.nonzero(cont[:-1, 1] & ~cont[1:, 1] & (tb_[:-1] > t_ref))[0]
    onset = {"A_shank_200N": float(tb_[lift[0] + 1]), "B_hip_288N": t_ref}
    cases = {"A_shank_200N": ("shank_l", 200.0), "B_hip_288N": ("hip", 288.0)}
    stride = base["stride_duration_s"]
    res = {}
    for name, (site, f) in cases.items():
        t_push = onset[name]
        st, log = simulate(p, after, sim=sim, state=st0, push=push_on(site, f, t_push, 0.2))
        td = measures.touchdowns(st.events)
        m = measures.window_measures(log, st.events, warm + after / 2, warm + after)
        # recovery: strides (right leg) after the push until within 2 % of the baseline
        tr_ = td["t"][(td["leg"] == 0) & (td["t"] > t_push)]
        xr = td["x"][(td["leg"] == 0) & (td["t"] > t_push)]
        d, ln = np.diff(tr_), np.diff(xr)
        ok = (np.abs(d / base["stride_duration_s"] - 1) < 0.02) & (
            np.abs(ln / base["stride_length_m"] - 1) < 0.02
        )
        k = next((i for i in range(len(ok)) if ok[i:].all()), None)
        # onset-phase map: the same push started at n instants over one stride (n pushes
        # and n force levels, so that every batch below shares one compiled rollout)
        n = 10 if quick else 20
        phases = np.arange(n) / n
        stv, _ = batched(
            sim,
            _batch(n, p),
            st0,
            terr.flat(),
            after,
            push=_push_batch(site, f, t_ref + phases * stride),
            axes=(0, None, None, 0),
        )
        fell_ph = np.asarray(stv.fell)
        # tolerance: the largest forward push still followed by walking, at this onset
        forces = np.arange(n) * (1000.0 / n)
        stv, _ = batched(
            sim,
            _batch(len(forces), p),
            st0,
            terr.flat(),
            after,
            push=_push_batch(site, forces, t_push),
            axes=(0, None, None, 0),
        )
        fell_f = np.asarray(stv.fell)
        first_fall = forces[fell_f].min() if fell_f.any() else np.inf
        res[name] = dict(
            site=site,
            force_N=f,
            onset_s=t_push,
            onset_after_right_touchdown_s=t_push - t_ref,
            fell=bool(st.fell),
            steady_after=m,
            strides_to_recover=k,
            stride_durations_after_s=d[:8],
            stride_lengths_after_m=ln[:8],
            onset_phase_map=dict(
                phase_of_stride=phases, fell=fell_ph, survived_fraction=1 - fell_ph.mean()
            ),
            tolerance=dict(
                forces_N=forces,
                fell=fell_f,
                largest_survived_below_first_fall_N=forces[forces < first_fall].max(),
            ),
        )
        pos = plots.joint_positions(sim.tb, log.qpos)
        tt = np.asarray(log.t)
        sel = np.nonzero((tt >= t_push - 1.0) & (tt <= t_push + 4.0))[0][::10]
        fig = plots.figure(14, 3.0)
        ax = fig.add_subplot(111)
        plots.stick_figure(ax, pos, sel)
        on = np.nonzero((tt >= t_push) & (tt < t_push + 0.2))[0]
        # dots: the pushed point (hip, or the middle of the left shank) while pushed
        dots = pos[on, 0] if site == "hip" else 0.5 * (pos[on, 3] + pos[on, 4])
        ax.plot(dots[:, 0], dots[:, 1], "k.", ms=4)
        ax.set_title(f"Fig. 7{name[0]}: {f:.0f} N forward on the {site} for 0.2 s (dots)")
        plots.save(fig, out / f"fig7{name[0].lower()}_{site}.png")

    fig = plots.figure(10, 3.5)
    ax = fig.add_subplot(121)
    for name, c in (("A_shank_200N", plots.LEFT), ("B_hip_288N", "k")):
        tol = res[name]["tolerance"]
        ax.plot(tol["forces_N"], ~tol["fell"], "o-", color=c, label=name)
    ax.set_xlabel("forward push for 0.2 s [N]")
    ax.set_ylabel("walking afterwards (1) / fell (0)")
    ax.legend(fontsize=7)
    ax = fig.add_subplot(122)
    for name, c in (("A_shank_200N", plots.LEFT), ("B_hip_288N", "k")):
        mp = res[name]["onset_phase_map"]
        ax.plot(mp["phase_of_stride"], ~mp["fell"], "o-", color=c, label=name)
    ax.set_xlabel("push onset, fraction of the stride after right touchdown")
    ax.legend(fontsize=7)
    plots.save(fig, out / "fig7_tolerance.png")

    return _write(
        out,
        "fig7",
        dict(
            right_touchdown_s=t_ref,
            push_duration_s=0.2,
            baseline=base,
            cases=res,
            paper=dict(
                A="200 N forward on link 5 (shank) in swing for 0.2 s: returns to steady walking"
                " within a few steps",
                B="288 N forward on link 1 for 0.2 s: returns to steady walking",
            ),
        ),
    )


# ---------------------------------------------------------------------------- ground
def _stable_range(vals, ok, nominal):
    """[lowest, highest] of the contiguous walking run around ``nominal``, and whether
    each end is the edge of the tested list (open) -> (range, open_ends) or (None, None)."""
    i0 = int(np.argmin(np.abs(vals - nominal)))
    if not ok[i0]:
        return None, None
    lo = hi = i0
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    while hi < len(vals) - 1 and ok[hi + 1]:
        hi += 1
    return [vals[lo], vals[hi]], [lo == 0, hi == len(vals) - 1]


def ground(out: Path, quick: bool = False) -> dict:
    """Walking for a range of ground stiffness k_g and damping b_g (section 4.1.3).

    Each value is changed one at a time (the other at its Appendix D value), in one
    vmapped batch, from two starts: the Appendix E state (as in section 4.1.1) and the
    steady walking state reached with the nominal ground after 20 s (does the limit cycle
    persist?).  "Walks" = no fall in 20 s and a regular gait: stride-length SD below
    ``REGULAR_SD_M`` over the last 10 s.  dt = 0.1 ms because the ground damper is
    explicit: b_g dt / m_eff must stay below ~2 with an effective ankle mass m_eff of
    about 1.5-2.5 kg.
    """
    dt = 0.00025 if quick else 0.0001
    sim = default_sim(dt)
    dur = 8.0 if quick else 20.0
    if quick:
        kgs = np.array([5e3, 1e4, 2e4])
        bgs = np.array([5e2, 1e3, 5e3])
    else:
        kgs = np.array([3e3, 4e3, 5e3, 6e3, 7e3, 8e3, 9e3, 1e4, 1.5e4, 2e4, 2.5e4, 3e4, 4e4, 6e4])
        bgs = np.array([3e2, 4e2, 5e2, 6e2, 7e2, 8e2, 1e3, 2e3, 5e3, 1e4, 1.5e4, 2e4])
    kg = np.concatenate([kgs, np.full(len(bgs), 1e4)])
    bg = np.concatenate([np.full(len(kgs), 1e3), bgs])
    nk = len(kgs)
    st_e = sim.init(event_capacity=256)
    st_s, _ = _gait(sim, dur)
    st_s = st_s.replace(events=st_e.events)
    result = {}
    for start, st0 in (("appendix_e", st_e), ("steady_walk", st_s)):
        stv, logv = batched(sim, _batch(len(kg), k_g=kg, b_g=bg), st0, terr.flat(), dur)
        rows = []
        t_start = float(st0.t)
        for i in range(len(kg)):
            m = measures.gait_measures(
                _member(logv, i), _member(stv.events, i), _member(stv, i), t_start + dur / 2
            )
            sd = m["stride_length_sd_m"]
            regular = sd is not None and sd < REGULAR_SD_M
            rows.append(dict(k_g=kg[i], b_g=bg[i], walks=not m["fell"] and regular, **m))
        ok = np.array([r["walks"] for r in rows])
        rk, ok_k = _stable_range(kgs, ok[:nk], 1e4)
        rb, ok_b = _stable_range(bgs, ok[nk:], 1e3)
        result[start] = dict(
            runs=rows,
            stable_k_g=dict(range=rk, open_ends=ok_k, b_g=1e3),
            stable_b_g=dict(range=rb, open_ends=ok_b, k_g=1e4),
        )
    fig = plots.figure(10, 3.5)
    for k, (vals, sl, name) in enumerate(
        ((kgs, slice(0, nk), "k_g [N/m]"), (bgs, slice(nk, None), "b_g [N s/m]"))
    ):
        ax = fig.add_subplot(1, 2, k + 1)
        for start, mk, col in (("appendix_e", "o", "k"), ("steady_walk", "s", "tab:blue")):
            rows = result[start]["runs"][sl]
            sp = np.array([r["speed_mps"] if r["speed_mps"] is not None else np.nan for r in rows])
            okk = np.array([r["walks"] for r in rows])
            ax.semilogx(vals, np.where(okk, sp, np.nan), mk + "-", color=col, ms=4, label=start)
            ax.semilogx(vals[~okk], np.zeros((~okk).sum()), "x", color=col)
        lo, hi = (8e3, 2e4) if k == 0 else (8e2, 1e4)
        ax.axvspan(lo, hi, color="0.88", label="paper: stable")
        ax.xaxis.set_minor_formatter(plots.NullFormatter())
        ax.set_xlabel(name)
        ax.set_ylabel("speed [m/s] (x = fell)")
        ax.legend(fontsize=7)
    plots.save(fig, out / "ground_range.png")
    return _write(
        out,
        "ground",
        dict(dt_s=dt, duration_s=dur, **result, paper=dict(k_g=[8e3, 2e4], b_g=[8e2, 1e4])),
    )


# ---------------------------------------------------------------------------- slope
def slope(out: Path, quick: bool = False) -> dict:
    """Uphill and downhill walking (section 4.1.3, Fig. 8); the slope starts 5 m ahead."""
    sim = default_sim()
    dur = 15.0 if quick else 30.0
    step = 0.02 if quick else 0.005
    steep_down = [-0.3, -0.2, -0.1] if quick else [-0.35, -0.3, -0.25, -0.2, -0.15, -0.1, -0.08]
    grades = np.round(np.concatenate([steep_down, np.arange(-0.06, 0.10 + 1e-9, step)]), 4)
    start = 5.0
    ts = [terr.slope(float(g), start=start) for g in grades]
    tb = jax.tree_util.tree_map(lambda *a: jnp.stack(a), *ts)
    st0 = sim.init(event_capacity=256)
    stv, logv = batched(sim, _batch(len(grades)), st0, tb, dur, axes=(0, None, 0, None))
    rows = []
    for i, g in enumerate(grades):
        lg, ev, s = _member(logv, i), _member(stv.events, i), _member(stv, i)
        m = measures.gait_measures(lg, ev, s)
        rows.append(dict(grade=g, walks=not m["fell"], **m))
    ok = np.array([r["walks"] for r in rows])
    up = grades >= 0
    max_up = None
    for g, k in zip(grades[up], ok[up], strict=True):
        if not k:
            break
        max_up = g
    down = [
        dict(grade=r["grade"], walks=r["walks"], fell_at_s=r["duration_s"] if r["fell"] else None)
        for r in rows
        if r["grade"] < 0
    ]
    if max_up is not None:
        i = int(np.nonzero(grades == max_up)[0][0])
        lg = _member(logv, i)
        pos = plots.joint_positions(sim.tb, lg.qpos)
        t = np.asarray(lg.t)
        sel = np.nonzero(t >= dur - 8.0)[0][::10]
        fig = plots.figure(14, 3.5)
        ax = fig.add_subplot(111)
        plots.stick_figure(
            ax, pos, sel, terrain_fn=lambda x: np.asarray(ts[i].height(jnp.asarray(x)))
        )
        ax.set_title(
            f"Fig. 8: uphill walking on a {100 * max_up:.1f} % slope (last 8 s, every 0.1 s)"
        )
        plots.save(fig, out / "fig8_uphill_stick.png")
    fig = plots.figure(7, 3.5)
    ax = fig.add_subplot(111)
    sp = np.array([r["speed_mps"] if r["speed_mps"] is not None else np.nan for r in rows])
    ax.plot(100 * grades[ok], sp[ok], "o-k", label="walks")
    ax.plot(100 * grades[~ok], np.zeros((~ok).sum()), "xr", label="falls")
    ax.axvline(6.0, color="0.6", ls="--", label="paper: 6 % uphill limit")
    ax.set_xlabel("grade [%] (negative = downhill)")
    ax.set_ylabel("speed [m/s]")
    ax.legend(fontsize=8)
    plots.save(fig, out / "slope_speed.png")
    return _write(
        out,
        "slope",
        dict(
            duration_s=dur,
            slope_start_m=start,
            runs=rows,
            max_uphill_grade=max_up,
            downhill=down,
            paper=dict(max_uphill_grade=0.06, downhill="falls"),
        ),
    )


# ---------------------------------------------------------------------------- fig11
def fig11(out: Path, quick: bool = False) -> dict:
    """Continuous up/down sweep of u0 (Fig. 11) plus the u0 survey from Appendix E."""
    sim = default_sim()
    if quick:
        up = [4.0, 5.0, 6.0, 7.0, 7.5, 8.0]
        down = [7.5, 7.0, 6.5, 6.0, 5.0, 4.0]
        plateau = 8.0
    else:
        up = [round(x, 2) for x in np.arange(4.0, 8.0 + 1e-9, 0.2)] + [8.1]
        down = [round(x, 2) for x in np.arange(8.0, 3.6 - 1e-9, -0.2)]
        plateau = 20.0
    levels = np.array(up + down)
    log_dt = 0.01
    per = int(round(plateau / log_dt))
    knots = [(k * plateau, {"u0": float(u)}) for k, u in enumerate(levels)]
    drive = commands.schedule(DRIVE, knots)  # u0 held at each level for one plateau
    cap = int(len(levels) * plateau * 6)
    st, log = simulate(
        TagaParams(u0=levels[0]),
        len(levels) * plateau,
        sim=sim,
        log_dt=log_dt,
        state=sim.init(event_capacity=cap),
        commands=drive,
    )
    rows = []
    for k, u0 in enumerate(levels):
        t0, t1 = k * plateau + plateau / 2, (k + 1) * plateau
        m = measures.window_measures(log, st.events, t0, t1)
        alive = bool(np.asarray(log.alive)[min((k + 1) * per, len(levels) * per) - 1])
        m["fell"] = not alive
        rows.append(dict(u0=u0, sweep="up" if k < len(up) else "down", gait=_gait_class(m), **m))
    ups, downs = rows[: len(up)], rows[len(up) :]
    up_switch = next((r["u0"] for r in ups if r["gait"] == "run"), None)
    down_switch = next((r["u0"] for r in downs if r["gait"] == "walk"), None)
    run_down = [r["u0"] for r in downs if r["gait"] == "run"]
    walk_up = [r["u0"] for r in ups if r["gait"] == "walk"]
    coexist = None
    if run_down and walk_up:
        lo, hi = min(run_down), max(walk_up)
        coexist = [lo, hi] if lo <= hi else None

    # where does running end? from steady running (taga_run after 20 s) set u0 higher
    st_r, _ = _gait(sim, 20.0, RUN_U0)
    st_r = st_r.replace(events=sim.init(event_capacity=256).events)
    hi_u0 = (
        np.array([8.0, 8.1, 8.2, 8.3, 8.4])
        if quick
        else np.array([7.9, 8.0, 8.1, 8.2, 8.25, 8.3, 8.35, 8.4, 8.5])
    )
    stv, logv = batched(
        sim, _batch(len(hi_u0), u0=hi_u0), st_r, terr.flat(), 15.0 if quick else 30.0
    )
    run_limit = []
    for i, u0 in enumerate(hi_u0):
        s = _member(stv, i)
        run_limit.append(
            dict(
                u0=u0,
                fell=bool(s.fell),
                fell_after_s=float(s.t_end) - 20.0 if bool(s.fell) else None,
            )
        )

    # which gait each u0 reaches from the Appendix E state
    su0 = np.arange(3.5, 9.01, 0.5) if quick else np.round(np.arange(3.5, 9.01, 0.25), 2)
    stv, logv = batched(
        sim,
        _batch(len(su0), u0=su0),
        sim.init(event_capacity=256),
        terr.flat(),
        12.0 if quick else 20.0,
    )
    survey = []
    for i, u0 in enumerate(su0):
        m = measures.gait_measures(_member(logv, i), _member(stv.events, i), _member(stv, i))
        survey.append(dict(u0=u0, gait=_gait_class(m), **m))

    fig = plots.figure(13, 3.8)
    for k, (key, lab) in enumerate(
        (
            ("stride_length_m", "stride length [m]"),
            ("stride_duration_s", "stride duration [s]"),
            ("speed_mps", "speed [m/s]"),
        )
    ):
        ax = fig.add_subplot(1, 3, k + 1)
        for rs, col, off in ((ups, "tab:blue", -0.02), (downs, "tab:orange", 0.02)):
            for r in rs:
                v = r[key]
                if v is None or not np.isfinite(v) or r["gait"] not in ("walk", "run"):
                    continue
                mk = "s" if r["gait"] == "walk" else "D"
                ax.plot(r["u0"] + off, v, mk, mfc="none" if rs is downs else col, color=col, ms=5)
        ax.set_xlabel("u0")
        ax.set_ylabel(lab)
        if coexist:
            ax.axvspan(coexist[0] - 0.05, coexist[1] + 0.05, color="0.9")
    fig.suptitle(
        "Fig. 11: squares walking, diamonds running; filled = u0 up, open = u0 down", fontsize=9
    )
    plots.save(fig, out / "fig11_bifurcation.png")

    t, uu = np.asarray(log.t), np.asarray(log.u0)
    fig = plots.figure(12, 3.5)
    ax = fig.add_subplot(111)
    x = np.asarray(log.qpos[:, 0])
    n_avg = int(2.0 / log_dt)
    v = (x[n_avg:] - x[:-n_avg]) / (n_avg * log_dt)
    ax.plot(t[n_avg:], v, lw=0.6, color="k", label="hip speed (2 s window)")
    ax2 = ax.twinx()
    ax2.plot(t, uu, color="tab:green", lw=1.0, label="u0")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("speed [m/s]")
    ax2.set_ylabel("u0")
    plots.save(fig, out / "fig11_sweep_timeline.png")

    return _write(
        out,
        "fig11",
        dict(
            plateau_s=plateau,
            levels=levels,
            sweep=rows,
            walk_to_run_on_the_way_up_at_u0=up_switch,
            run_to_walk_on_the_way_down_at_u0=down_switch,
            coexistence_u0=coexist,
            sweep_fell=bool(st.fell),
            sweep_fell_at_s=float(st.t_end) if bool(st.fell) else None,
            running_limit_from_steady_running=run_limit,
            survey_from_appendix_e=survey,
            paper=dict(
                walk_u0=5.5,
                run_u0=8.3,
                transition="abrupt, with hysteresis; walking and running coexist (Fig. 11)",
            ),
        ),
    )


# ---------------------------------------------------------------------------- CLI
def run(name: str, out: Path, quick: bool = False) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    fn = {
        "fig5": fig5,
        "fig6": fig6,
        "fig7": fig7,
        "ground": ground,
        "slope": slope,
        "fig11": fig11,
    }
    if name not in fn:
        raise SystemExit(f"unknown experiment {name!r}; choose from {COMMANDS + ('all',)}")
    t0 = time.time()
    res = fn[name](out, quick)
    print(
        f"[taga] {name}: done in {time.time() - t0:.0f} s -> {out / (name + '.json')}", flush=True
    )
    return res


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m jaxgait.taga.experiments", description=__doc__.split("\n")[0]
    )
    ap.add_argument("experiment", choices=COMMANDS + ("all",))
    ap.add_argument("--out", default="taga_results", help="output folder (PNG + JSON)")
    ap.add_argument("--quick", action="store_true", help="small, fast versions")
    a = ap.parse_args(argv)
    out = Path(a.out)
    names = COMMANDS if a.experiment == "all" else (a.experiment,)
    summary = {n: run(n, out, a.quick) for n in names}
    if a.experiment == "all":
        _write(out, "summary", summary)


if __name__ == "__main__":
    main()
