"""fbl_ankle: FBL with a swing plantarflexor drive and TA foot-lowering damping."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxgait import models, sim
from jaxgait.control.fbl import (
    FBL,
    GAS,
    N_SENSORS,
    S_DS,
    S_F,
    S_STANCE,
    SOL,
    TA,
    fbl_stimulation,
)
from jaxgait.control.fblankle import (
    EXTRA_NAMES,
    FBL_ANKLE,
    N_SENSORS_ANKLE,
    NEUTRAL,
    S_ANKLE,
    S_DANKLE,
    fbl_ankle_stimulation,
    lift_fbl_ankle,
)
from jaxgait.presets import load_preset
from jaxgait.world.envs import make_env

_fbl = jax.jit(fbl_stimulation)
_ankle = jax.jit(fbl_ankle_stimulation)


def _p(**extras):
    return FBL_ANKLE.unpack(jnp.asarray(lift_fbl_ankle(FBL.init, extras), jnp.float32))


def _random_sensors(n, seed=0):
    """(n * 2, N_SENSORS_ANKLE) random sensor rows with phase flags 0/1."""
    rng = np.random.default_rng(seed)
    s = rng.normal(size=(2 * n, N_SENSORS_ANKLE)) * 0.5 + 0.5
    s[:, S_STANCE] = rng.integers(0, 2, 2 * n)
    s[:, S_DS] = s[:, S_STANCE] * rng.integers(0, 2, 2 * n)
    s[:, S_DANKLE] = rng.normal(size=2 * n) * 3
    return jnp.asarray(s, jnp.float32)


def _sensors(stance, ds=0.0, dankle=0.0, f_sol=0.2):
    """Two identical hand-made rows."""
    s = np.full((2, N_SENSORS_ANKLE), 0.3)
    s[:, S_STANCE] = float(stance)
    s[:, S_DS] = ds
    s[:, S_ANKLE] = np.pi / 2
    s[:, S_DANKLE] = dankle
    s[:, S_F.start + SOL] = f_sol
    return jnp.asarray(s, jnp.float32)


def test_table_is_fbl_plus_three_neutral_extras():
    assert FBL_ANKLE.names[: FBL.size] == FBL.names
    assert FBL_ANKLE.names[FBL.size :] == EXTRA_NAMES == ("k_sw_SOL", "k_sw_GAS", "G_TA_v")
    assert NEUTRAL == {"k_sw_SOL": 1.0, "k_sw_GAS": 1.0, "G_TA_v": 0.0}
    assert S_ANKLE == N_SENSORS and S_DANKLE == N_SENSORS + 1
    vec = lift_fbl_ankle(FBL.init)
    FBL_ANKLE.check(vec)
    assert vec.shape == (31,)


def test_lift_checks_its_input():
    with pytest.raises(ValueError, match="FBL vector of 28"):
        lift_fbl_ankle(np.zeros(5))
    with pytest.raises(KeyError, match="k_sw_TA"):
        lift_fbl_ankle(FBL.init, {"k_sw_TA": 0.5})


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_neutral_law_is_fbl_bit_for_bit(seed):
    s = _random_sensors(64, seed)
    p_fbl = FBL.unpack(jnp.asarray(FBL.init, jnp.float32))
    # op by op (no jit): jit may fuse the two graphs differently, to the last bit
    with jax.disable_jit():
        got = fbl_ankle_stimulation(_p(), s)
        want = fbl_stimulation(p_fbl, s)
    np.testing.assert_array_equal(np.asarray(got), np.asarray(want))


def test_swing_plantarflexor_drive_is_scaled():
    p = _p(k_sw_SOL=0.25, k_sw_GAS=0.5)
    swing = np.asarray(_ankle(p, _sensors(stance=0)))
    np.testing.assert_allclose(swing[:, SOL], 0.25 * float(p["S0_SOL"]), rtol=1e-6)
    np.testing.assert_allclose(swing[:, GAS], 0.5 * float(p["S0_GAS"]), rtol=1e-6)
    # stance SOL and GAS are FBL's
    s = _sensors(stance=1)
    ref = np.asarray(_fbl(FBL.unpack(jnp.asarray(FBL.init, jnp.float32)), s))
    np.testing.assert_array_equal(np.asarray(_ankle(p, s))[:, [SOL, GAS]], ref[:, [SOL, GAS]])


@pytest.mark.parametrize(
    "stance, ds, dankle, extra",
    [
        (1, 0.0, 0.5, 0.4 * 0.5),  # stance, foot rolling down at 0.5 rad/s: + G v
        (1, 0.0, -0.5, 0.0),  # dorsiflexing: no term
        (1, 1.0, 0.5, 0.0),  # trailing leg's push-off (double support): no term
        (0, 0.0, 0.5, 0.0),  # swing: no term
    ],
)
def test_foot_lowering_damping_by_hand(stance, ds, dankle, extra):
    s = _sensors(stance=stance, ds=ds, dankle=dankle)
    p_fbl = FBL.unpack(jnp.asarray(FBL.init, jnp.float32))
    base = np.asarray(_fbl(p_fbl, s))[:, TA]
    ta = np.asarray(_ankle(_p(G_TA_v=0.4), s))[:, TA]
    np.testing.assert_allclose(ta - base, extra, atol=1e-6)


@pytest.fixture(scope="module")
def rollouts(fbl_model):
    """0.8 s on flat ground from fbl_walk's gains: FBL, fbl_ankle neutral and active."""
    _, walk, _ = load_preset("fbl_walk")
    ankle = models.get_model("fbl_ankle")
    cfg = sim.SimConfig(duration=0.8, log_dt=0.01, chunk_s=0.4)
    env = make_env("flat", jax.random.PRNGKey(0))
    f_fbl = jax.jit(jax.vmap(lambda p: sim.rollout(fbl_model, cfg, p, env)[:3]))
    f_ankle = jax.jit(jax.vmap(lambda p: sim.rollout(ankle, cfg, p, env)[:3]))
    active = {"k_sw_SOL": 0.5, "k_sw_GAS": 0.5, "G_TA_v": 0.5}
    vecs = np.stack([lift_fbl_ankle(walk), lift_fbl_ankle(walk, active)])
    ref = f_fbl(jnp.asarray(np.stack([walk, walk]), jnp.float32))
    return jax.tree.map(lambda x: x[0], ref), f_ankle(jnp.asarray(vecs, jnp.float32))


