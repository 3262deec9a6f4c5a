"""fblplus_bal: FBL+ with SIMBICON foot placement on the swing-end hip target."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxgait import models, sim
from jaxgait.control.fbl import (
    FBL,
    GLU,
    HFL,
    N_SENSORS,
    S_DCOM,
    S_DHIP,
    S_DS,
    S_HIP,
    S_STANCE,
    packed_sensors,
)
from jaxgait.control.fblplus import FBLPLUS, fblplus_stimulation, lift_fbl
from jaxgait.control.fblplus_bal import (
    EXTRA_NAMES,
    FBLPLUS_BAL,
    N_SENSORS_BAL,
    NEUTRAL,
    S_BAL_D,
    S_BAL_V,
    fblplus_bal_stimulation,
    lift_fblplus,
    packed_sensors_bal,
)
from jaxgait.control.interface import Sensors
from jaxgait.presets import load_preset, write_neutral_preset
from jaxgait.world.envs import make_env

_SW_END = {"kp_HFL": 1.0, "kp_GLU": 1.0, "delta_hip_ref": -0.35, "d_sw_end": -1.0}


def _p_plus(**extras):
    return FBLPLUS.unpack(jnp.asarray(lift_fbl(FBL.init, extras), jnp.float32))


def _p_bal(plus=None, **extras):
    plus = {} if plus is None else plus
    vec = lift_fblplus(lift_fbl(FBL.init, plus), extras)
    return FBLPLUS_BAL.unpack(jnp.asarray(vec, jnp.float32))


def _sensors(hip_deg, d=0.0, v=0.0, stance=0.0, dcom=-1.5):
    """Two identical hand-made rows (N_SENSORS_BAL,): by default a swing leg in swing end."""
    s = np.full((2, N_SENSORS_BAL), 0.3)
    s[:, S_STANCE] = stance
    s[:, S_DS] = 0.0
    s[:, S_DCOM] = dcom
    s[:, S_HIP] = np.deg2rad(hip_deg)
    s[:, S_DHIP] = 0.0
    s[:, S_BAL_D] = d
    s[:, S_BAL_V] = v
    return jnp.asarray(s, jnp.float32)


def test_table_is_fblplus_then_two_neutral_gains():
    assert FBLPLUS_BAL.names[: FBLPLUS.size] == FBLPLUS.names
    assert EXTRA_NAMES == ("c_d", "c_v") and NEUTRAL == {"c_d": 0.0, "c_v": 0.0}
    assert (S_BAL_D, S_BAL_V, N_SENSORS_BAL) == (N_SENSORS, N_SENSORS + 1, N_SENSORS + 2)
    vec = lift_fblplus(lift_fbl(FBL.init))
    FBLPLUS_BAL.check(vec)
    assert vec.shape == (FBLPLUS.size + 2,)
    with pytest.raises(ValueError, match="FBL\\+ vector of 38"):
        lift_fblplus(FBL.init)
    with pytest.raises(KeyError, match="c_x"):
        lift_fblplus(lift_fbl(FBL.init), {"c_x": 1.0})


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), d=st.floats(-1, 1), v=st.floats(-3, 3))
def test_neutral_law_is_fblplus_bit_for_bit(seed, d, v):
    rng = np.random.default_rng(seed)
    s = rng.normal(size=(8, N_SENSORS_BAL)) * 0.5 + 0.5
    s[:, S_STANCE] = rng.integers(0, 2, 8)
    s[:, S_HIP] = np.pi + rng.uniform(-1.2, 0.4, 8)
    s[:, S_DCOM] = rng.uniform(-2.5, 2.5, 8)
    s[:, S_BAL_D], s[:, S_BAL_V] = d, v
    s = jnp.asarray(s, jnp.float32)
    with jax.disable_jit():  # op by op: the same arithmetic
        got = fblplus_bal_stimulation(_p_bal(_SW_END), s)
        want = fblplus_stimulation(_p_plus(**_SW_END), s)
    np.testing.assert_array_equal(np.asarray(got), np.asarray(want))


def test_target_moves_by_hand():
    """Target -0.35 rad; c_d = 0.5 rad/m at d = 0.2 m and c_v = 0.1 rad s/m at v = 2 m/s move
    it by -(0.1 + 0.2) = -0.3 rad to -0.65 rad (37 deg of flexion).  At a straight hip
    (delta_h = 0) HFL gets kp (0 - (-0.65)) = 0.65 instead of 0.35; at delta_h = -0.5 rad
    (beyond FBL+'s target, short of the moved one) HFL 0.15 instead of GLU 0.15."""
    p0 = _p_bal(_SW_END)
    p = _p_bal(_SW_END, c_d=0.5, c_v=0.1)
    law = jax.jit(fblplus_bal_stimulation)
    straight = _sensors(180.0, d=0.2, v=2.0)
    base = np.asarray(law(p0, straight))
    moved = np.asarray(law(p, straight))
    np.testing.assert_allclose(moved[:, HFL] - base[:, HFL], 0.3, rtol=1e-5)
    bent = _sensors(180.0 - np.rad2deg(0.5), d=0.2, v=2.0)
    base, moved = np.asarray(law(p0, bent)), np.asarray(law(p, bent))
    np.testing.assert_allclose(base[:, GLU] - moved[:, GLU], 0.15, rtol=1e-4)
    np.testing.assert_allclose(moved[:, HFL] - base[:, HFL], 0.15, rtol=1e-4)
    # the feedback acts through the swing-end rule only: nothing in stance
    stance = _sensors(180.0, d=0.2, v=2.0, stance=1.0, dcom=0.5)
    np.testing.assert_array_equal(np.asarray(law(p, stance)), np.asarray(law(p0, stance)))


def test_packed_sensors_are_com_relative_to_the_other_ankle():
    """Each leg's row gets the CoM's x and vx minus the other leg's ankle's, after FBL's
    columns (unchanged)."""
    z2, z23 = jnp.zeros(2), jnp.zeros((2, 3))
    sens = Sensors(
        t=jnp.zeros(()), f_mtu=jnp.zeros((2, 7)), f_norm=jnp.zeros((2, 7)),
        l_ce=jnp.ones((2, 7)) * 0.1, l_norm=jnp.ones((2, 7)), phi=z23 + jnp.pi, dphi=z23,
        trunk=jnp.zeros(()), dtrunk=jnp.zeros(()), load=z2, stance=jnp.asarray([True, False]),
        touchdown=jnp.zeros(2, bool), double_support=jnp.zeros(2, bool), theta_to=z2,
        com=jnp.asarray([3.0, 1.0]), com_vel=jnp.asarray([2.0, 0.1]), feet=jnp.zeros((4, 2)),
        dcom=z2, ankle=jnp.asarray([[2.9, 0.08], [3.4, 0.2]]),
        ankle_vel=jnp.asarray([[0.0, 0.0], [4.5, 0.5]]), dleg=z2,
    )  # fmt: skip
    s = np.asarray(packed_sensors_bal(sens))
    assert s.shape == (2, N_SENSORS_BAL)
    np.testing.assert_array_equal(s[:, :N_SENSORS], np.asarray(packed_sensors(sens)))
    # right leg (stance): relative to the left (swing) ankle; left: to the right (stance) one
    np.testing.assert_allclose(s[:, S_BAL_D], [3.0 - 3.4, 3.0 - 2.9], atol=1e-6)
    np.testing.assert_allclose(s[:, S_BAL_V], [2.0 - 4.5, 2.0 - 0.0], atol=1e-6)


def test_neutral_lift_moves_like_its_fblplus_source(tmp_path):
    """A neutral preset (write_neutral_preset) keeps the source's start and moves like it for
    1 s, to float32 rounding."""
    vec = write_neutral_preset("fblplus_walk", tmp_path / "bal.json", model="fblplus_bal")
    model, loaded, doc = load_preset(tmp_path / "bal.json")
    assert model == "fblplus_bal" and doc["extras_neutral"] is True
    np.testing.assert_array_equal(loaded, vec)
    _, src, _ = load_preset("fblplus_walk")
    np.testing.assert_array_equal(vec[: FBLPLUS.size], src)
    cfg = sim.SimConfig(duration=1.0, log_dt=0.01)
    env = make_env("flat", jax.random.PRNGKey(0))
    a = sim.rollout(models.get_model("fblplus"), cfg, jnp.asarray(src, jnp.float32), env)[0]
    b = sim.rollout(models.get_model("fblplus_bal"), cfg, jnp.asarray(vec, jnp.float32), env)[0]
    np.testing.assert_allclose(np.asarray(b.qpos), np.asarray(a.qpos), atol=1e-3)
    with pytest.raises(ValueError, match="a 'fblplus' preset is needed"):
        write_neutral_preset("fbl_walk", tmp_path / "x.json", model="fblplus_bal")


def test_running_model_widens_the_listed_ranges_of_the_same_controller():
    """fblplus_bal_run: fblplus_bal's names and step, only RUN_RANGES wider, so an
    fblplus_bal vector is valid in it and one with G_GAS = 2.4 (Wang's doubled gain) only
    in it."""
    from jaxgait.control.fblplus_bal import FBLPLUS_BAL_RUN, RUN_RANGES

    spec = models.get_spec("fblplus_bal_run")
    assert spec.table is FBLPLUS_BAL_RUN and FBLPLUS_BAL_RUN.names == FBLPLUS_BAL.names
    for old, new in zip(FBLPLUS_BAL.specs, FBLPLUS_BAL_RUN.specs, strict=True):
        if old.name in RUN_RANGES:
            assert new.lower <= old.lower and new.upper >= old.upper
            assert (new.lower, new.upper) == RUN_RANGES[old.name]
        else:
            assert new == old
    v = np.asarray(FBLPLUS_BAL.init, float).copy()
    FBLPLUS_BAL_RUN.check(v)
    v[FBLPLUS_BAL.index("G_GAS")] = 2.4
    FBLPLUS_BAL_RUN.check(v)
    with pytest.raises(ValueError, match="G_GAS=2.4 not in"):
        FBLPLUS_BAL.check(v)
