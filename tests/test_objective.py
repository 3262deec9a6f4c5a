"""Objectives (thesis eq. 2.47-2.58, Table 2.8, Table 3.1), worst of k, NaN rollouts.

Most tests work on hand-made measures; one module fixture compiles a 4-rollout, 1 s batch
once and is shared by the tests that need real rollouts.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait.optim import INVALID_STAGE, stage_rank_key
from jaxgait.train import objective as obj
from jaxgait.train.experiments import EXPERIMENTS, get_experiment

D_LIM = 35.0


def measures(**kw):
    """A batch of measures (only the keys the criteria read), defaults: a good walk."""
    n = max(np.size(v) for v in kw.values()) if kw else 1
    base = dict(
        distance_m=D_LIM,
        mean_speed_mps=1.3,
        c_angles=0.9,
        step_length_snr=7.0,
        energy_J=7000.0,
        energy_J_per_m=200.0,
        mean_trunk_lean_rad=0.05,
        fell=False,
        step_length_mean_m=0.7,
    )
    base.update(kw)
    out = {}
    for k, v in base.items():
        a = np.broadcast_to(np.asarray(v), (n,))
        out[k] = jnp.asarray(a, bool if a.dtype == bool else jnp.float32)
    return out


EXP3_STAGES = ("distance", "speed", "steplengths", "angles", "energy")
EXP3 = obj.StageObjective(
    tuple((c, None) for c in EXP3_STAGES),
    d_lim=D_LIM,
    targets=(("v_desired", 1.3),),
)


def test_table_2_8_thresholds_follow_the_previous_criterion():
    # exp3 order of Table 3.1, conditions of Table 2.8 per criterion
    assert EXP3.thresholds == pytest.approx((0.99 * D_LIM, -0.05, 6.0, 0.8))
    robust = get_experiment("exp7a").objective()
    assert robust.criteria == ("distance", "trunk", "speed", "angles", "cot")
    assert robust.thresholds == pytest.approx((10.0, -obj.TRUNK_TOLERANCE, -0.05, 0.8))


def test_stage_of_each_particle():
    m = measures(
        distance_m=[10.0, 34.6, 35.0, 35.0, 35.0, 35.0],
        mean_speed_mps=[1.3, 1.3, 1.0, 1.32, 1.32, 1.32],
        step_length_snr=[7, 7, 7, 5.0, 7.0, 7.0],
        c_angles=[0.9, 0.9, 0.9, 0.9, 0.7, 0.85],
        energy_J=[1, 1, 1, 1, 1, 6000.0],
    )
    stage, value = EXP3.fitness(m)
    np.testing.assert_array_equal(stage, [0, 0, 1, 2, 3, 4])
    np.testing.assert_allclose(value, [10.0, 34.6, -0.3, 5.0, 0.7, -6000.0], rtol=1e-5)


def test_stage_cap_of_the_thesis():
    m = measures(energy_J=[6000.0, 6000.0])
    stage, value = EXP3.fitness(m, max_stage=jnp.asarray([1, 4]))
    np.testing.assert_array_equal(stage, [1, 4])
    assert value[0] == pytest.approx(0.0, abs=1e-6)  # C_speed at v = v*


def test_trunk_band_and_distance_10m_of_the_robust_stages():
    robust = get_experiment("exp6a").objective()
    m = measures(
        distance_m=[9.0, 12.0, 12.0, 120.0],
        mean_trunk_lean_rad=[0.05, 0.2, 0.05, 0.05],
        mean_speed_mps=[1.3, 1.3, 1.0, 1.3],
    )
    stage, value = robust.fitness(m)
    np.testing.assert_array_equal(stage, [0, 1, 2, 4])
    assert value[1] == pytest.approx(-(0.2 - 0.105), rel=1e-5)
    assert value[3] == pytest.approx(120.0 * 120.0 / 7000.0, rel=1e-5)  # C_cot = d^2 / E


def test_weighted_objective_is_the_weighted_sum():
    w = obj.WeightedObjective(
        (("distance", 1.0), ("energy", 1e-4), ("angles", 2.0), ("speed", 3.0)),
        targets=(("v_desired", 1.3),),
    )
    m = measures(distance_m=[30.0], energy_J=[5000.0], c_angles=[0.5], mean_speed_mps=[1.1])
    f = float(w.score(m)[0])
    assert f == pytest.approx(30.0 - 0.5 + 1.0 - 0.6, rel=1e-5)  # eq. 2.52 + eq. 2.56 term
    extra = obj.WeightedObjective((("upright", 10.0), ("energy_per_m", 0.01)))
    m2 = measures(fell=[False, True], energy_J_per_m=[200.0, 100.0])
    np.testing.assert_allclose(extra.score(m2), [10.0 - 2.0, -1.0], rtol=1e-5)


def test_worst_of_k_by_stage_order_and_nan_is_worst():
    stage = jnp.asarray([[2, 1, 2], [3, 3, 3], [4, 4, 4]])
    value = jnp.asarray([[5.0, 100.0, -1.0], [2.0, 1.0, 3.0], [1.0, jnp.nan, 2.0]])
    s, v = obj.worst_of_k(stage, value)
    np.testing.assert_array_equal(s, [1, 3, INVALID_STAGE])
    np.testing.assert_array_equal(v, [100.0, 1.0, -np.inf])


def test_invalid_rollouts_score_worst_in_every_convention():
    m = measures(distance_m=[35.0, np.nan, 35.0])
    valid = jnp.asarray([True, True, False])
    stage, value = EXP3.fitness(m, valid)
    np.testing.assert_array_equal(stage[1:], [INVALID_STAGE, INVALID_STAGE])
    assert np.all(np.isneginf(value[1:]))
    assert np.all(np.isposinf(obj.to_tell("cmaes", EXP3, stage, value)[1:]))
    assert np.all(np.isposinf(obj.to_tell("pso", EXP3, stage, value)[1:]))
    s, v = obj.to_tell("stage_pso", EXP3, stage, value)
    assert int(s[1]) == INVALID_STAGE and np.isneginf(v[1])
    w = obj.WeightedObjective((("distance", 1.0),))
    ws, wv = w.fitness(m, valid)
    np.testing.assert_array_equal(ws, [0, INVALID_STAGE, INVALID_STAGE])
    assert np.isposinf(obj.to_tell("cmaes", w, ws, wv)[1])


def test_rank_key_orders_stages_then_values():
    stage = jnp.asarray([0, 0, 1, 4])
    value = jnp.asarray([34.0, 30.0, -0.2, -6000.0])
    key = obj.to_tell("cmaes", EXP3, stage, value)
    assert np.all(np.diff(np.asarray(key)[[1, 0, 2, 3]]) < 0)  # lower is better
    assert float(key[0]) == pytest.approx(float(stage_rank_key(0, 34.0 / 10.0)))


@pytest.mark.parametrize(
    "stages, msg",
    [
        ((("distance", 3.0),), "stage 0"),
        ((("distance", None), ("energy", None), ("speed", None)), "explicit entrance"),
        ((("distance", None), ("nope", None)), "unknown criterion"),
    ],
)
def test_bad_stage_lists(stages, msg):
    with pytest.raises(obj.ObjectiveError, match=msg):
        obj.StageObjective(stages, d_lim=D_LIM, targets=(("v_desired", 1.3),))


def test_missing_target_and_infinite_d_lim():
    with pytest.raises(obj.ObjectiveError, match="v_desired"):
        obj.StageObjective((("distance", None), ("speed", None)), d_lim=D_LIM)
    with pytest.raises(obj.ObjectiveError, match="finite d_lim"):
        obj.StageObjective((("distance", None), ("energy", None)), d_lim=math.inf)


def test_every_registry_objective_builds():
    for name, exp in EXPERIMENTS.items():
        o = exp.objective()
        assert o.kind == ("stage" if exp.stages else "weighted"), name


# ------------------------------------------------------------------ real rollouts


@pytest.fixture(scope="module")
def evaluator():
    from jaxgait.train import PopulationEvaluator

    exp = get_experiment("exp3", particles=4, iterations=1, duration=1.0)
    return PopulationEvaluator(exp)


@pytest.fixture(scope="module")
def walk_vec():
    from jaxgait.train import get_model, resolve_init

    return resolve_init("fbl_walk", get_model("fbl").table)


def test_nan_rollout_scores_worst(evaluator, walk_vec):
    import jax

    pop = np.tile(walk_vec, (4, 1)).astype(np.float32)
    pop[2, 5] = np.nan  # a parameter set that makes the simulation non-finite
    stage, value, valid = evaluator.scores(jnp.asarray(pop), jax.random.split(jax.random.key(0), 4))
    assert list(valid) == [True, True, False, True]
    assert stage[2] == INVALID_STAGE and np.isneginf(value[2])
    assert np.all(stage[[0, 1, 3]] == 0) and np.all(value[[0, 1, 3]] > 1.0)  # walked > 1 m


def test_worst_of_k_on_fresh_environments(walk_vec):
    """Two parameter sets x two random-push draws: k draws differ, the worst is kept."""
    import jax

    from jaxgait.train import PopulationEvaluator

    exp = get_experiment(
        "exp6a",
        particles=2,
        worst_of_k=2,
        duration=1.0,
        iterations=1,
        env_overrides={"t_start": 0.1, "magnitude_mean_max": 400.0, "n_ramp": 1},
    )
    ev = PopulationEvaluator(exp)
    pop = jnp.asarray(np.tile(walk_vec, (2, 1)), jnp.float32)
    key = jax.random.key(3)
    stage, value, _ = ev.scores(jnp.repeat(pop, 2, axis=0), jax.random.split(key, 4))
    ws, wv, n_failed = ev.evaluate(pop, key)
    assert n_failed == 0
    per = value.reshape(2, 2)
    assert not np.allclose(per[:, 0], per[:, 1])  # the draws differ
    np.testing.assert_allclose(wv, per.min(axis=1), rtol=1e-6)
    np.testing.assert_array_equal(ws, stage.reshape(2, 2).min(axis=1))


# ------------------------------------------------------------------ sharding

_SHARDED = r"""
import json, sys
import jax, jax.numpy as jnp, numpy as np
from jaxgait.core import compile_cache
compile_cache.enable()
from jaxgait.train.experiments import get_experiment
from jaxgait.train import PopulationEvaluator, train
assert jax.local_device_count() == 4, jax.devices()
exp = get_experiment("exp3", particles=16, iterations=2, duration=1.0)
ev = PopulationEvaluator(exp)
pop = jnp.asarray(np.load(sys.argv[1]))
keys = jax.random.split(jax.random.key(7), 16)
_, trace, _, _ = next(ev.run(pop, keys))
stage, value, valid = ev.scores(pop, keys)
res = train(exp, sys.argv[2], progress=None, plots=False)
print("RESULT" + json.dumps({
    "n_devices": ev.n_devices, "rows": ev.rows,
    "trace_devices": len(trace.qpos.sharding.device_set),
    "stage": stage.tolist(), "value": value.tolist(),
    "best_params": res.best_params.tolist(), "best_stage": res.best_stage,
    "best_value": res.best_value,
    "history": [r["best_value"] for r in res.history],
}))
"""


@pytest.mark.slow
def test_sharded_equals_unsharded(evaluator, walk_vec, tmp_path):
    """16 rollouts on 4 forced CPU devices (a subprocess: the flag must be set before jax
    starts) vs on 1 device here, 4 rollouts per device call in both: identical results."""
    import json
    import os
    import subprocess
    import sys

    import jax

    from jaxgait.train import get_model, train

    table = get_model("fbl").table
    rng = np.random.default_rng(0)
    pop = np.tile(walk_vec, (16, 1)) * (1 + 0.02 * rng.uniform(-1, 1, (16, walk_vec.size)))
    pop = np.clip(pop, table.lower, table.upper).astype(np.float32)
    np.save(tmp_path / "pop.npy", pop)
    env = dict(os.environ)
    flags = env.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=4"
    env["XLA_FLAGS"] = flags.strip()
    proc = subprocess.run(
        [sys.executable, "-c", _SHARDED, str(tmp_path / "pop.npy"), str(tmp_path / "sharded")],
        capture_output=True,
        text=True,
        env=env,
        timeout=1200,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    line = [s for s in proc.stdout.splitlines() if s.startswith("RESULT")][-1]
    got = json.loads(line[len("RESULT") :])
    assert got["n_devices"] == 4 and got["rows"] == 16 and got["trace_devices"] == 4

    assert evaluator.n_devices == 1 and evaluator.rows == 4
    stage, value, _ = evaluator.scores(jnp.asarray(pop), jax.random.split(jax.random.key(7), 16))
    np.testing.assert_array_equal(got["stage"], stage)
    np.testing.assert_array_equal(got["value"], value)
    exp = get_experiment("exp3", particles=16, iterations=2, duration=1.0, batch_size=4)
    res = train(exp, tmp_path / "single", progress=None, plots=False)
    assert (got["best_stage"], got["best_value"]) == (res.best_stage, res.best_value)
    assert got["history"] == [r["best_value"] for r in res.history]
    np.testing.assert_array_equal(got["best_params"], res.best_params)
