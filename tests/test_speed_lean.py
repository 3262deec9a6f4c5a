"""The lean speed regulator (jaxgait.control.speed_lean): its law by hand, its bounds, its
table, and that it is the wrapped controller when its gains are zero."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxgait import models, sim
from jaxgait.control.fblplus_bal import FBLPLUS_BAL_RUN, FBLPLUS_BAL_RUN_CONTROLLER, SR_RANGES
from jaxgait.control.speed_lean import (
    REGULATOR_NAMES,
    lean_command,
    regulator_update,
    speed_regulated,
)
from jaxgait.world.envs import make_env

SR = "fblplus_bal_run_sr"


def _p(**kw):
    p = {"v_reg": 2.5, "k_vp": 0.02, "k_vi": 0.01, "tau_vr": 0.5, "i_max_vr": 2.0}
    p.update(kw)
    return {k: jnp.float32(v) for k, v in p.items()}


def test_table_is_the_wrapped_one_then_the_regulator():
    """fblplus_bal_run's names (SR_RANGES wider), then the regulator's five gains."""
    table = models.get_spec(SR).table
    assert table.names == FBLPLUS_BAL_RUN.names + REGULATOR_NAMES
    for old, new in zip(FBLPLUS_BAL_RUN.specs, table.specs, strict=False):
        if old.name in SR_RANGES:
            assert (new.lower, new.upper) == SR_RANGES[old.name]
            assert new.lower <= old.lower and new.upper >= old.upper
        else:
            assert new == old
    init = table.unpack(jnp.asarray(table.init))
    assert float(init["k_vp"]) == 0.0 and float(init["k_vi"]) == 0.0  # neutral by default


def test_update_and_lean_by_hand():
    """tau 0.5 s, dt 0.01 s: v = 2 + 0.02 (3 - 2) = 2.02; I = 0.5 + 0.01 (2.5 - 2.02) =
    0.5048; lean = 0.02 (2.5 - 2.02) + 0.01 x 0.5048 = 0.009600 + 0.005048 = 0.014648 rad
    (forwards when slower than v_reg)."""
    p = _p()
    v, integral = regulator_update(p, jnp.float32(2.0), jnp.float32(0.5), jnp.float32(3.0), 0.01)
    assert float(v) == pytest.approx(2.02, abs=1e-6)
    assert float(integral) == pytest.approx(0.5048, abs=1e-6)
    assert float(lean_command(p, v, integral, 0.1)) == pytest.approx(0.014648, abs=1e-6)
    # faster than the target: the lean goes backwards
    assert float(lean_command(p, jnp.float32(3.0), jnp.float32(0.0), 0.1)) == pytest.approx(-0.01)


@settings(max_examples=60, deadline=None)
@given(
    v=st.floats(-5, 8),
    i0=st.floats(-2, 2),
    v_com=st.floats(-5, 8),
    k_vp=st.floats(0, 0.1),
    k_vi=st.floats(0, 0.05),
    i_max=st.floats(0.1, 10),
)
def test_integral_and_lean_stay_in_their_bounds(v, i0, v_com, k_vp, k_vi, i_max):
    p = _p(k_vp=k_vp, k_vi=k_vi, i_max_vr=i_max)
    v1, integral = regulator_update(p, jnp.float32(v), jnp.float32(i0), jnp.float32(v_com), 5e-4)
    assert abs(float(integral)) <= i_max * (1 + 1e-6)
    assert min(v, v_com) - 1e-4 <= float(v1) <= max(v, v_com) + 1e-4  # a filter, no overshoot
    assert abs(float(lean_command(p, v1, integral, 0.1))) <= 0.1 + 1e-7


def test_zero_gains_move_as_the_wrapped_controller():
    """k_vp = k_vi = 0: the same rollout as fblplus_bal_run, bit for bit (1 s)."""
    base_vec = np.asarray(FBLPLUS_BAL_RUN.init, np.float32)
    sr = models.get_spec(SR).table
    vec = sr.pack(dict(zip(FBLPLUS_BAL_RUN.names, base_vec, strict=True)))
    cfg = sim.SimConfig(duration=1.0, log_dt=0.01)
    env = make_env("flat", jax.random.PRNGKey(0))
    a = sim.rollout(models.get_model("fblplus_bal_run"), cfg, jnp.asarray(base_vec), env)[0]
    b = sim.rollout(models.get_model(SR), cfg, jnp.asarray(vec, jnp.float32), env)[0]
    np.testing.assert_array_equal(np.asarray(b.qpos), np.asarray(a.qpos))


def test_a_regulated_rollout_leans_with_the_speed_error():
    """With a target far above the speed (v_reg 5 m/s) and k_vp at its bound the offset is at
    lean_max (0.1 rad) from the start: the trunk leans further forwards than with the
    regulator off, and the state holds the filtered speed and the growing integral."""
    sr = models.get_spec(SR).table
    base = dict(zip(FBLPLUS_BAL_RUN.names, np.asarray(FBLPLUS_BAL_RUN.init), strict=True))
    cfg = sim.SimConfig(duration=0.5, log_dt=0.01)
    env = make_env("flat", jax.random.PRNGKey(0))
    model = models.get_model(SR)
    lean = []
    for k_vp in (0.0, 0.1):
        vec = sr.pack({**base, "v_reg": 5.0, "k_vp": k_vp})
        _, _, summary, final = sim.rollout(model, cfg, jnp.asarray(vec, jnp.float32), env)
        assert 0.5 < float(final.ctrl.v) < 2.0  # the filtered forward speed (v0 1.3 m/s)
        assert float(final.ctrl.integral) > 0.5 * (5.0 - 2.0)  # 0.5 s of an error above 3
        lean.append(float(summary.trunk_lean_sum) / float(summary.duration))
    assert lean[1] > lean[0] + 0.02


def test_refuses_a_controller_without_lean_or_with_the_names():
    no_lean = dataclasses.replace(FBLPLUS_BAL_RUN_CONTROLLER, commands=())
    with pytest.raises(ValueError, match="no lean_offset command"):
        speed_regulated(no_lean, "x")
    once = speed_regulated(FBLPLUS_BAL_RUN_CONTROLLER, "once")
    with pytest.raises(ValueError, match="already has parameters"):
        speed_regulated(once, "twice")


def test_a_second_regulator_on_another_command_has_its_own_names():
    """``fblplus_bal_run_sr2``: the regulator on FBL+'s swing-end hip target around the
    lean-regulated model: its gains carry the suffix and may be negative, the lean
    regulator's keep theirs; zero gains leave the rollout bit for bit as the model it wraps,
    nonzero ones of either sign change it (on the regulated runner fblplus_run_2p0, whose
    swing-end rule uses the hip target)."""
    from jaxgait.presets import load_preset

    inner = models.get_model(SR).controller
    both = models.get_model("fblplus_bal_run_sr2").controller
    assert both.table.names == inner.table.names + tuple(n + "_h" for n in REGULATOR_NAMES)
    spec = {sp.name: sp for sp in both.table.specs}
    assert (spec["k_vp_h"].lower, spec["k_vp_h"].upper) == (-0.3, 0.1)
    assert (spec["k_vi_h"].lower, spec["k_vi_h"].upper) == (-0.1, 0.05)
    assert (spec["k_vp"].lower, spec["k_vp"].upper) == (0.0, 0.1)  # the lean's: unchanged
    with pytest.raises(ValueError, match="no v_target command"):
        speed_regulated(inner, "x", command="v_target")
    _, base, doc = load_preset("fblplus_run_2p0")
    base = np.asarray(base, np.float32)
    cfg = sim.SimConfig(duration=1.0, log_dt=0.01, v0=doc["v0"])
    env = make_env("flat", jax.random.PRNGKey(0))
    a = sim.rollout(models.get_model(SR), cfg, jnp.asarray(base), env)[0]
    runs = []
    for k in (0.0, 0.1, -0.1):
        vec = both.table.pack({"k_vp_h": k, "v_reg_h": 5.0}, base=np.r_[base, both.table.init[-5:]])
        both.table.check(vec)
        model = models.get_model("fblplus_bal_run_sr2")
        runs.append(sim.rollout(model, cfg, jnp.asarray(vec, jnp.float32), env)[0])
    np.testing.assert_array_equal(np.asarray(runs[0].qpos), np.asarray(a.qpos))
    for r in runs[1:]:
        assert not np.array_equal(np.asarray(r.qpos), np.asarray(a.qpos))
    assert not np.array_equal(np.asarray(runs[1].qpos), np.asarray(runs[2].qpos))


def test_ranges_replace_the_gains_bounds_and_are_checked():
    ctrl = speed_regulated(FBLPLUS_BAL_RUN_CONTROLLER, "r", ranges={"k_vi": (-0.2, 0.2)})
    spec = {sp.name: sp for sp in ctrl.table.specs}
    assert (spec["k_vi"].lower, spec["k_vi"].upper) == (-0.2, 0.2)
    assert (spec["k_vp"].lower, spec["k_vp"].upper) == (0.0, 0.1)
    with pytest.raises(ValueError, match=r"ranges name no regulator gain: \['k_p'\]"):
        speed_regulated(FBLPLUS_BAL_RUN_CONTROLLER, "r", ranges={"k_p": (0, 1)})
    with pytest.raises(ValueError, match="range \\(0.1, 0.2\\) of k_vp excludes its initial 0.0"):
        speed_regulated(FBLPLUS_BAL_RUN_CONTROLLER, "r", ranges={"k_vp": (0.1, 0.2)})


def test_swing_end_widened_model_is_the_regulated_runner_with_one_range():
    """``fblplus_bal_run_sr_se``: ``fblplus_bal_run_sr``'s names, d_sw_end in [-2.5, 1]
    instead of [-2.5, 0] (every other entry equal); a runner's vector moves bit for bit as in
    the model it widens (1 s), and a positive threshold (swing end starting while the swing
    foot is behind the CoM) changes the run."""
    from jaxgait.presets import load_preset

    sr = models.get_spec(SR).table
    se = models.get_spec("fblplus_bal_run_sr_se").table
    assert se.names == sr.names
    for old, new in zip(sr.specs, se.specs, strict=True):
        if old.name == "d_sw_end":
            assert (old.lower, old.upper) == (-2.5, 0.0) and (new.lower, new.upper) == (-2.5, 1.0)
        else:
            assert new == old
    _, base, doc = load_preset("fblplus_push_run_1p8")
    base = np.asarray(base, np.float32)
    cfg = sim.SimConfig(duration=1.0, log_dt=0.01, v0=doc["v0"])
    env = make_env("flat", jax.random.PRNGKey(0))
    a = sim.rollout(models.get_model(SR), cfg, jnp.asarray(base), env)[0]
    b = sim.rollout(models.get_model("fblplus_bal_run_sr_se"), cfg, jnp.asarray(base), env)[0]
    np.testing.assert_array_equal(np.asarray(b.qpos), np.asarray(a.qpos))
    early = se.pack({"d_sw_end": 0.5}, base=base)
    se.check(early, "d_sw_end 0.5")  # inside the widened range
    early = jnp.asarray(early, jnp.float32)
    c = sim.rollout(models.get_model("fblplus_bal_run_sr_se"), cfg, early, env)[0]
    assert np.abs(np.asarray(c.qpos) - np.asarray(a.qpos)).max() > 1e-3
