"""Robustness measures (thesis 3.2, 7.2-7.3.1): push physics, monotone search, the CLI."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import robustness, sim
from jaxgait.analysis import robustness as rb
from jaxgait.analysis.robustness import RobustnessConfig, ladder_search, push_survive_fn
from jaxgait.presets import load_preset
from jaxgait.world import envs
from jaxgait.world.envs import push_force

# small settings shared by every real-model test (one compiled rollout of 2 s, batch 4)
SMALL = RobustnessConfig(
    seeds=2,
    push_env="push",
    push_t_min=0.5,
    push_t_max=1.0,
    push_max_duration=0.5,
    after_push=0.5,
    push_step=150.0,
    push_per_rung=2,
    push_max=600.0,
    push_refine=1,
    duration=2.0,
    slope_jitter=10.0,
)


# ------------------------------------------------------------------------------ toy ladder


def _toy(thresholds):
    """Survives exactly the amplitudes <= the seed's threshold; records every call."""
    calls = []

    def survive(amps):
        calls.append(np.array(amps))
        return amps <= np.asarray(thresholds)[:, None]

    return survive, calls


def test_ladder_finds_threshold_within_resolution():
    th = np.array([0.0, 55.0, 137.0, 299.0])
    survive, calls = _toy(th)
    res = ladder_search(survive, 4, step=20.0, per_rung=4, max_amp=400.0, refine=2)
    assert all(c.shape == (4, 4) for c in calls)  # one batch shape: one compilation
    assert np.all(res.best <= th)
    assert np.all(res.best > th - 20.0 / 25 - 1e-9)  # two 5-sections of a 20 N bracket
    assert not res.censored.any() and not res.fell_unpushed.any()


def test_ladder_survives_f_implies_reports_at_least_f():
    rng = np.random.default_rng(0)
    for _ in range(20):
        th = rng.uniform(0, 450, 6)
        survive, _ = _toy(th)
        res = ladder_search(survive, 6, step=20.0, per_rung=3, max_amp=400.0, refine=1)
        for f in np.arange(0, 401, 20.0):  # every ladder amplitude the seed survives
            assert np.all(res.best[th >= f] >= f)
        # a stronger walker (higher thresholds) never reports less
        res2 = ladder_search(_toy(th + 30)[0], 6, 20.0, 3, 400.0, 1)
        assert np.all(res2.best >= res.best)


def test_ladder_never_skips_a_failure():
    """Non-monotone survival (a hole at 60 N): the report stops below the hole."""

    def survive(amps):
        return (amps < 50) | (amps > 70)

    res = ladder_search(survive, 2, step=20.0, per_rung=4, max_amp=400.0, refine=1)
    assert np.all(res.best < 60) and np.all(res.best >= 40)
    for amps, ok in res.tested:  # every tested amplitude <= best survived
        assert np.all(ok[amps <= res.best[:, None]])


def test_ladder_censoring_and_unpushed_fall():
    survive, _ = _toy([-1.0, 1e9])
    res = ladder_search(survive, 2, step=50.0, per_rung=4, max_amp=300.0, refine=1)
    np.testing.assert_array_equal(res.best, [0.0, 300.0])
    np.testing.assert_array_equal(res.fell_unpushed, [True, False])
    np.testing.assert_array_equal(res.censored, [False, True])


# ------------------------------------------------------------------------------ real model


@pytest.fixture(scope="module")
def walker():
    _, vec, _ = load_preset("fblplus_walk")
    return robustness.get_model("fbl"), vec[:28]


def test_push_changes_momentum_by_its_impulse(walker):
    """In the air, total linear momentum changes by the push impulse plus gravity's.

    The walker (muscles and reflexes running: internal forces) is lifted 1 m so that no
    contact acts; one 300 N push at 30 deg above the horizontal lasts 0.1 s.
    """
    model, vec = walker
    cfg = sim.SimConfig(duration=1.0)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    p = env.pushes
    env = env.replace(
        pushes=p.replace(
            t0=p.t0.at[0].set(0.0201),
            duration=p.duration.at[0].set(0.1),
            magnitude=p.magnitude.at[0].set(300.0),
            angle=p.angle.at[0].set(np.deg2rad(30.0)),
            height=p.height.at[0].set(0.5),
        )
    )
    params = jnp.asarray(vec, jnp.float32)
    s0 = sim.initial_state(model, params, env, cfg)
    s0 = s0.replace(qpos=s0.qpos.at[1].add(1.0))
    n = 400  # 0.2 s

    def momentum(s):
        _, lin = jax.linearize(lambda q: model.points(q, jnp.zeros((), q.dtype)), s.qpos)
        return model.mass * lin(s.qvel)[7]

    @jax.jit
    def run(s):
        def body(s, _):
            f = jnp.stack(push_force(env.pushes, s.t)[:2]) * model.dt
            s = sim.step(model, cfg, params, env, s)
            return s, (f, s.grf)

        return jax.lax.scan(body, s, None, length=n)

    s1, (impulses, grf) = run(s0)
    assert float(jnp.abs(grf).max()) == 0.0  # no ground contact at all
    impulse = np.asarray(impulses.sum(0), float)
    np.testing.assert_allclose(impulse, 300.0 * 0.1 * np.array([np.cos(np.pi / 6), 0.5]), rtol=0.01)
    gravity = np.array([0.0, -model.mass * 9.81 * n * model.dt])
    dp = np.asarray(momentum(s1) - momentum(s0), float)
    np.testing.assert_allclose(dp, impulse + gravity, atol=0.01 * np.abs(impulse).max())


