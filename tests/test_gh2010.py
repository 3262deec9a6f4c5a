"""Geyer's model as Geyer ran it: the thigh pressure-sheet load signal against its law and the
body's geometry, and Geyer's stance balance block against hand-computed values."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import models, sim
from jaxgait.control.fbl import (
    FBL,
    GAS,
    GLU,
    HAM,
    HFL,
    N_SENSORS,
    S_DS,
    S_DTRUNK,
    S_LOAD,
    S_STANCE,
    S_TRUNK,
    SOL,
    TA,
    VAS,
    fbl_stimulation,
)
from jaxgait.control.gait import GaitConfig, thigh_sheet_load
from jaxgait.control.gh2010 import GH2010_PARAMS, GLU_OF_HAM, gh2010_stimulation
from jaxgait.presets import load_preset
from jaxgait.sim.step import leg_load

G = 9.81
M_BELOW = 0.8 * 8.5 + 3.5 + 1.25  # lower 4/5 of the thigh, shank, foot [kg]
M_HAT = 53.5


def test_sheet_masses_are_geyers_split_of_the_thigh():
    below, hat = models.get_model("fbl_gh2010").sheet_masses
    assert below == pytest.approx(M_BELOW) and hat == pytest.approx(M_HAT)


def test_sheet_load_by_hand():
    # vertical thigh carrying the body weight: (784.8 - 11.55 g) / (53.5 g)
    load = thigh_sheet_load(jnp.array([[0.0, 80 * G], [0.0, 0.0]]), jnp.zeros(2), M_BELOW, M_HAT)
    np.testing.assert_allclose(load, [(80 * G - M_BELOW * G) / (M_HAT * G), 0.0], rtol=1e-6)
    # thigh pitched 30 deg: the GRF and the weight below are projected on (sin a, cos a)
    a = np.deg2rad(30.0)
    grf = jnp.array([[100.0, 800.0], [-50.0, 10.0]])
    load = thigh_sheet_load(grf, jnp.array([a, a]), M_BELOW, M_HAT)
    expect = (100 * np.sin(a) + 800 * np.cos(a) - M_BELOW * G * np.cos(a)) / (M_HAT * G)
    # the lightly loaded leg: -25 + 8.66 - 98.1 < 0, the sheet in tension reads 0
    np.testing.assert_allclose(load, [expect, 0.0], rtol=1e-6)


def test_sheet_axis_is_the_thigh_of_the_body():
    """The unit vector the law projects on points from the knee to the hip in the body."""
    model = models.get_model("fbl_gh2010")
    body = model.body
    q = np.zeros(body.mj_model.nq)
    q[2], q[3], q[6] = 0.1, 0.5, -0.3  # trunk pitch, right and left hip
    origins, angles = body.frames(jnp.asarray(q))
    shank = [body.mj_model.body(n).id for n in ("shank_r", "shank_l")]
    hip_to_knee = origins[np.asarray(shank)] - origins[model.thigh_ids]
    a = angles[model.thigh_ids]
    u = np.stack([np.sin(a), np.cos(a)], -1)
    np.testing.assert_allclose(-hip_to_knee / 0.5, u, atol=1e-6)
    # so a leg pushed along its thigh by F reads (F - the weight's share) / (m_HAT g)
    f = 700.0
    grf = jnp.asarray(f * u)
    load = leg_load(model, jnp.asarray(q), None, grf)
    np.testing.assert_allclose(load, (f - M_BELOW * G * u[:, 1]) / (M_HAT * G), rtol=1e-5)


def test_grf_load_signal_is_the_gait_detections_filtered_load():
    model = models.get_model("fbl")

    class _G:
        load = jnp.array([0.7, 0.2])

    np.testing.assert_array_equal(leg_load(model, None, _G, None), _G.load)
    with pytest.raises(ValueError, match="load_signal"):
        GaitConfig(load_signal="pressure")


def _sensors(stance, ds, theta, dtheta, load):
    s = np.zeros((2, N_SENSORS), np.float32)
    s[:, S_STANCE], s[:, S_DS] = stance, ds
    s[:, S_TRUNK], s[:, S_DTRUNK], s[:, S_LOAD] = theta, dtheta, load
    s[:, 7:14] = 1.0  # l_ce / l_opt
    s[:, 0:7] = 0.3  # F / F_max
    return jnp.asarray(s)


def test_geyers_stance_balance_block_by_hand():
    p = {k: jnp.float32(v) for k, v in GH2010_PARAMS.items()}
    kp, kd, ref, dS = 1.9099, 0.2, 0.1047, 0.25
    # right leg: stance, leaning forward (u > 0), trailing in double support, load 2;
    # left leg: stance, leaning back (u < 0), load 0.5
    theta = np.array([0.3, -0.1], np.float32)
    s = _sensors([1.0, 1.0], [1.0, 0.0], theta, [0.5, -0.2], [2.0, 0.5])
    out = np.asarray(gh2010_stimulation(p, s))
    u = kp * (theta - ref) + kd * np.array([0.5, -0.2])
    load = np.array([2.0, 0.5])
    ham = np.clip((0.05 + np.maximum(u, 0)) * load, 0, 1)
    hfl = np.clip((0.05 + np.maximum(-u, 0)) * load, 0, 1) + np.array([1.0, 0.0]) * dS
    glu = GLU_OF_HAM * ham - GLU_OF_HAM * np.array([1.0, 0.0]) * dS
    np.testing.assert_allclose(out[:, HAM], ham, rtol=1e-5)
    np.testing.assert_allclose(out[:, HFL], hfl, rtol=1e-5)
    np.testing.assert_allclose(out[:, GLU], glu, rtol=1e-5, atol=1e-7)
    # right: HAM clipped at 1; HFL only its prestimulation, gated by the load, plus delta_S
    assert ham[0] == 1.0 and hfl[0] == pytest.approx(0.05 * 2.0 + dS)
    # the other muscles are FBL's (Table 2.4 and Geyer agree there)
    ref_out = np.asarray(fbl_stimulation(p, s))
    for m in (SOL, TA, GAS, VAS):
        np.testing.assert_allclose(out[:, m], ref_out[:, m], rtol=1e-6)


def test_swing_is_fbls():
    p = {k: jnp.float32(v) for k, v in GH2010_PARAMS.items()}
    s = _sensors([0.0, 0.0], [0.0, 0.0], [0.2, 0.2], [0.1, 0.1], [0.0, 0.0])
    np.testing.assert_allclose(gh2010_stimulation(p, s), fbl_stimulation(p, s), rtol=1e-6)


def test_shipped_gh2010_preset_is_geyers_gains_on_the_faithful_model():
    model, vec, _ = load_preset("fbl_gh2010")
    assert model == "fbl_gh2010"
    m = models.get_model(model)
    assert m.gait.load_signal == "thigh_sheet"
    expect = np.asarray(FBL.init, np.float32).copy()
    expect[FBL.index("k_bw")] = 1.0
    np.testing.assert_allclose(vec, expect, rtol=1e-6)
    cfg = sim.SimConfig(duration=0.3, chunk_s=0.3)
    f = sim.make_rollout(m, cfg, batched=False)
    from jaxgait.world import envs

    _, _, summary, _ = f(jnp.asarray(vec), envs.make_env("flat", jax.random.PRNGKey(0)))
    assert float(summary.duration) == pytest.approx(0.3, abs=1e-3)


# ----------------------------------------------------------------------- start options
def _start(**kw):
    from jaxgait.world import envs

    m = models.get_model("fbl")
    vec = jnp.asarray(FBL.init, jnp.float32)
    cfg = sim.SimConfig(duration=0.1, **kw)
    return m, vec, sim.initial_state(m, vec, envs.make_env("flat", jax.random.PRNGKey(0)), cfg)


def test_rest_start_has_every_muscle_at_the_minimum_activation():
    _, _, s = _start()
    np.testing.assert_array_equal(np.asarray(s.muscle.act), np.float32(0.01))


def test_reflex_start_is_a_fixed_point_of_the_controllers_stimulation():
    """With ``start_activation="reflex"`` the activation is the controller's stimulation of
    the start sensors, clipped to [0.01, 1], and the muscles rest at it: one more pass of
    stimulation -> resting force -> sensors changes no activation by more than 1e-4."""
    from jaxgait.body.joints import q_to_phi
    from jaxgait.muscles import mtu

    m, vec, s = _start(start_activation="reflex")
    act = np.asarray(s.muscle.act)
    # the stance leg's (right) force-fed extensors are above the rest level, and the swing
    # leg's VAS is off in swing (0 stimulation -> the minimum)
    assert act[0, VAS] > 0.05 and act[0, SOL] > 0.02
    assert act[1, VAS] == pytest.approx(0.01)
    # the CE rests at that activation
    l_mtu = mtu.mtu_length(m.muscles, q_to_phi(s.qpos[jnp.asarray(m._ids[3])]))
    np.testing.assert_allclose(
        np.asarray(s.muscle.l_ce),
        np.asarray(mtu.init_lce(m.muscles, l_mtu, s.muscle.act)),
        rtol=1e-6,
    )
    # a fixed point: the stimulation of the rested muscles' sensors is the activation again
    p = m.table.unpack(vec)
    buf = np.asarray(s.ctrl.buf)
    stim = fbl_stimulation(p, jnp.asarray(buf[-1]))
    np.testing.assert_allclose(np.clip(np.asarray(stim), 0.01, 1.0), act, atol=1e-4)


def test_zero_delay_start_fills_the_delay_lines_with_zeros():
    _, _, rest = _start()
    _, _, zero = _start(start_delays="zero")
    assert np.all(np.asarray(zero.ctrl.buf) == 0.0)
    assert np.any(np.asarray(rest.ctrl.buf) != 0.0)
    np.testing.assert_array_equal(np.asarray(zero.qpos), np.asarray(rest.qpos))


@pytest.mark.parametrize("field", ["start_activation", "start_delays"])
def test_unknown_start_option_is_refused_by_name(field):
    with pytest.raises(ValueError, match=field):
        sim.SimConfig(**{field: "standing"})
