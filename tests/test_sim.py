"""The whole-body step and rollout: energy on passive motion, MuJoCo agreement, jit hygiene."""

import copy
import dataclasses
import math

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxgait import sim
from jaxgait.body.joints import SoftLimits
from jaxgait.world import envs
from jaxgait.world.contact import ContactParams


def _passive(model, contact=None, limits=None):
    """The model with muscles that produce no force (F_max = 0)."""
    table = dataclasses.replace(model.muscles, f_max=np.zeros_like(model.muscles.f_max))
    return dataclasses.replace(
        model,
        muscles=table,
        contact=contact or model.contact,
        limits=limits or model.limits,
    )


def _energy(model, qpos, qvel, contact_k, limit_k):
    """Kinetic + gravitational (MuJoCo C) + contact and soft-limit spring energy [J]."""
    m = copy.copy(model.body.mj_model)  # never change the shared model (MJX rejects the flag)
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    d.qvel[:] = qvel
    mujoco.mj_forward(m, d)
    e = d.energy[0] + d.energy[1]
    pts = np.asarray(model.points(jnp.asarray(qpos), 0.0))[:4]
    depth = np.maximum(-pts[:, 1], 0.0)
    e += 0.5 * contact_k * np.sum(depth**2)
    from jaxgait.body.joints import q_to_phi

    phi = np.asarray(q_to_phi(jnp.asarray(qpos)[jnp.asarray(model._ids[3])]))
    lim = model.limits
    over = np.maximum(phi - np.asarray(lim.upper), 0) + np.maximum(np.asarray(lim.lower) - phi, 0)
    e += 0.5 * limit_k * np.sum(over**2)
    return e


@pytest.mark.parametrize("dynamics", ["mjx", "planar"])
def test_passive_drop_conserves_energy(fbl_model, dynamics):
    """A passive drop with all damping off conserves energy.

    Muscles produce no force; the ligament springs, made stiff and centred on the pose,
    hold the posture; contact and soft-limit damping are off and there is no friction.
    The body falls 5 cm, lands on both feet and bounces on the contact springs.
    """
    jax.config.update("jax_enable_x64", True)
    try:
        pose = np.deg2rad([185.0, 170.0, 85.0])  # GH angles of both legs (slightly extended hip)
        cp = ContactParams(v_n_max=math.inf, v_t_max=math.inf, mu_slide=0.0, mu_stick=0.0)
        lim = SoftLimits(lower=tuple(pose), upper=tuple(pose), k=3000.0, omega_ref=math.inf)
        model = _passive(fbl_model, cp, lim)
        cfg = sim.SimConfig(
            duration=10.0, v0=0.0, fall_hip_height=-10.0, fall_pitch=10.0, dynamics=dynamics
        )
        env = envs.make_env("flat", jax.random.PRNGKey(0))
        env = jax.tree.map(
            lambda x: jnp.asarray(x, jnp.float64) if x.dtype == jnp.float32 else x, env
        )
        params = jnp.asarray(model.table.init, jnp.float64)
        s = sim.initial_state(model, params, env, cfg)
        from jaxgait.body.joints import phi_to_q

        q_leg = jnp.asarray(phi_to_q(jnp.asarray(pose)))
        qpos = s.qpos.at[2].set(0.0).at[3:6].set(q_leg).at[6:9].set(q_leg)
        lowest = float(np.min(np.asarray(model.points(qpos, 0.0))[:4, 1]))
        s = s.replace(qpos=qpos.at[1].add(0.05 - lowest))  # feet 5 cm above the ground
        step = jax.jit(
            lambda s: jax.lax.fori_loop(0, 50, lambda i, s: sim.step(model, cfg, params, env, s), s)
        )
        energies, min_z = [], []
        for _ in range(40):  # 1 s
            s = step(s)
            energies.append(_energy(model, np.asarray(s.qpos), np.asarray(s.qvel), cp.k_n, lim.k))
            min_z.append(float(np.min(np.asarray(model.points(s.qpos, 0.0))[:4, 1])))
        e = np.array(energies)
        assert min(min_z) < -1e-3  # the feet did hit the ground
        # semi-implicit Euler: a bounded O(dt) energy error (< 0.1 % of ~ 910 J), no drift
        assert np.max(np.abs(e - e[0])) < 1.0, np.max(np.abs(e - e[0]))
        assert abs(e[-10:].mean() - e[:10].mean()) < 0.5
    finally:
        jax.config.update("jax_enable_x64", False)