@pytest.fixture(scope="module")
def push_search(walker):
    model, vec = walker
    survive, base = push_survive_fn(model, vec, SMALL)
    res = ladder_search(survive, 2, SMALL.push_step, 2, SMALL.push_max, SMALL.push_refine)
    return survive, res


def test_real_push_search_is_monotone(push_search):
    """Survives every ladder amplitude up to F (checked again here) => reports >= F."""
    survive, res = push_search
    ladder = np.arange(0.0, SMALL.push_max + 1, SMALL.push_step)
    ok = np.concatenate(
        [survive(np.tile(ladder[i : i + 2], (2, 1))) for i in range(0, len(ladder) - 1, 2)], 1
    )
    for seed in range(2):
        prefix = np.cumprod(ok[seed, : ok.shape[1]]).astype(bool)
        if prefix.any():
            f = ladder[: len(prefix)][prefix].max()
            assert res.best[seed] >= f
    # the reported amplitude itself survives (same trials replayed)
    assert np.all(survive(np.tile(res.best[:, None], (1, 2))) | res.fell_unpushed[:, None])
    for amps, oks in res.tested:
        assert np.all(oks[amps <= res.best[:, None]])


def test_cli_json_keys(push_search, capsys):
    """The CLI with small settings (the same compiled rollout as above) prints one JSON."""
    fbl_preset = load_preset("fblplus_walk")[2]["source"]  # the FBL walk it was made from
    argv = [
        fbl_preset,
        "--model",
        "fbl",
        "--seeds",
        "2",
        "--duration",
        "2.0",
        "--push-env",
        "push",
        "--push-window",
        "0.5",
        "1.0",
        "--push-max-duration",
        "0.5",
        "--after-push",
        "0.5",
        "--push-step",
        "150",
        "--push-max",
        "600",
        "--push-per-rung",
        "2",
        "--push-refine",
        "0",
        "--json",
    ]
    assert robustness.main(argv) == 0
    rep = json.loads(capsys.readouterr().out)
    for k in ("max_push_N", "max_slope_pct", "slope_distance_m"):
        assert isinstance(rep[k], float) and isinstance(rep[k + "_sd"], float)
        assert len(rep[k + "_seeds"]) == 2
    assert rep["model"] == "fbl" and rep["seeds"] == 2
    assert 0.0 <= rep["max_push_N"] <= 600.0


def test_fbl_preset_lifted_to_fblplus_on_request():
    _, vec, _ = load_preset("fblplus_walk")
    name, lifted = robustness.params_for_model("fbl", vec[:28], "fblplus")
    assert name == "fblplus"
    np.testing.assert_array_equal(lifted, vec)
    with pytest.raises(ValueError, match="cannot run"):
        robustness.params_for_model("fblplus", vec, "fbl")


def test_cli_bad_input(capsys):
    assert robustness.main(["no_such_preset_xyz", "--json"]) == 2
    assert "no_such_preset_xyz" in capsys.readouterr().err
    assert robustness.main(["fblplus_walk", "--tests", "push,fly"]) == 2
    assert robustness.main(["fblplus_walk", "--model", "fbl"]) == 2


def test_push_duration_sets_the_fixed_push_and_is_checked():
    cfg = rb.RobustnessConfig(seeds=2, push_env="push", push_duration=0.4)
    env = rb.push_base_envs(cfg, jax.random.split(jax.random.PRNGKey(0), 2))
    np.testing.assert_allclose(np.asarray(env.pushes.duration[:, 0]), 0.4)
    with pytest.raises(ValueError, match="push_duration=0.4 .push_env 'push' only"):
        rb.RobustnessConfig(push_duration=0.4)  # random_push draws its own durations


def test_cli_starts_from_the_presets_speed_and_pose(tmp_path, monkeypatch, capsys):
    """As ``evaluate``, the robustness rollouts start at the preset's ``v0`` and ``pose``
    (a runner saved with v0 2.4 m/s must not be pushed from a 1.3 m/s start); a preset
    without them starts at the simulator's defaults."""
    seen = []

    def spy(model, vec, rcfg, tests):
        seen.append(rcfg)
        return {"model": "fbl", "seeds": rcfg.seeds}

    monkeypatch.setattr(robustness, "robustness", spy)
    _, _, doc = load_preset("fbl_walk")
    path = tmp_path / "start.json"
    path.write_text(json.dumps({**doc, "v0": 1.1, "pose": "run"}))
    assert robustness.main([str(path), "--json"]) == 0
    assert robustness.main(["fbl_walk", "--json"]) == 0
    capsys.readouterr()
    (a, b) = seen
    assert (a.v0, a.pose) == (1.1, "run") and (b.v0, b.pose) == (None, None)
    cfg_a, cfg_b = rb._sim_cfg(1.0, a), rb._sim_cfg(1.0, b)
    assert (cfg_a.v0, cfg_a.pose) == (1.1, "run")
    assert (cfg_b.v0, cfg_b.pose) == (sim.SimConfig.v0, sim.SimConfig.pose)
    with pytest.raises(ValueError, match="pose='crouch'"):
        rb.RobustnessConfig(pose="crouch")
    with pytest.raises(ValueError, match="v0=inf"):
        rb.RobustnessConfig(v0=float("inf"))
