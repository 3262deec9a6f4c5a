"""Tests of jaxgait.optim: PSO (thesis eq. 2.45-2.46), stage PSO (2.2.1.2), CMA-ES wrapper.

Compilation dominates the run time on CPU, so the tests share a few jitted programs: every run
goes through ``init`` and ``advance`` (50 generations per ``lax.scan``), and the objectives are
shared between tests.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxgait.optim import (
    CMAES,
    PSO,
    STRATEGIES,
    Bounds,
    PSOState,
    StagePSO,
    Strategy,
    as_bounds,
    evaluate_stages,
    make_strategy,
    move_swarm,
    reflect_unit,
    stage_argbest,
    stage_better,
    stage_rank_key,
    threshold_entrance,
)

SHIFT = jnp.array([1.5, -2.0, 0.7, 3.1, -0.4])
HOLE = 4.0  # the objectives below are NaN (a failed rollout) where x[0] > HOLE


def sphere(x):
    """Shifted sphere with a NaN region x[0] > HOLE away from the optimum."""
    f = jnp.sum((x - SHIFT[: x.shape[-1]]) ** 2, axis=-1)
    return jnp.where(x[..., 0] > HOLE, jnp.nan, f)


def rastrigin(x):
    d = x.shape[-1]
    return 10.0 * d + jnp.sum(x**2 - 10.0 * jnp.cos(2.0 * jnp.pi * x), axis=-1)


def box(d, lo=-5.0, hi=5.0):
    return jnp.full((d,), lo), jnp.full((d,), hi)


# The programs here are tiny and run for milliseconds: on CPU, skip XLA's backend optimisations
# to halve compile time (every jitted program of this file uses the same options).
_OPTS = {"xla_backend_optimization_level": 0} if jax.default_backend() == "cpu" else None
jit = partial(jax.jit, compiler_options=_OPTS)


@partial(jit, static_argnames=("strategy",))
def init(strategy, key, bounds, init_mean=None):
    return strategy.init(key, bounds, init_mean)


BLOCK = 50


@partial(jit, static_argnames=("strategy", "fn", "n_gen"))
def advance(strategy, fn, state, key, n_gen=BLOCK):
    """``n_gen`` generations of ask -> evaluate -> tell inside one jitted ``lax.scan``.

    Generation i uses ``jax.random.split(key, n_gen)[i]`` for its ``ask``.
    """

    def generation(state, k):
        population, state = strategy.ask(k, state)
        fitness = fn(population)
        state = strategy.tell(state, population, fitness)
        return state, (population, fitness, getattr(state, "velocity", None))

    return jax.lax.scan(generation, state, jax.random.split(key, n_gen))


def run(strategy, fn, key, bounds, n_gen, init_mean=None):
    """init, then ``n_gen`` generations in scanned blocks of 50; populations, fitness and
    velocities as NumPy arrays (assertions in NumPy avoid compiling many tiny programs)."""
    block = BLOCK if n_gen % BLOCK == 0 else n_gen
    state = init(strategy, key, bounds, init_mean)
    outs = []
    for i in range(n_gen // block):
        state, out = advance(strategy, fn, state, jax.random.fold_in(key, i), block)
        outs.append(jax.device_get(out))
    return state, jax.tree.map(lambda *a: np.concatenate(a), *outs)


def no_nan(tree):
    leaves = [np.asarray(x) for x in jax.tree.leaves(tree)]
    return not any(np.isnan(x).any() for x in leaves if np.issubdtype(x.dtype, np.floating))


def np_sphere(x):
    return np.sum((np.asarray(x) - np.asarray(SHIFT)[: x.shape[-1]]) ** 2, axis=-1)


# --- registry and bounds ------------------------------------------------------------------------


def test_registry_and_protocol():
    assert set(STRATEGIES) == {"pso", "stage_pso", "cmaes"}
    for name in STRATEGIES:
        strategy = make_strategy(name, 8)
        assert isinstance(strategy, Strategy)
        assert strategy.popsize == 8
        assert hash(strategy) == hash(make_strategy(name, 8))  # usable as a static jit arg
    assert make_strategy("pso", 4, omega=0.5).omega == 0.5
    with pytest.raises(ValueError, match="unknown optimiser 'nelder'.*cmaes"):
        make_strategy("nelder", 8)
    with pytest.raises(TypeError):
        make_strategy("pso", 8, sigma_init=0.1)
    with pytest.raises(ValueError, match="popsize"):
        make_strategy("cmaes", 1)


def test_bounds_validation():
    b = as_bounds(np.array([[0.0, 1.0], [2.0, 3.0]]))
    assert isinstance(b, Bounds) and b.num_dims == 2
    np.testing.assert_allclose(b.range, [2.0, 2.0])
    with pytest.raises(ValueError, match="upper > lower"):
        as_bounds((jnp.zeros(2), jnp.array([1.0, 0.0])))
    with pytest.raises(ValueError, match="finite"):
        as_bounds((jnp.zeros(2), jnp.array([1.0, jnp.inf])))
    with pytest.raises(ValueError, match="shapes"):
        as_bounds((jnp.zeros(2), jnp.ones(3)))


def test_reflect_unit():
    z = jnp.array([-0.2, 0.0, 0.3, 1.0, 1.3, 2.4, -1.7])
    np.testing.assert_allclose(reflect_unit(z), [0.2, 0.0, 0.3, 1.0, 0.7, 0.4, 0.3], atol=1e-6)


# --- PSO ----------------------------------------------------------------------------------------


def test_pso_defaults_are_the_thesis_values():
    pso = PSO(10)
    assert (pso.omega, pso.c1, pso.c2, pso.vmax_frac) == (0.729, 2.05, 2.05, 0.3)


def test_pso_converges_on_sphere_despite_nan():
    pso = PSO(20)
    state, (pops, _, _) = run(pso, sphere, jax.random.key(0), box(5), 150)
    params, fit = jax.device_get(pso.best(state))
    # thesis constants (omega = 0.729 with c1 = c2 = 2.05 unscaled): the clamp bounds the swarm
    assert fit < 1e-3
    np.testing.assert_allclose(params, SHIFT, atol=3e-2)
    assert fit == pytest.approx(np_sphere(params), rel=1e-5, abs=1e-7)
    assert int(state.generation) == 150
    # NaN candidates were proposed, yet none entered the state
    assert (pops[..., 0] > HOLE).any()
    assert no_nan(state)
    assert (np.asarray(state.pbest_position)[:, 0] <= HOLE).all()
    # Clerc's constriction (c1 = c2 = 0.729 * 2.05) converges much faster
    clerc = PSO(20, c1=1.49445, c2=1.49445)
    state, _ = run(clerc, sphere, jax.random.key(0), box(5), 100)
    assert float(clerc.best(state)[1]) < 1e-5


@pytest.mark.parametrize("dim", [2, 5])
def test_pso_progress_on_rastrigin(dim):
    pso = PSO(20)
    for seed in range(2):
        state, (pops, _, _) = run(pso, rastrigin, jax.random.key(seed), box(dim, -5.12, 5.12), 100)
        first_best = float(
            np.min(10.0 * dim + np.sum(pops[0] ** 2 - 10.0 * np.cos(2.0 * np.pi * pops[0]), -1))
        )
        fit = float(pso.best(state)[1])
        assert fit < 0.5 * first_best
        assert fit < 2.0 * dim


def _linear(x):
    # optimum in a corner of any box: drives particles onto the bounds
    return jnp.sum(jnp.array([1.0, -1.0, 1.0]) * x, axis=-1)


@settings(max_examples=20, deadline=None, database=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    # float32 bounds; no subnormals, which XLA's CPU backend flushes to zero
    lo=st.lists(st.floats(-100.0, 100.0, width=32, allow_subnormal=False), min_size=3, max_size=3),
    width=st.lists(st.floats(1e-3, 1e3), min_size=3, max_size=3),
)
def test_pso_inside_bounds_and_velocity_clamped(seed, lo, width):
    lower = np.array(lo, np.float32)
    upper = lower + np.array(width, np.float32)
    state, (pops, _, vels) = run(PSO(8), _linear, jax.random.key(seed), (lower, upper), 25)
    assert ((pops >= lower) & (pops <= upper)).all()
    vmax = np.float32(0.3) * (upper - lower)
    assert (np.abs(vels) <= vmax * (1 + 1e-6)).all()
    # the corner optimum drives particles onto the bounds: the clipping path is exercised
    assert ((pops == lower) | (pops == upper)).any()


def test_pso_init_around_mean():
    pso = PSO(16, init_spread=0.2)
    lower, upper = np.zeros(3, np.float32), np.array([1.0, 10.0, 100.0], np.float32)
    mean = np.array([0.95, 5.0, 50.0], np.float32)
    state = init(pso, jax.random.key(1), (lower, upper), mean)
    pos, vel = np.asarray(state.position), np.asarray(state.velocity)
    np.testing.assert_allclose(pos[0], mean)
    half = np.float32(0.1) * (upper - lower)
    assert (pos >= np.maximum(lower, mean - half) - 1e-6).all()
    assert (pos <= np.minimum(upper, mean + half) + 1e-6).all()
    assert (np.abs(vel) <= np.float32(0.3) * (upper - lower)).all()
    # the first ask returns the initial positions unchanged
    pop, _ = jit(pso.ask)(jax.random.key(2), state)
    np.testing.assert_array_equal(pop, pos)


def _swarm(x, v, pb, gb, lower, upper):
    return PSOState(
        lower=lower,
        upper=upper,
        position=x,
        velocity=v,
        pbest_position=pb,
        gbest_position=gb,
        generation=jnp.asarray(1, jnp.int32),
        pbest_fitness=jnp.zeros(x.shape[0]),
        gbest_fitness=jnp.zeros(()),
    )


def test_move_swarm_equations_clamp_and_bounds():
    move = jit(partial(move_swarm, omega=0.729, c1=2.05, c2=2.05, vmax_frac=0.3))
    lower, upper = jnp.zeros(2), jnp.array([10.0, 100.0])
    x = jnp.array([[5.0, 50.0], [9.9, 50.0]])
    v = jnp.array([[0.1, -0.2], [2.5, 0.0]])
    pb = jnp.array([[5.5, 49.0], [9.9, 50.0]])
    gb = jnp.array([6.0, 52.0])
    key = jax.random.key(3)
    x_new, v_new = move(key, _swarm(x, v, pb, gb, lower, upper))
    # eq. 2.45-2.46 with the same random numbers
    k1, k2 = jax.random.split(key)
    r1, r2 = (
        np.asarray(jax.random.uniform(k1, x.shape)),
        np.asarray(jax.random.uniform(k2, x.shape)),
    )
    x, v, pb, gb = (np.asarray(a) for a in (x, v, pb, gb))
    v_ref = 0.729 * v + 2.05 * r1 * (pb - x) + 2.05 * r2 * (gb - x)
    np.testing.assert_allclose(v_new[0], v_ref[0], rtol=1e-6)
    np.testing.assert_allclose(x_new[0], x[0] + v_ref[0], rtol=1e-6)
    # pushed through the upper bound of dim 0: clipped and that velocity component zeroed
    x_edge, v_edge = move(key, _swarm(x, v, x, upper, lower, upper))
    assert float(x_edge[1, 0]) == 10.0 and float(v_edge[1, 0]) == 0.0
    assert float(v_edge[1, 1]) > 0.0 and float(x_edge[1, 1]) < 100.0
    # far attractors: the velocity saturates at the clamp 0.3 * range
    _, v_far = move(key, _swarm(x, v, jnp.zeros_like(x), jnp.zeros(2), lower, upper))
    v_unclamped = 0.729 * v - 2.05 * (r1 + r2) * x
    vmax = np.array([3.0, 30.0])
    np.testing.assert_allclose(v_far, np.clip(v_unclamped, -vmax, vmax), rtol=1e-6)
    assert float(v_unclamped[0, 1]) < -30.0


# --- NaN handling (all strategies) --------------------------------------------------------------


@partial(jit, static_argnames=("strategy", "staged"))
def _nan_scenario(strategy, staged, key):
    """A generation with only NaN fitness, then one whose NaN candidate sits at the optimum."""
    k0, k1, k2 = jax.random.split(key, 3)

    def fitness(f):
        return (jnp.zeros(f.shape, jnp.int32), -f) if staged else f

    state = strategy.init(k0, box(3))
    pop, state = strategy.ask(k1, state)
    after_all_nan = strategy.tell(state, pop, fitness(jnp.full(pop.shape[:1], jnp.nan)))
    pop, state = strategy.ask(k2, after_all_nan)
    pop = pop.at[0].set(SHIFT[:3])
    f = jnp.sum((pop - SHIFT[:3]) ** 2, axis=-1).at[0].set(jnp.nan)
    return after_all_nan, strategy.tell(state, pop, fitness(f))


@pytest.mark.parametrize("name", sorted(STRATEGIES))
def test_nan_fitness_never_best_nor_in_state(name):
    strategy = make_strategy(name, 6)
    staged = name == "stage_pso"
    after_all_nan, state = _nan_scenario(strategy, staged, jax.random.key(5))
    assert no_nan(after_all_nan) and no_nan(state)
    _, fit = strategy.best(after_all_nan)
    if staged:
        assert int(fit[0]) == -1 and float(fit[1]) == -np.inf
    else:
        assert float(fit) == np.inf
    params, fit = strategy.best(state)
    assert not np.allclose(params, SHIFT[:3])  # the NaN candidate at the optimum is ignored
    assert bool(jnp.isfinite(fit[1] if staged else fit))


# --- stage ranking ------------------------------------------------------------------------------


_stage_better = jit(stage_better)
_stage_argbest = jit(stage_argbest)
_stage_rank_key = jit(stage_rank_key)
_evaluate_stages = jit(evaluate_stages)
_threshold_entrance = jit(threshold_entrance)


def test_stage_better_hand_cases():
    def better(a, b):
        return bool(_stage_better((a[0], float(a[1])), (b[0], float(b[1]))))

    assert better((2, -5.0), (1, 100.0))
    assert not better((1, 100.0), (2, -5.0))
    assert better((1, 3.0), (1, 2.0))
    assert not better((1, 2.0), (1, 3.0))
    assert not better((1, 2.0), (1, 2.0))  # strict
    assert better((0, -1e9), (0, np.nan))
    assert better((0, -np.inf), (3, np.nan))  # NaN is worse than anything valid
    assert not better((3, np.nan), (0, -1e9))
    assert not better((3, np.nan), (-1, -np.inf))
    a = (jnp.array([2, 1, 1, 0]), jnp.array([-5.0, 3.0, 2.0, np.nan]))
    b = (jnp.array([1, 1, 1, 0]), jnp.array([100.0, 2.0, 3.0, 0.0]))
    np.testing.assert_array_equal(_stage_better(a, b), [True, True, False, False])


def test_stage_argbest_and_rank_key():
    stage = np.array([0, 2, 2, 1, 2], np.int32)
    value = np.array([50.0, -3.0, -1.0, 9.0, np.nan], np.float32)
    assert int(_stage_argbest(stage, value)) == 2
    # top stage whose values are all -inf: still chosen from the top stage
    assert int(_stage_argbest(np.array([0, 1], np.int32), np.array([5.0, -np.inf]))) == 1
    key = np.asarray(_stage_rank_key(stage, value))
    assert key[4] == np.inf
    np.testing.assert_array_equal(np.argsort(key[:4]), [2, 1, 3, 0])
    # the scalar key agrees with the exact order on random pairs of moderate values
    rng = np.random.default_rng(0)
    s = rng.integers(0, 4, size=(2, 500)).astype(np.int32)
    v = rng.normal(0, 30, size=(2, 500)).astype(np.float32)
    key_a, key_b = _stage_rank_key(s, v, 30.0)
    np.testing.assert_array_equal(key_a < key_b, _stage_better((s[0], v[0]), (s[1], v[1])))


def test_evaluate_stages_hand_tables():
    criteria = np.array(
        [
            [1.0, 10.0, 100.0],
            [2.0, 20.0, 200.0],
            [3.0, 30.0, 300.0],
            [4.0, 40.0, 400.0],
        ],
        np.float32,
    )
    ok = np.array([[False, False], [True, False], [True, True], [False, True]])
    stage, value = _evaluate_stages(criteria, ok)
    np.testing.assert_array_equal(stage, [0, 1, 2, 0])  # row 3: a later pass does not count
    np.testing.assert_array_equal(value, [1.0, 20.0, 300.0, 4.0])
    assert stage.dtype == jnp.int32
    # thesis: a particle at stage N is evaluated up to stage N + 1
    stage, value = _evaluate_stages(criteria, ok, max_stage=jnp.array([0, 0, 1, 0]))
    np.testing.assert_array_equal(stage, [0, 0, 1, 0])
    np.testing.assert_array_equal(value, [1.0, 2.0, 30.0, 4.0])
    with pytest.raises(ValueError, match="S-1"):
        _evaluate_stages(criteria, jnp.ones((4, 3), bool))


def test_threshold_entrance_table_2_8():
    d_lim = 35.0
    thresholds = np.array([0.99 * d_lim, 0.8, -0.05, 6.0], np.float32)
    # columns: d, C_angles, C_speed, C_steplengths, -E
    criteria = np.array(
        [
            [12.0, 0.9, -0.01, 7.0, -900.0],  # fell early: stage 0, value d
            [35.0, 0.5, -0.01, 7.0, -800.0],  # reached d_lim, poor angles: stage 1
            [35.0, 0.9, -0.30, 7.0, -700.0],  # too slow: stage 2
            [35.0, 0.9, -0.01, 5.0, -600.0],  # irregular steps: stage 3
            [35.0, 0.9, -0.01, 7.0, -500.0],  # all passed: stage 4, value -E
            [np.nan, 0.9, -0.01, 7.0, -500.0],  # failed rollout: stage 0, NaN value
        ],
        np.float32,
    )
    stage, value = _evaluate_stages(criteria, _threshold_entrance(criteria, thresholds))
    np.testing.assert_array_equal(stage, [0, 1, 2, 3, 4, 0])
    np.testing.assert_allclose(value[:5], [12.0, 0.5, -0.30, 5.0, -500.0], rtol=1e-6)
    assert int(_stage_argbest(stage, value)) == 4
    assert np.isnan(value[5])


# --- stage PSO ----------------------------------------------------------------------------------


TARGET = jnp.array([3.0, -2.0])


def _toy_stages(x):
    """Stage 0: get x0 near 3; stage 1: get x1 near -2; stage 2: get close to (3, -2).

    NaN (a failed rollout) where x1 < -4.
    """
    err = jnp.abs(x - TARGET)
    criteria = jnp.stack([-err[:, 0], -err[:, 1], -jnp.sum(err**2, axis=-1)], axis=-1)
    criteria = jnp.where(x[:, 1:2] < -4.0, jnp.nan, criteria)
    return evaluate_stages(criteria, threshold_entrance(criteria, jnp.array([-0.5, -0.5])))


STAGE_PSO = StagePSO(16, init_spread=0.1)
STAGE_START = jnp.array([-4.0, 4.0])


def test_stage_pso_climbs_stages():
    state, (_, (stages, _), _) = run(
        STAGE_PSO, _toy_stages, jax.random.key(0), box(2), 50, STAGE_START
    )
    assert (stages[0] == 0).all()  # all particles start in stage 0
    params, (stage, value) = jax.device_get(STAGE_PSO.best(state))
    assert stage == 2
    assert value > -1e-3
    np.testing.assert_allclose(params, TARGET, atol=0.05)
    assert np.mean(np.asarray(state.pbest_stage)) > 1.5
    assert state.stage.dtype == jnp.int32 and state.pbest_stage.dtype == jnp.int32
    assert no_nan(state)


# --- CMA-ES -------------------------------------------------------------------------------------


def test_cmaes_converges_on_sphere_despite_nan():
    cma = CMAES(12, sigma_init=0.3)
    state, (pops, _, _) = run(cma, sphere, jax.random.key(0), box(5), 100)
    params, fit = jax.device_get(cma.best(state))
    assert fit < 1e-6
    np.testing.assert_allclose(jax.device_get(cma.mean(state)), SHIFT, atol=1e-2)
    assert ((pops >= -5.0) & (pops <= 5.0)).all()
    assert (pops[..., 0] > HOLE).any() and no_nan(state)


def test_cmaes_respects_bounds_with_disparate_ranges():
    # ranges from 2e-2 to 2e3; the optimum of ``sphere`` is outside the box in dims 0 and 4
    lower = np.array([0.0, -1e3, 0.0, 0.0, -1e-2], np.float32)
    upper = np.array([1e-3, 1e3, 1.0, 10.0, 1e-2], np.float32)
    cma = CMAES(12, sigma_init=0.3)
    state, (pops, _, _) = run(cma, sphere, jax.random.key(1), (lower, upper), 100)
    assert ((pops >= lower) & (pops <= upper)).all()
    params, fit = jax.device_get(cma.best(state))
    projected = np.clip(np.asarray(SHIFT), lower, upper)
    assert fit < np_sphere(projected) + 1e-3
    # dim 0 moves the fitness by at most 3e-3 over its range, so only dims 1-4 are located
    np.testing.assert_array_less(jnp.abs(params - projected)[1:] / (upper - lower)[1:], 0.02)
    mean = np.asarray(cma.mean(state))
    assert ((mean >= lower) & (mean <= upper)).all()


# --- scan vs loop, state as a pytree ------------------------------------------------------------


@pytest.mark.parametrize(
    "strategy, fn, bounds, init_mean",
    [
        (PSO(20), sphere, box(5), None),
        (STAGE_PSO, _toy_stages, box(2), STAGE_START),
        (CMAES(12, sigma_init=0.3), sphere, box(5), None),
    ],
    ids=["pso", "stage_pso", "cmaes"],
)
def test_scan_equals_python_loop(strategy, fn, bounds, init_mean):
    # 50 generations scanned inside one jit (compiled already by the tests above) against a
    # Python loop of jitted steps with the same keys
    key = jax.random.key(0)
    state0 = init(strategy, key, bounds, init_mean)
    block_key = jax.random.fold_in(key, 0)
    scanned, _ = advance(strategy, fn, state0, block_key, BLOCK)

    @jit
    def step(state, k):
        population, state = strategy.ask(k, state)
        return strategy.tell(state, population, fn(population))

    state = state0
    for k in jax.random.split(block_key, BLOCK):
        state = step(state, k)
    assert jax.tree.structure(state) == jax.tree.structure(scanned)
    for a, b in zip(jax.tree.leaves(state), jax.tree.leaves(scanned), strict=True):
        assert isinstance(a, jax.Array) and a.dtype == b.dtype and a.shape == b.shape
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
    assert int(scanned.generation) == BLOCK
