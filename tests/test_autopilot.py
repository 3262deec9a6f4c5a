"""Automatic speed control of a network model (jaxgait.control.autopilot): the law keeps the
control vector in its declared ranges, its state starts fresh in every rollout, the preset
form loads, and the tracking command runs at a tiny size."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxgait import models, presets, sim
from jaxgait.control.autopilot import AUTO_SPEED, speed_commands
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
)
def test_speed_law_stays_in_the_declared_ranges(gains, v_target, v, integral, o_sched):
    cmds = _inner_commands()
    lo, hi = AUTO_SPEED.lower, AUTO_SPEED.upper
    p = {
        n: lo[k] + g * (hi[k] - lo[k])
        for k, (n, g) in enumerate(zip(AUTO_SPEED.names, gains, strict=True))
    }
    sched = {c.name: jnp.asarray(c.default) for c in cmds}
    sched["O_INBAS"] = jnp.asarray(o_sched)
    out = speed_commands(p, v_target, v, integral, sched, cmds)
    blo, bhi = bounds(cmds)
    vec = jnp.stack([out[c.name] for c in cmds])
    assert bool(jnp.all(vec >= blo)) and bool(jnp.all(vec <= bhi))
    for c in cmds:  # the law moves only the basal offset and the clock
        if c.name not in ("O_INBAS", "omega"):
            assert float(out[c.name]) == float(sched[c.name])


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


@pytest.mark.slow
def test_tracking_command_runs_at_a_tiny_size(tmp_path):
    from jaxgait.spinal.cli import main

    args = ["track", "3fbl_auto", "--profile", "1.3,1.25", "--segment", "2", "--settle", "1.2"]
    assert main(args + ["--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "tracking.json").read_text())
    assert len(res["rms"]) == 2 and not res["fell"]
    assert np.all(np.isfinite(res["rms"])) and max(res["rms"]) < 0.5
