"""Tests of the Taga et al. (1991) neural-oscillator biped (jaxgait.taga)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from mujoco import mjx

from jaxgait.taga import ground, measures, model, network, reference
from jaxgait.taga.model import TagaParams
from jaxgait.world import terrain

HIP_TAU, HIP_TAU_A, BETA = 0.05, 0.60, 2.5


# ------------------------------------------------------------------ body (Appendix D)
@pytest.fixture(scope="module")
def tb():
    return model.load()


def test_mjcf_holds_appendix_d_body(tb):
    m = tb.body.mj_model
    names = ["hip", "thigh_r", "shank_r", "thigh_l", "shank_l"]
    mass = {n: float(m.body(n).mass[0]) for n in names}
    assert mass == {"hip": 48.0, "thigh_r": 7.0, "shank_r": 4.0, "thigh_l": 7.0, "shank_l": 4.0}
    np.testing.assert_allclose(m.body("thigh_r").inertia[1], 7.0 * 0.5**2 / 12, rtol=1e-6)
    np.testing.assert_allclose(m.body("shank_l").inertia[1], 4.0 * 0.6**2 / 12, rtol=1e-6)
    np.testing.assert_allclose(m.opt.gravity, [0, 0, -9.8])
    # the keyframe is the Appendix E posture: ankle = (x_shank + l2/2 cos x11, ... )
    a = np.asarray(tb.body.sites(jnp.asarray(tb.keyframe_qpos), tb.ankle_ids))
    x = reference.appendix_e()
    for k, (i, j) in enumerate(((8, 10), (11, 13))):
        ank = [x[i] + 0.3 * np.cos(x[j]), x[i + 1] - 0.3 * np.sin(x[j])]
        np.testing.assert_allclose(a[k], ank, atol=1e-5)


def test_mjx_dynamics_match_the_papers_newton_euler_equations(tb):
    """MJX accelerations = eq. 4 (Appendices A, B) for random states, torques, ground forces."""
    rng = np.random.default_rng(0)
    mx = mjx.put_model(tb.body.mj_model)

    @jax.jit
    def mjx_qacc(q, dq, tau, fg):
        qfrc = tb.segment_torques_to_qfrc(q, tau) + tb.body.site_forces_to_qfrc(q, fg, tb.ankle_ids)
        d = mjx.make_data(mx).replace(qpos=q, qvel=dq, qfrc_applied=qfrc)
        return mjx.forward(mx, d).qacc

    paper_xdd = jax.jit(reference.accelerations)
    for _ in range(4):
        q = np.array([0.3, 1.0, *rng.uniform(-0.6, 0.6, 4)])
        dq = rng.uniform(-2, 2, 6)
        tau = rng.uniform(-50, 50, 4)
        fg = rng.uniform(-300, 600, (2, 2))
        f32 = lambda a: jnp.asarray(a, jnp.float32)
        qacc = np.asarray(mjx_qacc(f32(q), f32(dq), f32(tau), f32(fg)))
        x, xd = reference.from_qpos(q, dq)
        xdd = np.asarray(paper_xdd(f32(x), f32(xd), f32(tau), f32(fg)))
        expect = [xdd[0], xdd[1], xdd[4], xdd[10] - xdd[4], xdd[7], xdd[13] - xdd[7]]
        np.testing.assert_allclose(qacc, expect, rtol=2e-3, atol=2e-2)


# ------------------------------------------------------------------ Matsuoka oscillator (eq. 5)
def _two_neuron(tau, tau_a, u0, w=2.0, beta=BETA, t_end=30.0, dt=0.001):
    """Eq. 5 with RK4; returns (period [s], peak-to-peak amplitude of u1) over the last half."""
    wm = jnp.asarray([[0.0, -w], [-w, 0.0]])
    s = network.NeuralState(u=jnp.asarray([0.1, 0.0]), v=jnp.zeros(2))
    feed = jnp.zeros(2)

    def body(s, _):
        s = network.rk4_step(s, dt, wm, tau, tau_a, beta, u0, feed)
        return s, s.u

    _, u = jax.jit(lambda s: jax.lax.scan(body, s, None, length=int(t_end / dt)))(s)
    u = np.asarray(u)[int(t_end / dt) // 2 :]
    return measures.dominant_period(u[:, 0] - u[:, 1], dt), float(u[:, 0].max() - u[:, 0].min())


def test_matsuoka_oscillator_u0_sets_amplitude_not_frequency():
    p1, a1 = _two_neuron(HIP_TAU, HIP_TAU_A, 1.0)
    p5, a5 = _two_neuron(HIP_TAU, HIP_TAU_A, 5.0)
    assert np.isfinite(p1) and a1 > 0.1  # it oscillates
    assert p5 == pytest.approx(p1, rel=0.005)
    assert a5 / a1 == pytest.approx(5.0, rel=0.01)


def test_matsuoka_oscillator_time_constants_set_frequency():
    p, _ = _two_neuron(HIP_TAU, HIP_TAU_A, 5.5)
    p_half, _ = _two_neuron(HIP_TAU / 2, HIP_TAU_A / 2, 5.5)  # knee/ankle constants
    p_slow_adapt, _ = _two_neuron(HIP_TAU, 2 * HIP_TAU_A, 5.5)
    assert p_half == pytest.approx(p / 2, rel=0.01)  # halving tau, tau' doubles the frequency
    assert p_slow_adapt > 1.2 * p  # tau' alone also changes the frequency


# ------------------------------------------------------------------ network (eq. 6, App. C, D)
def test_weight_matrix_is_appendix_d():
    w = np.asarray(network.weight_matrix(-2.0, -1.0, -1.0))
    assert w[0, 1] == w[1, 0] == w[10, 11] == w[11, 10] == -2.0
    assert w[0, 2] == w[2, 0] == w[1, 3] == w[3, 1] == -1.0
    for i, j in ((6, 1), (6, 2), (8, 3), (8, 4), (10, 1), (10, 2), (12, 3), (12, 4)):
        assert w[i - 1, j - 1] == -1.0
    assert (w != 0).sum() == 12 + 4 + 8
    assert w[4, 0] == 0.0  # knee flexors are not inhibited by the hip


def test_isolated_network_hips_alternate_in_antiphase():
    p = TagaParams(u0=5.5).as_floats()
    w = network.weight_matrix(p.w_fe, p.w_rl, p.w_hka)
    tau, tau_a = network.time_constants(p.tau_hip, p.tau_hip_adapt, p.tau_ka, p.tau_ka_adapt)
    s0 = network.zeros()
    s0 = s0.replace(u=s0.u.at[0].set(0.1))  # break the flexor/extensor symmetry
    dt = 0.001
    _, u = network.isolated_rollout(s0, 40000, dt, w, tau, tau_a, p.beta, p.u0)
    u = np.asarray(u)[20000:]
    right, left = u[:, 0] - u[:, 1], u[:, 2] - u[:, 3]
    period = measures.dominant_period(right, dt)
    assert np.isfinite(period) and period == pytest.approx(
        measures.dominant_period(left, dt), rel=1e-3
    )
    tr = np.nonzero((right[:-1] < 0) & (right[1:] >= 0))[0] * dt
    tl = np.nonzero((left[:-1] < 0) & (left[1:] >= 0))[0] * dt
    lag = np.mean([((tl[tl > t][0] - t) / period) % 1 for t in tr if (tl > t).any()])
    assert lag == pytest.approx(0.5, abs=0.02)
    assert np.corrcoef(right, left)[0, 1] < -0.9


def test_feedback_is_appendix_c():
    rng = np.random.default_rng(1)
    a = rng.uniform(0.5, 3.0, 8)
    th = rng.uniform(-0.5, 0.5, 4)
    dsh = rng.uniform(-3, 3, 2)
    c = np.array([1.0, 0.0])
    x5, x8, x11, x14 = th + np.pi / 2
    h2, h4 = c
    a1, a2, a3, a4, a5, a6, a7, a8 = a
    hp = np.pi / 2
    expect = [
        a1 * (x5 - hp) - a2 * (x8 - hp) + a3 * (x11 - hp) * h2 + a4 * h4,
        a1 * (hp - x5) - a2 * (hp - x8) + a3 * (hp - x11) * h2 - a4 * h4,
        a1 * (x8 - hp) - a2 * (x5 - hp) + a3 * (x14 - hp) * h4 + a4 * h2,
        a1 * (hp - x8) - a2 * (hp - x5) + a3 * (hp - x14) * h4 - a4 * h2,
        a5 * (hp - x14) * h4,
        a5 * (x14 - hp) * h4,
        a5 * (hp - x11) * h2,
        a5 * (x11 - hp) * h2,
        a6 * (hp - x11) * h2 + a7 * (hp - x14) * h4 - a8 * dsh[0] * h2,
        a6 * (x11 - hp) * h2 + a7 * (x14 - hp) * h4 + a8 * dsh[0] * h2,
        a6 * (hp - x14) * h4 + a7 * (hp - x11) * h2 - a8 * dsh[1] * h4,
        a6 * (x14 - hp) * h4 + a7 * (x11 - hp) * h2 + a8 * dsh[1] * h4,
    ]
    got = network.feedback(jnp.asarray(th), jnp.asarray(dsh), jnp.asarray(c), jnp.asarray(a))
    np.testing.assert_allclose(np.asarray(got), expect, rtol=1e-5, atol=1e-5)


def test_ankle_torque_only_in_contact():
    y = jnp.arange(12.0) / 10
    p = TagaParams().p
    t_air = network.torques(y, jnp.zeros(2), p)
    t_r = network.torques(y, jnp.asarray([1.0, 0.0]), p)
    assert float(t_air[4]) == float(t_air[5]) == 0.0
    assert float(t_r[4]) == pytest.approx(75.0 * 0.9 - 100.0 * 0.8) and float(t_r[5]) == 0.0
    assert float(t_air[0]) == pytest.approx(85.0 * 0.1 - 15.0 * 0.0)  # T_r1 = p_e^h y2 - p_f^h y1


def test_knee_stop_and_viscosity():
    p = TagaParams()
    tr = jnp.zeros(6)
    # right knee hyper-extended by 0.01 rad (x5 - x11 > 0): the stop flexes it
    th = jnp.asarray([0.0, 0.0, -0.01, 0.0])
    q = model.joint_torques(th, jnp.zeros(4), tr, p)
    assert float(q[2]) == pytest.approx(100.0) and float(q[0]) == pytest.approx(-100.0)
    # flexed knee: no stop; relative knee rate damped by b2 only
    th = jnp.asarray([0.0, 0.0, 0.3, 0.0])
    q = model.joint_torques(th, jnp.asarray([0.0, 0.0, 1.0, 0.0]), tr, p)
    assert float(q[2]) == pytest.approx(-10.0) and float(q[0]) == pytest.approx(10.0)
    # hip viscosity b1 |x5 - pi/2| dx5 acts on the thigh alone
    q = model.joint_torques(jnp.asarray([0.2, 0.0, 0.2, 0.0]), jnp.asarray([1.0, 0, 1.0, 0]), tr, p)
    assert float(q[0]) == pytest.approx(-10.0 * 0.2) and float(q[2]) == pytest.approx(0.0)
    q_step = model.joint_torques(jnp.asarray([0.0, 0.0, -0.01, 0.0]), jnp.zeros(4), tr, p, "step")
    assert float(q_step[2]) == pytest.approx(1e4)


# ------------------------------------------------------------------ ground (Appendix A)
def test_ground_resets_rest_point_on_touchdown():
    flat = terrain.flat()
    gs = ground.initial()
    vel = jnp.asarray([[0.5, -0.2], [0.0, 0.0]])
    kg, bg = 1e4, 1e3
    # right ankle above the ground: no force, no rest point
    f, gs, td = ground.contact_forces(
        jnp.asarray([[0.30, 0.01], [0.0, 0.5]]), vel, gs, flat, kg, bg
    )
    assert not bool(td[0]) and float(jnp.abs(f).sum()) == 0.0
    # first step below the ground: rest point = touchdown point on the surface
    f, gs, td = ground.contact_forces(
        jnp.asarray([[0.31, -0.002], [0.0, 0.5]]), vel, gs, flat, kg, bg
    )
    assert bool(td[0]) and not bool(td[1])
    np.testing.assert_allclose(np.asarray(gs.rest[0]), [0.31, 0.0], atol=1e-7)
    np.testing.assert_allclose(np.asarray(f[0]), [-bg * 0.5, kg * 0.002 + bg * 0.2], rtol=1e-5)
    # while in contact the rest point stays put and the spring pulls back to it
    f, gs, td = ground.contact_forces(
        jnp.asarray([[0.35, -0.01], [0.0, 0.5]]), jnp.zeros((2, 2)), gs, flat, kg, bg
    )
    assert not bool(td[0])
    np.testing.assert_allclose(np.asarray(gs.rest[0]), [0.31, 0.0], atol=1e-7)
    np.testing.assert_allclose(np.asarray(f[0]), [-kg * 0.04, kg * 0.01], rtol=1e-4)
    # rising ankle: no vertical damping (b_g f(-dy/dt))
    f, gs, _ = ground.contact_forces(
        jnp.asarray([[0.35, -0.01], [0.0, 0.5]]),
        jnp.asarray([[0.0, 0.3], [0, 0]]),
        gs,
        flat,
        kg,
        bg,
    )
    assert float(f[0, 1]) == pytest.approx(kg * 0.01, rel=1e-4)
    # lift-off, then a new touchdown elsewhere resets the rest point there
    f, gs, _ = ground.contact_forces(jnp.asarray([[0.6, 0.05], [0.0, 0.5]]), vel, gs, flat, kg, bg)
    assert float(jnp.abs(f[0]).sum()) == 0.0
    f, gs, td = ground.contact_forces(
        jnp.asarray([[1.7, -0.001], [0.0, 0.5]]), vel, gs, flat, kg, bg
    )
    assert bool(td[0])
    np.testing.assert_allclose(np.asarray(gs.rest[0]), [1.7, 0.0], atol=1e-6)


def test_ground_rest_point_on_a_slope():
    up = terrain.slope(0.1, start=0.0)
    gs = ground.initial()
    f, gs, td = ground.contact_forces(
        jnp.asarray([[2.0, 0.19], [0.0, 5.0]]), jnp.zeros((2, 2)), gs, up, 1e4, 1e3
    )
    assert bool(td[0])
    np.testing.assert_allclose(np.asarray(gs.rest[0]), [2.0, 0.2], atol=1e-5)
    assert float(f[0, 1]) == pytest.approx(1e4 * 0.01, rel=1e-3)


# ------------------------------------------------------------------ presets and errors
def test_params_from_dict_and_presets():
    from jaxgait import taga

    p = model.params_from_dict({"u0": 6.0, "p_e_h": 90.0, "a5": 2.0})
    assert float(p.u0) == 6.0 and float(p.p[1]) == 90.0 and float(p.a[4]) == 2.0
    with pytest.raises(KeyError, match="unknown Taga parameter"):
        model.params_from_dict({"u00": 1.0})
    assert taga.load_preset("taga_walk")["params"]["u0"] == 5.5
    assert taga.load_preset("taga_run")["model"] == "taga"
    with pytest.raises(FileNotFoundError, match="available"):
        taga.load_preset("taga_nope")
    with pytest.raises(ValueError, match="model"):
        taga.load_preset({"model": "fbl", "params": {}})
    with pytest.raises(ValueError, match="environment"):
        taga.terrain_for("wavy")
    with pytest.raises(ValueError, match="knee_stop"):
        model.Options(knee_stop="soft")


# ------------------------------------------------------------------ whole model (slow)
@pytest.fixture(scope="module")
def walk_and_run():
    from jaxgait import taga

    return taga.evaluate_preset("taga_walk", 20.0), taga.evaluate_preset("taga_run", 20.0)


@pytest.mark.slow
def test_taga_walk_walks_20s(walk_and_run):
    w, _ = walk_and_run
    assert not w["fell"] and w["duration_s"] == pytest.approx(20.0, abs=1e-3)
    assert w["distance_m"] > 20.0
    assert 1.0 < w["speed_mps"] < 2.0
    assert w["double_support_fraction"] > 0.05 and w["flight_fraction"] == 0.0
    assert w["stride_length_m"] == pytest.approx(w["speed_mps"] * w["stride_duration_s"], rel=0.02)


@pytest.mark.slow
def test_taga_run_has_flight_and_no_double_support(walk_and_run):
    w, r = walk_and_run
    assert not r["fell"]
    assert r["flight_fraction"] > 0.1 and r["double_support_fraction"] == 0.0
    assert r["speed_mps"] > w["speed_mps"] and r["stride_duration_s"] < w["stride_duration_s"]
