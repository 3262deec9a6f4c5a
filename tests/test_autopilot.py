"""Automatic speed control of a network model (jaxgait.control.autopilot): the law keeps the
control vector in its declared ranges, its state starts fresh in every rollout, the preset
form loads, and the tracking command runs at a tiny size."""

import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxgait import models, presets, sim
from jaxgait.control.autopilot import (
    AUTO_SPEED,
    grade_at_touchdown,
    speed_commands,
    target_speed,
)
from jaxgait.control.commands import bounds
from jaxgait.spinal.auto import auto_preset
from jaxgait.world import envs


def _inner_commands():
    return models.get_model("3fbl_walk").controller.commands


@settings(max_examples=60, deadline=None)
@given(
    gains=st.lists(st.floats(0, 1), min_size=len(AUTO_SPEED.names), max_size=len(AUTO_SPEED.names)),
    v_target=st.floats(0.2, 3.0),
    v=st.floats(-1.0, 4.0),
    integral=st.floats(-10.0, 10.0),
    o_sched=st.floats(-0.3, 0.3),
    grade=st.floats(-1.0, 1.0),
)
def test_speed_law_stays_in_the_declared_ranges(gains, v_target, v, integral, o_sched, grade):
    cmds = _inner_commands()
    lo, hi = AUTO_SPEED.lower, AUTO_SPEED.upper
    p = {
        n: lo[k] + g * (hi[k] - lo[k])
        for k, (n, g) in enumerate(zip(AUTO_SPEED.names, gains, strict=True))
    }
    sched = {c.name: jnp.asarray(c.default) for c in cmds}
    sched["O_INBAS"] = jnp.asarray(o_sched)
    out = speed_commands(p, v_target, v, integral, sched, cmds, grade)
    blo, bhi = bounds(cmds)
    vec = jnp.stack([out[c.name] for c in cmds])
    assert bool(jnp.all(vec >= blo)) and bool(jnp.all(vec <= bhi))
    assert set(out) == set(sched)


def test_grade_estimate_from_the_feet_at_touchdown():
    """Step 3 of the law: heel of the leg touching down against the ball of the other."""
    g = 0.12  # both contact points on a 12 % ramp
    xr, xl = 1.0, 0.4  # right heel ahead, left ball behind
    feet = jnp.array([[xr, g * xr], [xr + 0.2, g * xr + 0.05], [xl - 0.2, 0.3], [xl, g * xl]])
    td = jnp.array([True, False])
    assert float(grade_at_touchdown(feet, td, 0.0, 1.0)) == pytest.approx(g, abs=1e-6)
    # the filter moves a fraction k_g of the way; no touchdown leaves the estimate alone
    assert float(grade_at_touchdown(feet, td, 0.02, 0.5)) == pytest.approx(0.07, abs=1e-6)
    assert float(grade_at_touchdown(feet, jnp.array([False, False]), 0.02, 0.5)) == pytest.approx(
        0.02
    )
    # the slope rule adds k_sw g to omega and k_sb g to O_INBAS (no speed error here)
    cmds = _inner_commands()
    p = dict(zip(AUTO_SPEED.names, map(float, AUTO_SPEED.init), strict=True))
    p.update(k_sw=-2.0, k_sb=0.5, k_sc=0.25, k_lean_g=0.4, k_os_g=0.3, k_as_g=2.0)
    p.update(k_ff=0.0, k_p=0.0, k_i=0.0)
    sched = {c.name: jnp.asarray(c.default) for c in cmds}
    out = speed_commands(p, 1.3, 1.3, 0.0, sched, cmds, g)
    assert float(out["omega"]) == pytest.approx(float(sched["omega"]) - 2.0 * g, abs=1e-6)
    assert float(out["O_INBAS"]) == pytest.approx(0.5 * g, abs=1e-6)
    assert float(out["O_INCPG"]) == pytest.approx(0.25 * g, abs=1e-6)
    assert float(out["lean_offset"]) == pytest.approx(0.4 * g, abs=1e-6)
    assert float(out["O_INSEN"]) == pytest.approx(0.3 * g, abs=1e-6)
    assert float(out["A_INSEN"]) == pytest.approx(1.0 + 2.0 * g, abs=1e-6)
    # the feedforward gains move their command by k (v* - v_ref), nothing else
    p.update(k_sw=0.0, k_sb=0.0, k_sc=0.0, k_lean_g=0.0, k_os_g=0.0, k_as_g=0.0)
    p.update(k_a_bas=0.5, k_lean_v=-0.1, v_ref=1.2)
    out = speed_commands(p, 1.4, 1.4, 0.0, sched, cmds, 0.0)
    ff = {"A_INBAS": 0.5 * 0.2, "lean_offset": -0.1 * 0.2}
    for c in cmds:
        want = float(sched[c.name]) + ff.get(c.name, 0.0)
        assert float(out[c.name]) == pytest.approx(want, abs=1e-6), c.name