def test_rollout_is_fbl_to_rounding_when_neutral(rollouts):
    """The same law, compiled in another graph: XLA may fuse it otherwise, so the rollouts
    agree to float32 rounding, not bit for bit: states within about 4e-5 at 0.8 s, contact
    forces (stiff) within 0.1 % of their range."""
    ref, both = rollouts
    neutral = jax.tree.map(lambda x: x[0], both)
    assert int(ref[1].n) >= 1  # a touchdown happened: both phases were exercised
    assert int(neutral[1].n) == int(ref[1].n)
    for a, b in zip(jax.tree.leaves(ref), jax.tree.leaves(neutral), strict=True):
        a, b = np.asarray(a, float), np.asarray(b, float)
        scale = max(float(np.max(np.abs(a), initial=0.0)), 1e-6)  # contact forces: stiff
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-3 * scale)


def test_rollout_changes_when_rules_on(rollouts):
    ref, both = rollouts
    on = jax.tree.map(lambda x: x[1], both)
    assert not np.array_equal(np.asarray(ref[0].stim), np.asarray(on[0].stim))


def test_shipped_start_is_fbl_humanlike_with_neutral_extras(tmp_path):
    from jaxgait.presets import write_neutral_preset

    model, vec, doc = load_preset("fbl_ankle_walk")
    assert model == "fbl_ankle" and doc["table"] == "fbl_ankle" and vec.shape == (31,)
    src_model, src_vec, _ = load_preset(doc["source"])
    assert src_model == "fbl"
    np.testing.assert_array_equal(vec, lift_fbl_ankle(src_vec))
    again = write_neutral_preset(doc["source"], tmp_path / "a.json", model="fbl_ankle")
    np.testing.assert_array_equal(again, vec)
    with pytest.raises(ValueError, match="no neutral lift to model 'wang8'"):
        write_neutral_preset("fbl_walk", tmp_path / "b.json", model="wang8")
    with pytest.raises(ValueError, match="a .fbl. preset is needed"):
        write_neutral_preset("fbl_ankle_walk", tmp_path / "c.json", model="fbl_ankle")
