"""FBL+ (thesis 2.1.3, Table 2.6): table, reduction to FBL, swing end and stance end."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import models, sim
from jaxgait.control import fbl as reflex
from jaxgait.control.fbl import (
    FBL,
    GAS,
    GLU,
    HAM,
    HFL,
    N_SENSORS,
    S_DCOM,
    S_DHIP,
    S_DKNEE,
    S_DS,
    S_HIP,
    S_KNEE,
    S_STANCE,
    SOL,
    TA,
    VAS,
    fbl_stimulation,
)
from jaxgait.control.fblplus import (
    EXTRA_NAMES,
    FBLPLUS,
    NEUTRAL,
    OFF,
    fblplus_stimulation,
    lift_fbl,
    phases_plus,
)
from jaxgait.presets import load_preset
from jaxgait.world.envs import make_env

_fbl = jax.jit(jax.vmap(fbl_stimulation, in_axes=(None, 0)))
_plus = jax.jit(jax.vmap(fblplus_stimulation, in_axes=(None, 0)))


def _p_fbl():
    return FBL.unpack(jnp.asarray(FBL.init, jnp.float32))


def _p_plus(**extras):
    return FBLPLUS.unpack(jnp.asarray(lift_fbl(FBL.init, extras), jnp.float32))


def _random_sensors(n, seed=0):
    """n random sensor arrays (n, 2, N_SENSORS) with plausible phase flags and angles."""
    rng = np.random.default_rng(seed)
    s = rng.normal(size=(n, 2, N_SENSORS)) * 0.5 + 0.5
    s[..., S_STANCE] = rng.integers(0, 2, (n, 2))
    s[..., S_DS] = s[..., S_STANCE] * rng.integers(0, 2, (n, 2))
    s[..., S_HIP] = np.pi + rng.uniform(-1.2, 0.4, (n, 2))
    s[..., S_KNEE] = np.pi - rng.uniform(0.0, 1.5, (n, 2))
    s[..., S_DHIP] = rng.normal(size=(n, 2)) * 3
    s[..., S_DKNEE] = rng.normal(size=(n, 2)) * 3
    s[..., S_DCOM] = rng.uniform(-2.9, 2.9, (n, 2))
    return jnp.asarray(s, jnp.float32)


def _sensors(stance, dcom, hip_deg=180.0, knee_deg=180.0, dhip=0.0, dknee=0.0, ds=0.0):
    """Both legs identical, one hand-made sensor array (2, N_SENSORS)."""
    s = np.full((2, N_SENSORS), 0.3)
    s[:, S_STANCE] = float(stance)
    s[:, S_DS] = ds
    s[:, S_DCOM] = dcom
    s[:, S_HIP] = np.deg2rad(hip_deg)
    s[:, S_KNEE] = np.deg2rad(knee_deg)
    s[:, S_DHIP] = dhip
    s[:, S_DKNEE] = dknee
    return jnp.asarray(s, jnp.float32)


# ------------------------------------------------------------------------------ table


def test_table_is_fbl_plus_ten_table_2_6_parameters():
    assert FBLPLUS.name == "fblplus"
    assert FBLPLUS.size == FBL.size + 10 == 38
    assert FBLPLUS.specs[: FBL.size] == FBL.specs
    assert EXTRA_NAMES == (
        "kp_HFL",
        "kd_HFL",
        "kp_GLU",
        "kd_GLU",
        "kp_VAS",
        "kd_VAS",
        "delta_hip_ref",
        "delta_knee_ref",
        "d_st_end",
        "d_sw_end",
    )
    rng = {s.name: (s.lower, s.upper) for s in FBLPLUS.specs}
    for m in ("HFL", "GLU", "VAS"):
        assert rng[f"kp_{m}"] == (0.0, 2.0) and rng[f"kd_{m}"] == (0.0, 1.0)
    assert rng["delta_hip_ref"] == (-1.0, 0.0)
    assert rng["delta_knee_ref"] == (0.0, 1.14)
    assert rng["d_st_end"] == (0.0, 3.0)
    assert rng["d_sw_end"] == (-2.5, 0.0)
    assert all("Table 2.6" in s.source for s in FBLPLUS.specs[FBL.size :])
    # the initial values are the neutral setting: no PD gain, stance end at its upper bound
    assert all(NEUTRAL[f"k{x}_{m}"] == 0.0 for x in "pd" for m in ("HFL", "GLU", "VAS"))
    assert NEUTRAL["d_st_end"] == 3.0
    np.testing.assert_array_equal(FBLPLUS.init, lift_fbl(FBL.init))


def test_lift_fbl_checks_its_input():
    with pytest.raises(ValueError, match="28"):
        lift_fbl(np.zeros(5))
    with pytest.raises(KeyError, match="nope"):
        lift_fbl(FBL.init, {"nope": 1.0})
    v = lift_fbl(FBL.init, {"kp_VAS": 1.5})
    assert v[FBLPLUS.index("kp_VAS")] == 1.5 and v.shape == (38,)


# ------------------------------------------------------------------------------ reduction


@pytest.mark.parametrize("extras", [OFF, NEUTRAL], ids=["off", "neutral"])
def test_reduces_exactly_to_fbl_on_random_sensors(extras):
    """Extra rules off (gains 0, thresholds never reached): bit-identical stimulation."""
    s = _random_sensors(512)
    a = np.asarray(_fbl(_p_fbl(), s))
    b = np.asarray(_plus(_p_plus(**extras), s))
    np.testing.assert_array_equal(a, b)


def test_swing_end_with_zero_gains_changes_nothing():
    """Swing end triggered everywhere (d_sw_end = 0 > every d) but the PD gains are 0."""
    s = _random_sensors(256, seed=1).at[..., S_DCOM].set(-1.0)
    p = _p_plus(**{**OFF, "d_sw_end": 0.0})
    np.testing.assert_array_equal(np.asarray(_fbl(_p_fbl(), s)), np.asarray(_plus(p, s)))


@pytest.fixture(scope="module")
def walk_vec():
    """The FBL part of the shipped FBL+ walking preset (an FBL walking gait)."""
    model, vec, _ = load_preset("fblplus_walk")
    assert model == "fblplus"
    return vec[: FBL.size]


def test_shipped_preset_is_the_fbl_walk_with_neutral_extras(walk_vec):
    _, vec, doc = load_preset("fblplus_walk")
    assert doc["table"] == "fblplus" and vec.shape == (38,)
    np.testing.assert_array_equal(vec, lift_fbl(walk_vec))
    src = load_preset(doc["source"])
    np.testing.assert_allclose(src[1], walk_vec, rtol=0, atol=0)


@pytest.fixture(scope="module")
def rollouts(fbl_model, walk_vec):
    """Short walks on flat ground from the same start: FBL (1 set) and FBL+ (2 sets)."""
    plus = models.get_model("fblplus")
    cfg = sim.SimConfig(duration=1.2, log_dt=0.01, chunk_s=0.4)
    env = make_env("flat", jax.random.PRNGKey(0))
    # both batched alike (2 lanes): the same vectorised physics, so results compare exactly
    f_fbl = jax.jit(jax.vmap(lambda p: sim.rollout(fbl_model, cfg, p, env)[:3]))
    f_plus = jax.jit(jax.vmap(lambda p: sim.rollout(plus, cfg, p, env)[:3]))
    active = {"kp_HFL": 1.5, "kd_HFL": 0.2, "kp_GLU": 1.5, "kp_VAS": 1.0, "d_sw_end": -0.5}
    vecs = jnp.asarray(np.stack([lift_fbl(walk_vec, OFF), lift_fbl(walk_vec, active)]), jnp.float32)
    ref = f_fbl(jnp.asarray(np.stack([walk_vec, walk_vec]), jnp.float32))
    return jax.tree.map(lambda x: x[0], ref), f_plus(vecs), plus


def test_make_fblplus_model(rollouts, fbl_model):
    plus = rollouts[2]
    assert plus.name == "fblplus" and plus.table is FBLPLUS
    assert plus.controller.settings.law is fblplus_stimulation
    assert plus.muscles is fbl_model.muscles and plus.dt == fbl_model.dt


def test_rollout_identical_to_fbl_when_rules_off(rollouts):
    ref, plus, _ = rollouts
    off = jax.tree.map(lambda x: x[0], plus)
    for a, b in zip(jax.tree.leaves(ref), jax.tree.leaves(off), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert int(ref[1].n) >= 1  # at least one touchdown (a stance/swing change) happened


def test_rollout_changes_when_swing_end_rules_on(rollouts):
    ref, plus, _ = rollouts
    on = jax.tree.map(lambda x: x[1], plus)
    assert not np.array_equal(np.asarray(ref[0].stim), np.asarray(on[0].stim))


# ------------------------------------------------------------------------------ swing end


def test_swing_end_triggers_on_com_distance():
    p = _p_plus(d_sw_end=-1.0)
    # swing, foot 1.5 foot lengths ahead of the CoM: swing end; 0.5 ahead: not yet
    _, sw = phases_plus(p, _sensors(False, -1.5))
    assert bool(sw.all())
    _, sw = phases_plus(p, _sensors(False, -0.5))
    assert not bool(sw.any())
    # a stance leg is never in swing end
    _, sw = phases_plus(p, _sensors(True, -1.5))
    assert not bool(sw.any())


def _delta(p, s):
    """FBL+ minus FBL stimulation (2, 7) for one sensor array."""
    return np.asarray(fblplus_stimulation(p, s) - fbl_stimulation(_p_fbl(), s))


def test_hip_pd_pushes_towards_the_shared_target():
    """Target 20 deg flexion (delta_h^ref = -0.349 rad, phi_h = 160 deg)."""
    g = {"kp_HFL": 1.0, "kp_GLU": 1.0, "delta_hip_ref": -np.deg2rad(20.0), "d_sw_end": -1.0}
    p = _p_plus(**g)
    # hip straight (180 deg): less flexed than the target -> HFL flexes, GLU silent
    d = _delta(p, _sensors(False, -1.5, hip_deg=180.0))
    np.testing.assert_allclose(d[:, HFL], np.deg2rad(20.0), rtol=1e-5)
    np.testing.assert_array_equal(d[:, GLU], 0.0)
    # hip at 40 deg flexion: beyond the target -> GLU extends, HFL silent
    d = _delta(p, _sensors(False, -1.5, hip_deg=140.0))
    np.testing.assert_allclose(d[:, GLU], np.deg2rad(20.0), rtol=1e-5)
    np.testing.assert_array_equal(d[:, HFL], 0.0)
    # outside swing end nothing is added
    d = _delta(p, _sensors(False, -0.5, hip_deg=180.0))
    np.testing.assert_array_equal(d, 0.0)
    # other muscles never change
    d = _delta(p, _sensors(False, -1.5, hip_deg=180.0))
    for m in (HAM, GAS, SOL, TA, VAS):
        np.testing.assert_array_equal(d[:, m], 0.0)


def test_hip_pd_damping_opposes_the_hip_velocity():
    ref = np.deg2rad(160.0) - np.pi
    at_target = dict(hip_deg=160.0)
    p = _p_plus(kp_HFL=1.0, kd_HFL=0.5, kp_GLU=1.0, kd_GLU=0.5, delta_hip_ref=ref, d_sw_end=-1.0)
    # at the target, extending (dphi_h > 0, delta_h growing): HFL brakes it
    d = _delta(p, _sensors(False, -1.5, dhip=2.0, **at_target))
    np.testing.assert_allclose(d[:, HFL], 1.0, rtol=1e-5)
    np.testing.assert_array_equal(d[:, GLU], 0.0)
    # at the target, flexing (dphi_h < 0): GLU brakes it
    d = _delta(p, _sensors(False, -1.5, dhip=-2.0, **at_target))
    np.testing.assert_allclose(d[:, GLU], 1.0, rtol=1e-5)
    np.testing.assert_array_equal(d[:, HFL], 0.0)


def test_knee_pd_extends_a_bent_knee_only():
    p = _p_plus(kp_VAS=2.0, kd_VAS=0.1, delta_knee_ref=np.deg2rad(10.0), d_sw_end=-1.0)
    # knee bent 40 deg (phi_k = 140 deg): 30 deg more than the target -> VAS extends
    d = _delta(p, _sensors(False, -1.5, knee_deg=140.0))
    np.testing.assert_allclose(d[:, VAS], 2.0 * np.deg2rad(30.0), rtol=1e-5)
    # bending further (dphi_k < 0 => flexion rate > 0) adds damping
    d2 = _delta(p, _sensors(False, -1.5, knee_deg=140.0, dknee=-1.0))
    np.testing.assert_allclose(d2[:, VAS] - d[:, VAS], 0.1, rtol=1e-4)
    # knee straighter than the target: nothing (a muscle only pulls one way)
    d = _delta(p, _sensors(False, -1.5, knee_deg=178.0))
    np.testing.assert_array_equal(d[:, VAS], 0.0)
    np.testing.assert_array_equal(d[:, [HFL, GLU]], 0.0)


# ------------------------------------------------------------------------------ stance end


def test_stance_end_by_com_distance_applies_the_stance_end_rules():
    p = _p_plus(d_st_end=1.5)
    p_fbl = _p_fbl()
    # stance, no double support, CoM 2 foot lengths ahead of the ball: stance end
    s = _sensors(True, 2.0)
    st, _ = phases_plus(p, s)
    assert bool(st.all())
    np.testing.assert_array_equal(
        np.asarray(fblplus_stimulation(p, s)),
        np.asarray(fbl_stimulation(p_fbl, s.at[:, S_DS].set(1.0))),
    )
    d = np.asarray(fblplus_stimulation(p, s) - fbl_stimulation(p_fbl, s))
    ds = float(p["delta_S"])
    np.testing.assert_allclose(d[:, GLU], -ds, rtol=1e-5)
    np.testing.assert_allclose(d[:, HFL], ds, rtol=1e-5)
    # below the threshold: FBL's stance (no double support)
    s = _sensors(True, 1.0)
    st, _ = phases_plus(p, s)
    assert not bool(st.any())
    np.testing.assert_array_equal(
        np.asarray(fblplus_stimulation(p, s)), np.asarray(fbl_stimulation(p_fbl, s))
    )
    # contralateral touchdown (double support) still enters stance end
    st, _ = phases_plus(p, _sensors(True, 0.0, ds=1.0))
    assert bool(st.all())
    # a swing leg is never in stance end
    st, _ = phases_plus(p, _sensors(False, 2.0))
    assert not bool(st.any())


def test_law_is_jit_and_vmap_friendly():
    s = _random_sensors(8, seed=3)
    out = _plus(_p_plus(kp_HFL=1.0, d_sw_end=0.0), s)
    assert out.shape == (8, 2, reflex.N_MUSCLES)
    assert bool(jnp.all(jnp.isfinite(out)))