def test_contact_grade_reads_the_feet_lowest_points_by_hand():
    """On a 10 % slope (z = 0.1 x) a right foot landing on its forefoot (heel 3.5 cm up)
    and a left foot in heel-off: the chord of the lowest points reads 0.10, the heel-to-ball
    estimate 0.19 (its bias for such a landing)."""
    from jaxgait.control.autopilot import contact_grade

    feet = jnp.array([[1.0, 0.15], [1.15, 0.115], [0.3, 0.06], [0.45, 0.045]])
    td = jnp.array([True, False])
    assert float(contact_grade(feet, td, 0.0, 1.0)) == pytest.approx(0.10, abs=1e-6)
    assert float(grade_at_touchdown(feet, td, 0.0, 1.0)) == pytest.approx(0.105 / 0.55, abs=1e-6)
    # filtered as the other estimate; no touchdown, no change
    assert float(contact_grade(feet, td, 0.02, 0.5)) == pytest.approx(0.06, abs=1e-6)
    assert float(contact_grade(feet, jnp.array([False, False]), 0.02, 0.5)) == pytest.approx(0.02)


def test_targets_are_limited_to_the_speeds_held():
    p = {"v_min": 1.1, "v_max": 1.3}
    got = [float(target_speed(p, v)) for v in (0.7, 1.1, 1.2, 1.3, 1.8)]
    assert got == pytest.approx([1.1, 1.1, 1.2, 1.3, 1.3])
    # the defaults leave every declared target alone
    lo, hi = (AUTO_SPEED.init[AUTO_SPEED.names.index(n)] for n in ("v_min", "v_max"))
    assert (lo, hi) == (0.2, 3.0)


def test_a_rate_limit_turns_a_target_step_into_a_ramp():
    """A step of v_target from 1.3 to 0.7 m/s with a_max 0.2 m/s^2: the law's target falls
    0.2 m/s per second (0.1 mm/s per 0.5 ms step) and reaches 0.7 after 3 s; the speed
    range still applies; a preset refuses a rate that is not a positive number."""
    p = {"v_min": 0.2, "v_max": 3.0}
    dt, prev = 0.0005, jnp.asarray(1.3)
    for _ in range(2000):  # 1 s
        prev = target_speed(p, 0.7, prev, dt, 0.2)
    assert float(prev) == pytest.approx(1.1, abs=1e-4)
    for _ in range(6000):  # 3 s more: arrived and held
        prev = target_speed(p, 0.7, prev, dt, 0.2)
    assert float(prev) == pytest.approx(0.7, abs=1e-6)
    assert float(target_speed({"v_min": 1.1, "v_max": 1.3}, 0.7, 1.1, dt, 0.2)) == pytest.approx(
        1.1
    )
    assert float(target_speed(p, 0.7, prev, dt)) == pytest.approx(
        0.7
    )  # no limit: the clipped command
    doc = auto_preset("3fbl_walk", "t_auto_rate", target_rate=0.3)
    try:
        model = models.get_model(presets.preset_from_dict(doc, where="r.json")[0])
        assert model.controller.settings.target_rate == 0.3
    finally:
        presets.forget_network("t_auto_rate")
    bad = dict(doc, autopilot=dict(doc["autopilot"], target_rate=-1))
    with pytest.raises(presets.PresetError, match="target_rate must be a number > 0"):
        presets.preset_from_dict(bad, where="r.json")