@pytest.mark.parametrize("dynamics", ["mjx", "planar"])
def test_integrator_matches_mujoco_c_in_flight(fbl_model, dynamics):
    """With muscles off and the body in the air, the step is MuJoCo's semi-implicit Euler
    (with MJX's passes or the planar tree's equations of motion: both against the C library)."""
    jax.config.update("jax_enable_x64", True)
    try:
        model = _passive(fbl_model, limits=SoftLimits(lower=(-9.0,) * 3, upper=(9.0,) * 3))
        cfg = sim.SimConfig(
            duration=10.0, v0=1.0, fall_hip_height=-10.0, fall_pitch=10.0, dynamics=dynamics
        )
        env = envs.make_env("flat", jax.random.PRNGKey(0))
        env = jax.tree.map(
            lambda x: jnp.asarray(x, jnp.float64) if x.dtype == jnp.float32 else x, env
        )
        params = jnp.asarray(model.table.init, jnp.float64)
        s = sim.initial_state(model, params, env, cfg)
        s = s.replace(
            qpos=s.qpos.at[1].add(1.0), qvel=s.qvel.at[3:].set(jnp.asarray([1, -2, 3, -1, 2, -3.0]))
        )
        m = model.body.mj_model
        d = mujoco.MjData(m)
        d.qpos[:] = np.asarray(s.qpos)
        d.qvel[:] = np.asarray(s.qvel)
        step = jax.jit(lambda s: sim.step(model, cfg, params, env, s))
        for _ in range(300):
            s = step(s)
            mujoco.mj_step(m, d)
        np.testing.assert_allclose(np.asarray(s.qpos), d.qpos, atol=1e-9)
        np.testing.assert_allclose(np.asarray(s.qvel), d.qvel, atol=1e-8)
    finally:
        jax.config.update("jax_enable_x64", False)


@pytest.fixture(scope="module")
def short_rollout(fbl_model):
    cfg = sim.SimConfig(duration=0.2, chunk_s=0.1, log_dt=0.01)
    return cfg, sim.make_rollout(fbl_model, cfg, batched=True)


def test_rollout_shapes_and_no_recompile(fbl_model, short_rollout):
    cfg, roll = short_rollout
    B = 2
    env = envs.make_env_batch("flat", jax.random.split(jax.random.PRNGKey(0), B))
    p1 = jnp.broadcast_to(jnp.asarray(fbl_model.table.init, jnp.float32), (B, fbl_model.table.size))
    tr, ev, sm, _ = roll(p1, env)
    assert tr.qpos.shape == (B, 20, 9) and tr.act.shape == (B, 20, 2, 7)
    assert np.all(np.asarray(sm.duration) == pytest.approx(0.2, abs=1e-3))
    n = roll._cache_size()
    p2 = p1 * 1.01  # new parameter values, same shapes: no new compilation
    roll(p2, env)
    assert roll._cache_size() == n == 1


def test_fall_stops_and_freezes_summary(fbl_model):
    """A parameter set that cannot stand falls; the summary is frozen at the fall."""
    cfg = sim.SimConfig(duration=3.0, chunk_s=0.5, log_dt=0.01)
    roll = sim.make_rollout(fbl_model, cfg, batched=False)
    table = fbl_model.table
    weak = table.pack({"G_VAS": table.lower[table.index("G_VAS")], "G_SOL": 0.8, "S0_VAS": 0.01})
    tr, ev, sm, s = roll(
        jnp.asarray(weak, jnp.float32), envs.make_env("flat", jax.random.PRNGKey(0))
    )
    assert bool(sm.fell)
    assert float(sm.duration) < 3.0
    alive = np.asarray(tr.alive)
    # the trace is alive up to the fall and not after
    k = int(alive.sum())
    assert alive[:k].all() and not alive[k:].any()
    assert abs(float(tr.t[k - 1]) - float(sm.duration)) <= 0.011


def test_clock_stays_on_the_step_grid(fbl_model):
    """t after n steps is n dt: 20,000 float32 additions of dt drift by milliseconds."""
    cfg = sim.SimConfig(duration=1e6, fall_hip_height=-1e3, fall_pitch=1e3)
    p = jnp.asarray(fbl_model.table.init, jnp.float32)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    s0 = sim.initial_state(fbl_model, p, env, cfg)
    run = jax.jit(
        lambda s: jax.lax.fori_loop(0, 20000, lambda i, s: sim.step(fbl_model, cfg, p, env, s), s)
    )
    s = run(s0)
    assert float(s0.t) == 0.0
    assert float(s.t) == pytest.approx(20000 * fbl_model.dt, abs=2e-6)


@pytest.mark.parametrize(
    "field, value",
    [("muscle_substeps", 0), ("ce_solve_iters", -1), ("ce_solve_iters", 1.5), ("max_events", 0)],
)
def test_sim_config_rejects_bad_counts(field, value):
    with pytest.raises(ValueError, match=f"SimConfig.{field}"):
        sim.SimConfig(**{field: value})
