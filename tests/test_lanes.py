"""The lane scheduler: a queue of rollouts over fewer (or more) lanes gives each rollout the
result it has alone, and counts the lane utilisation."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import presets, sim
from jaxgait.sim.lanes import lane_rollouts
from jaxgait.world import envs

CFG = sim.SimConfig(duration=1.0, chunk_s=0.25)


def _one(trace, events, summary):
    return {
        "distance": summary.distance,
        "duration": summary.duration,
        "fell": summary.fell,
        "energy": summary.energy,
        "steps": events.n,
        "x_end": trace.com[-1, 0],
        "alive_rows": trace.alive.sum(),
    }


def _finish(trace, events, summary, aux):
    return {**jax.vmap(_one)(trace, events, summary), "tag": aux}


@functools.partial(jax.jit, static_argnums=(0, 4, 5))
def _scheduled(model, params, env, tags, lanes, drain=()):
    return lane_rollouts(model, CFG, params, env, _finish, lanes, aux=tags, drain=drain)


@pytest.fixture(scope="module")
def mixed(fbl_model):
    """Walkers and fallers on different wavy grounds, rolled out directly (one batch)."""
    _, vec, _ = presets.load_preset("fbl_walk")
    table = fbl_model.table
    rng = np.random.default_rng(0)
    wild = table.lower + rng.uniform(size=(3, table.size)) * (table.upper - table.lower)
    params = jnp.asarray(np.stack([vec, wild[0], vec * 1.01, wild[1], wild[2]]), jnp.float32)
    env = envs.make_env_batch("wavy", jax.random.split(jax.random.PRNGKey(3), params.shape[0]))
    direct = jax.jit(jax.vmap(lambda p, e: _one(*sim.rollout(fbl_model, CFG, p, e)[:3])))
    return params, env, jax.device_get(direct(params, env))


@pytest.mark.parametrize(
    "lanes, drain",
    [
        pytest.param(2, (), id="queue_longer"),
        pytest.param(8, (), id="queue_shorter"),
        # the drained tail compiles three programs: in the slow lane (.ci/run runs it)
        pytest.param(3, (2, 1), id="drained_to_2_then_1", marks=pytest.mark.slow),
    ],
)
def test_scheduled_equals_direct_per_candidate(fbl_model, mixed, lanes, drain):
    params, env, ref = mixed
    tags = 10 * jnp.arange(params.shape[0])
    res, stats = jax.device_get(_scheduled(fbl_model, params, env, tags, lanes, drain))
    np.testing.assert_array_equal(res["tag"], np.asarray(tags))  # each result in its slot
    assert ref["fell"].any() and not ref["fell"].all()  # the batch mixes fallers and walkers
    np.testing.assert_array_equal(res["fell"], ref["fell"])
    np.testing.assert_array_equal(res["steps"], ref["steps"])
    np.testing.assert_array_equal(res["alive_rows"], ref["alive_rows"])
    np.testing.assert_allclose(res["duration"], ref["duration"], atol=1e-6)
    for k in ("distance", "x_end"):
        np.testing.assert_allclose(res[k], ref[k], rtol=0, atol=1e-4, err_msg=k)
    np.testing.assert_allclose(res["energy"], ref["energy"], rtol=1e-4)
    assert 0 < float(stats.busy) <= float(stats.total)


def test_utilisation_of_a_hand_made_queue(fbl_model, mixed):
    """Five walkers of four chunks each (1 s) on two lanes: lane 0 runs rollouts 0, 2 and 4
    (12 chunks), lane 1 runs rollouts 1 and 3 and idles 4 chunks: 20 busy lane-chunks of 24."""
    _, vec, _ = presets.load_preset("fbl_walk")
    params = jnp.asarray(np.stack([vec] * 5), jnp.float32)
    env = envs.make_env_batch("flat", jax.random.split(jax.random.PRNGKey(0), 5))
    res, stats = _scheduled(fbl_model, params, env, jnp.arange(5), 2)
    assert not np.asarray(res["fell"]).any()
    per_chunk = round(0.25 / fbl_model.dt)
    assert int(stats.chunks) == 12
    assert int(stats.busy) == 20 * per_chunk and int(stats.total) == 24 * per_chunk
    assert float(stats.utilisation) == pytest.approx(20 / 24)
    np.testing.assert_allclose(np.asarray(res["duration"]), 1.0, atol=1e-6)


@pytest.mark.slow
def test_drained_tail_runs_on_fewer_lanes(fbl_model):
    """The hand-made queue with a drain to one lane: after 8 chunks the queue is empty and
    only rollout 4 is active, so its last 4 chunks run on one lane: 20 busy lane-chunks of
    8 x 2 + 4 x 1 = 20 (utilisation 1), still 12 chunks, every rollout 1 s."""
    _, vec, _ = presets.load_preset("fbl_walk")
    params = jnp.asarray(np.stack([vec] * 5), jnp.float32)
    env = envs.make_env_batch("flat", jax.random.split(jax.random.PRNGKey(0), 5))
    res, stats = _scheduled(fbl_model, params, env, jnp.arange(5), 2, (1,))
    per_chunk = round(0.25 / fbl_model.dt)
    assert int(stats.chunks) == 12
    assert int(stats.busy) == 20 * per_chunk and int(stats.total) == 20 * per_chunk
    np.testing.assert_array_equal(np.asarray(res["tag"]), np.arange(5))
    np.testing.assert_allclose(np.asarray(res["duration"]), 1.0, atol=1e-6)
    assert not np.asarray(res["fell"]).any()


def test_lanes_must_be_positive(fbl_model, mixed):
    params, env, _ = mixed
    with pytest.raises(ValueError, match="n_lanes"):
        lane_rollouts(fbl_model, CFG, params, env, _finish, 0)
    for bad in [(2,), (1, 1), (0,)]:  # not below the lanes, not decreasing, not >= 1
        with pytest.raises(ValueError, match="drain"):
            lane_rollouts(fbl_model, CFG, params, env, _finish, 2, drain=bad)


def test_evaluator_drain_ladder_is_valid():
    """The evaluator's drain widths are what ``lane_rollouts`` accepts for every lane count,
    end at one lane and shrink by at most a third of the lanes per width (12: 8, 4, 1)."""
    from jaxgait.train.evaluator import drain_widths

    for lanes in range(1, 33):
        widths = drain_widths(lanes)
        assert list(widths) == sorted(set(widths), reverse=True), lanes
        assert all(1 <= w < lanes for w in widths), lanes
        assert (widths[-1] == 1) if lanes > 1 else widths == ()
        steps = [a - b for a, b in zip((lanes, *widths), widths, strict=False)]
        assert all(d <= -(-lanes // 3) + 1 for d in steps[:-1]), (lanes, widths)
    assert drain_widths(12) == (8, 4, 1)


@pytest.mark.slow
def test_queued_training_evaluation_equals_direct_calls(fbl_model):
    """The population evaluator with ``lanes`` scores every candidate as the direct calls do,
    and both report their lane counts."""
    from jaxgait.train import PopulationEvaluator, get_experiment

    _, vec, _ = presets.load_preset("fbl_walk")
    table = fbl_model.table
    rng = np.random.default_rng(1)
    pop = np.clip(vec * (1 + 0.3 * rng.uniform(-1, 1, (6, vec.size))), table.lower, table.upper)
    pop = jnp.asarray(pop, jnp.float32)
    keys = jax.random.split(jax.random.PRNGKey(2), 6)
    exp = get_experiment("exp3", particles=6, iterations=1, duration=1.0)
    direct = PopulationEvaluator(exp)
    queued = PopulationEvaluator(exp.replace(lanes=2))
    assert direct.lanes is None and queued.lanes == 2
    s0, v0, ok0 = direct.scores(pop, keys)
    s1, v1, ok1 = queued.scores(pop, keys)
    np.testing.assert_array_equal(s1, s0)
    np.testing.assert_array_equal(ok1, ok0)
    # the same physics in a different batch: float32 rounding (< 1 mm of 1 m in 1 s here)
    np.testing.assert_allclose(v1, v0, rtol=0, atol=1e-3)
    for ev in (direct, queued):
        u = float(ev.last_stats.utilisation)
        assert 0.0 < u <= 1.0 and int(ev.last_stats.busy) > 0
    # a stage cap reorders the queue (highest cap first); every result still lands in its slot
    cap = np.array([0, 5, 1, 5, 0, 2], np.int32)
    s2, v2, ok2 = queued.scores(pop, keys, cap)
    s3, v3, ok3 = direct.scores(pop, keys, cap)
    np.testing.assert_array_equal(s2, s3)
    np.testing.assert_array_equal(s2, np.minimum(s0, cap))
    np.testing.assert_allclose(v2, v3, rtol=0, atol=1e-3)
    # keep_first (the final evaluation) of a queued evaluator: a direct call of its own size
    s4, v4, _, first = queued.scores(pop[:2], keys[:2], keep_first=True)
    np.testing.assert_array_equal(s4, s0[:2])
    np.testing.assert_allclose(v4, v0[:2], rtol=0, atol=1e-3)
    assert first[0].t.shape[0] == 100  # row 0's trace: 1 s at 10 ms


def test_automatic_lane_choice():
    """None: a queue over CPU_AUTO_LANES per CPU device once a device holds more than
    CPU_AUTO_QUEUE_ABOVE rollouts (and no batch_size bounds the calls); 0: direct calls; N: N
    lanes."""
    from jaxgait.train import get_experiment
    from jaxgait.train.evaluator import CPU_AUTO_LANES, CPU_AUTO_QUEUE_ABOVE, choose_lanes

    assert CPU_AUTO_LANES <= CPU_AUTO_QUEUE_ABOVE
    assert choose_lanes(get_experiment("quickstart"), 1) is None  # 16: one direct call
    assert jax.default_backend() == "cpu"
    exp = get_experiment("exp3")  # 60 rollouts per iteration
    assert exp.lanes is None and choose_lanes(exp, 1) == CPU_AUTO_LANES
    assert choose_lanes(exp, 4) is None  # 15 per device
    assert choose_lanes(exp, 3) == CPU_AUTO_LANES  # 20 per device
    assert choose_lanes(exp.replace(particles=8), 1) is None
    assert choose_lanes(exp.replace(particles=8), 1, n_runs=4) == CPU_AUTO_LANES
    assert choose_lanes(exp.replace(batch_size=30), 1) is None
    assert choose_lanes(exp.replace(lanes=0), 1) is None
    assert choose_lanes(exp.replace(lanes=5), 1) == 5