def test_auto_preset_round_trip_and_fresh_state(tmp_path):
    doc = auto_preset("3fbl_walk", "t_auto", {"k_p": 0.03})
    path = tmp_path / "t_auto.json"
    path.write_text(json.dumps(doc))
    try:
        name, vec, _ = presets.load_preset(path)
        model = models.get_model(name)
        assert model.table.name == "auto_speed" and vec[AUTO_SPEED.names.index("k_p")] == 0.03
        assert model.controller.command_names[0] == "v_target"
        cfg = sim.SimConfig(duration=0.6)
        env = envs.make_env("flat", jax.random.PRNGKey(0))
        f = sim.make_rollout(model, cfg, batched=False)
        s1 = f(jnp.asarray(vec, jnp.float32), env)[3]
        s2 = f(jnp.asarray(vec, jnp.float32), env)[3]
        # pure: a second rollout starts from a fresh integral and speed filter
        assert float(s1.ctrl.integral) == float(s2.ctrl.integral) != 0.0
        s0 = sim.initial_state(model, jnp.asarray(vec, jnp.float32), env, cfg)
        assert float(s0.ctrl.integral) == 0.0
        assert float(s0.ctrl.v) == pytest.approx(cfg.v0, abs=0.05)
    finally:
        presets.forget_network("t_auto")
    bad = dict(doc, autopilot={"law": "speed", "base_params": {"k_bw": 1.2}})
    with pytest.raises(presets.PresetError, match="all 28 FBL parameters"):
        presets.preset_from_dict(bad, where="x.json")


def test_network_in_the_table_drives_the_same_walk_and_its_gains_move_it():
    """With the network's parameters moved into the table (to train them with the law) the
    rollout is the same, bit for bit; a changed ``net_`` entry changes the walk."""
    from jaxgait.spinal.tune import expand_names

    a = auto_preset("3fbl_walk", "t_auto_a", {"k_p": 0.03})
    b = auto_preset(a, "t_auto_b", network_in_table=True)
    try:
        cfg = sim.SimConfig(duration=1.0)
        env = envs.make_env("flat", jax.random.PRNGKey(0))
        out = []
        for doc in (a, b):
            name, vec, _ = presets.preset_from_dict(doc, where=doc["model"])
            model = models.get_model(name)
            f = sim.make_rollout(model, cfg, batched=False)
            out.append((model, vec, f(jnp.asarray(vec, jnp.float32), env)[0]))
        (ma, va, ta), (mb, vb, tb) = out
        assert ma.table.name == "auto_speed" and mb.table.name == "auto_speed_net"
        assert mb.table.size == AUTO_SPEED.size + 28
        np.testing.assert_array_equal(np.asarray(ta.com), np.asarray(tb.com))
        i = mb.table.names.index("net_G_SOL")
        assert vb[i] == a["autopilot"]["base_params"]["G_SOL"]
        vb2 = vb.copy()
        vb2[i] *= 0.9
        f = sim.make_rollout(mb, cfg, batched=False)
        tc = f(jnp.asarray(vb2, jnp.float32), env)[0]
        assert not np.array_equal(np.asarray(tc.com), np.asarray(tb.com))
        names = expand_names(("k_p", "net_*"), mb.table.names)
        assert names[0] == "k_p" and len(names) == 29 and names[-1] == "net_delta_S"
        with pytest.raises(Exception, match="unknown gains"):
            expand_names(("nett_*",), mb.table.names)
    finally:
        presets.forget_network("t_auto_a")
        presets.forget_network("t_auto_b")


@pytest.mark.slow
def test_tracking_command_runs_at_a_tiny_size(tmp_path):
    from jaxgait.spinal.cli import main

    args = ["track", "3fbl_auto", "--profile", "1.3,1.25", "--segment", "2", "--settle", "1.2"]
    assert main(args + ["--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "tracking.json").read_text())
    assert len(res["rms"]) == 2 and not res["fell"]
    assert np.all(np.isfinite(res["rms"])) and max(res["rms"]) < 0.5


@pytest.mark.slow
def test_3fbl_auto_wide_follows_a_step_of_the_target_speed():
    """The shipped network-trained law walks through a step of the target from 1.3 to
    1.2 m/s and holds each within 0.08 m/s RMS after 5 s (experiments/spinal/README.md:
    0.035 and 0.040 over 20 s segments); its network parameters are in its table."""
    from jaxgait.spinal.auto import track

    name, vec, doc = presets.load_preset("3fbl_auto_wide")
    assert models.get_model(name).table.name == "auto_speed_net"
    assert doc["autopilot"]["network_in_table"] and doc["autopilot"]["target_rate"] == 0.3
    res = track("3fbl_auto_wide", [1.3, 1.2], segment_s=12.0, settle_s=5.0)
    assert not res["fell"]
    assert max(res["rms"]) < 0.08, res["rms"]


def test_anchored_parameters_interpolate_by_the_target_by_hand():
    from jaxgait.control.autopilot import anchored_params

    speeds = np.array([0.6, 1.0, 1.8])
    rows = jnp.array([[0.0, 1.0], [4.0, 1.0], [8.0, 3.0]])
    for v, want in [
        (0.2, [0.0, 1.0]),  # held below the first anchor
        (0.6, [0.0, 1.0]),
        (0.8, [2.0, 1.0]),  # halfway between 0.6 and 1.0
        (1.0, [4.0, 1.0]),
        (1.2, [5.0, 1.5]),  # a quarter of the way from 1.0 to 1.8
        (2.5, [8.0, 3.0]),  # held above the last
    ]:
        np.testing.assert_allclose(anchored_params(v, speeds, rows), want, atol=1e-6)
    np.testing.assert_array_equal(anchored_params(1.7, speeds[:1], rows[:1]), rows[0])


def test_grade_anchors_are_kept_as_changes_from_the_level_one():
    """Grade anchors r_j enter as r(g) - r_0: the level anchor's row is zero, the others
    their difference from it; anchors without a level one are refused."""
    from jaxgait.control.autopilot import speed_controller

    inner = models.get_model("3fbl_walk").controller
    r0 = np.asarray(inner.table.init, float)
    r1 = r0 * 1.01
    ctrl = speed_controller("t_g", inner, r0, grade_anchors=[(0.1, r1), (0.0, r0)])
    assert ctrl.settings.grade_points.tolist() == [0.0, 0.1]
    np.testing.assert_array_equal(ctrl.settings.grade_deltas[0], 0.0)
    np.testing.assert_allclose(ctrl.settings.grade_deltas[1], r1 - r0)
    with pytest.raises(ValueError, match="one at grade 0"):
        speed_controller("t_g", inner, r0, grade_anchors=[(0.1, r1)])
    with pytest.raises(ValueError, match="exclude each other"):
        speed_controller("t_g", inner, r0, network_in_table=True, anchors=[(1.0, r0)])


@settings(max_examples=60, deadline=None)
@given(
    v=st.floats(0.0, 3.0),
    gaps=st.lists(st.floats(0.05, 0.5), min_size=1, max_size=5),
    seed=st.integers(0, 1000),
)
def test_anchored_parameters_stay_between_their_neighbours(v, gaps, seed):
    """The interpolated vector lies, entry by entry, between the two anchors around v."""
    from jaxgait.control.autopilot import anchored_params

    speeds = 0.4 + np.concatenate([[0.0], np.cumsum(gaps)])
    rows = np.random.default_rng(seed).normal(size=(speeds.size, 3)).astype(np.float32)
    q = np.asarray(anchored_params(v, speeds, jnp.asarray(rows, jnp.float32)))
    k = int(np.clip(np.searchsorted(speeds, v, side="right") - 1, 0, speeds.size - 1))
    j = min(k + 1, speeds.size - 1) if v > speeds[0] else k
    lo, hi = np.minimum(rows[k], rows[j]), np.maximum(rows[k], rows[j])
    assert np.all(q >= lo - 1e-5) and np.all(q <= hi + 1e-5)  # float32


def test_speed_anchors_drive_the_network_they_interpolate(tmp_path):
    """A model whose anchors all carry one network's parameters walks as that network in
    the table does, bit for bit; an anchor changed at the target's side changes the walk;
    the preset refuses anchors that disagree on the law or give no speed."""
    from jaxgait.spinal.auto import anchored_preset

    base = auto_preset(
        auto_preset("3fbl_walk", "t_anc_a", {"k_p": 0.03}), "t_anc_b", network_in_table=True
    )
    slow = dict(base, tuning={"v_range": [1.0, 1.0]})
    fast = dict(base, tuning={"v_range": [1.6, 1.6]})
    level = dict(base, tuning={"v_range": [1.0, 1.0], "grade": 0.0})
    steep = dict(base, tuning={"v_range": [1.0, 1.0], "grade": 0.1})
    # grade anchors that carry the same network add nothing
    same = anchored_preset([slow, fast], "t_anc_c", grade_presets=[steep, level])
    assert [a["grade"] for a in same["autopilot"]["grade_anchors"]] == [0.0, 0.1]
    fast2 = json.loads(json.dumps(fast))
    fast2["params"]["net_G_SOL"] *= 0.9
    changed = anchored_preset([slow, fast2], "t_anc_d")
    assert [a["v"] for a in same["autopilot"]["anchors"]] == [1.0, 1.6]
    assert same["table"] == "auto_speed" and same["params"]["k_p"] == 0.03
    try:
        cfg = sim.SimConfig(duration=1.0)
        env = envs.make_env("flat", jax.random.PRNGKey(0))
        coms = []
        for doc in (base, same, changed):
            path = tmp_path / f"{doc['model']}.json"
            path.write_text(json.dumps(doc))
            name, vec, _ = presets.load_preset(path)
            model = models.get_model(name)
            f = sim.make_rollout(model, cfg, batched=False)
            coms.append(np.asarray(f(jnp.asarray(vec, jnp.float32), env)[0].com))
        np.testing.assert_array_equal(coms[0], coms[1])
        assert not np.array_equal(coms[1], coms[2])  # the default target 1.3 is between
        bad = json.loads(json.dumps(fast))
        bad["params"]["k_p"] = 0.05
        with pytest.raises(Exception, match=r"law gains \['k_p'\] differ"):
            anchored_preset([slow, bad], "t_anc_e")
        with pytest.raises(Exception, match="not trained at one constant target"):
            anchored_preset([base, fast], "t_anc_e")
        with pytest.raises(Exception, match="anchor speeds must differ"):
            anchored_preset([slow, fast], "t_anc_e", speeds=[1.2, 1.2])
        with pytest.raises(Exception, match="need one at grade 0"):
            anchored_preset([slow], "t_anc_e", grade_presets=[steep])
        doc = json.loads(json.dumps(same))
        doc["autopilot"]["anchors"][1]["v"] = 1.0
        with pytest.raises(presets.PresetError, match="speed anchors must be distinct"):
            presets.preset_from_dict(doc, where="a.json")
        doc["autopilot"]["anchors"][1] = {"v": 1.7, "params": {"G_SOL": 1.0}}
        with pytest.raises(presets.PresetError, match=r"anchors\[1\]\): params must give all"):
            presets.preset_from_dict(doc, where="a.json")
    finally:
        for n in ("t_anc_a", "t_anc_b", "t_anc_c", "t_anc_d"):
            presets.forget_network(n)


@pytest.mark.slow
def test_3fbl_auto_anchored_walks_slower_than_its_networks_allow(tmp_path):
    """The shipped speed-anchored model holds 0.9 m/s, which the network trained with its law
    over 0.9-1.6 m/s (``3fbl_auto_wide``, targets unclipped) walks at 1.15 m/s or falls
    (experiments/spinal/README.md, "Speed and grade anchors"); a target beyond its anchors
    is clipped to the speeds it holds: it walks at its fastest instead of falling."""
    from jaxgait.spinal.auto import speed_range

    res = speed_range("3fbl_auto_anchored", [0.9, 1.5, 1.8], duration_s=20.0, measure_s=8.0)
    assert res["held"][:2] == [True, True], res["speed_mps"]
    assert not any(res["fell"]) and res["speed_mps"][2] > 1.45  # its fastest, about 1.57
    wide = presets.load_preset("3fbl_auto_wide")[2]
    doc = json.loads(json.dumps(wide))
    doc["model"] = "t_wide_open"
    doc["params"]["v_min"] = 0.2
    path = tmp_path / "t_wide_open.json"
    path.write_text(json.dumps(doc))
    try:
        slow = speed_range(path, [0.9], duration_s=20.0, measure_s=8.0)
    finally:
        presets.forget_network("t_wide_open")
    assert not slow["held"][0], slow["speed_mps"]


def test_anchors_command_joins_presets_trained_at_constant_targets(tmp_path, capsys):
    """``spinal anchors`` reads each preset's constant tuning target, sets law gains given
    with --gain and refuses unknown ones (exit 2, the name in the message)."""
    from jaxgait.spinal.cli import main

    d = Path(__file__).resolve().parents[1] / "experiments" / "spinal" / "anchors"
    args = ["anchors", f"{d}/u1p5.json", f"{d}/a1p0.json", "--name", "t_anc_cli"]
    try:
        assert main(args + ["--gain", "v_min=0.9", "--out-dir", str(tmp_path)]) == 0
        doc = json.loads((tmp_path / "t_anc_cli.json").read_text())
        assert [a["v"] for a in doc["autopilot"]["anchors"]] == [1.0, 1.5]
        assert doc["params"]["v_min"] == 0.9
        assert main(args + ["--gain", "k_zz=1", "--out-dir", str(tmp_path)]) == 2
        assert "k_zz" in capsys.readouterr().err
    finally:
        presets.forget_network("t_anc_cli")
