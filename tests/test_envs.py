"""Environments (thesis 2.2.4): registry, replay, push statistics, push forces."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from jaxgait.world import envs as E

N_DRAWS = 2000
push_force = jax.jit(E.push_force)  # jitted once: eager dispatch is slow
push_force_t = jax.jit(jax.vmap(E.push_force, (None, 0)))  # over a time grid


def _equal(a, b):
    leaves = zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True)
    return all(np.array_equal(x, y) for x, y in leaves)


@pytest.mark.parametrize("name", list(E.ENVIRONMENTS))
def test_every_env_builds_with_shared_structure(name):
    env = E.make_env(name, jax.random.key(0))
    ref = E.make_env("flat", jax.random.key(0))
    assert jax.tree.structure(env) == jax.tree.structure(ref)
    assert jax.tree.map(jnp.shape, env) == jax.tree.map(jnp.shape, ref)
    assert _equal(env, E.make_env(name, jax.random.key(0)))  # replay
    assert np.all(np.diff(np.asarray(env.terrain.xs)) > 0)


@pytest.mark.parametrize("name", ["push", "random_push", "wavy"])
def test_different_keys_differ(name):
    a, b = E.make_env(name, jax.random.key(1)), E.make_env(name, jax.random.key(2))
    assert not _equal(a, b)


def test_mixed_batch_vmaps():
    keys = jax.random.split(jax.random.key(5), len(E.ENVIRONMENTS))
    batch = E.stack_envs(E.make_env(n, k) for n, k in zip(E.ENVIRONMENTS, keys, strict=True))
    z, (fx, fz, h) = jax.jit(jax.vmap(lambda e: (e.terrain.height(30.0), e.push_force(4.0))))(batch)
    assert z.shape == fx.shape == (len(E.ENVIRONMENTS),)
    names = list(E.ENVIRONMENTS)
    assert z[names.index("slope_up")] > 0 > z[names.index("slope_down")]
    with pytest.raises(ValueError, match="shapes"):
        E.stack_envs([E.make_env("flat", keys[0]), E.make_env(E.FlatEnv(n_pushes=3), keys[0])])


def test_config_overrides_and_errors():
    cfg = E.get_env_config("slope_up", grade=0.12)
    assert cfg.grade == 0.12 and E.ENVIRONMENTS["slope_up"].grade == 0.05
    assert float(E.make_env(cfg, jax.random.key(0)).terrain.slope(50.0)) == pytest.approx(0.12)
    assert E.get_env_config("wavy", alpha_max=0.3).alpha_max == 0.3
    with pytest.raises(ValueError, match="valid names: flat, slope_up"):
        E.get_env_config("hills")
    with pytest.raises(ValueError, match="valid fields: .*magnitude_mean_max"):
        E.get_env_config("random_push", max_force=3.0)
    with pytest.raises(ValueError, match="interval_df2"):
        E.get_env_config("random_push", interval_df2=2)
    with pytest.raises(ValueError, match="duration_shape"):
        E.get_env_config("random_push", duration_shape=2.5)
    with pytest.raises(ValueError, match="n_knots"):
        E.get_env_config("increasing_slope", n_knots=50)
    with pytest.raises(TypeError):
        E.make_env(3, jax.random.key(0))


@pytest.fixture(scope="module")
def random_pushes():
    cfg = E.ENVIRONMENTS["random_push"]
    keys = jax.random.split(jax.random.key(11), N_DRAWS)
    batch = E.make_env_batch(cfg, keys)
    return cfg, batch.pushes, keys


def test_make_env_batch_matches_single_and_replays(random_pushes):
    cfg, p, keys = random_pushes
    one = E.make_env("random_push", keys[2])
    # batched and single builds draw the same numbers (equal up to float rounding)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a[2], b, rtol=1e-6), p, one.pushes)
    again = E.make_env_batch(cfg, keys)
    assert all(
        np.array_equal(a, b)
        for a, b in zip(jax.tree.leaves(p), jax.tree.leaves(again.pushes), strict=True)
    )
    inner = jax.jit(lambda k: E.make_env("push", k).push_force(3.0))  # make_env inside a jit
    assert all(np.isfinite(np.asarray(v)) for v in inner(keys[0]))


def test_random_push_timing(random_pushes):
    """Pauses: scaled F(20, 20), mean 1 s; durations: gamma, mean 0.25 s.

    2000 draws x 128 pushes = 256,000 samples: SE of the mean pause 0.49 / 506 ~ 1e-3 s, of
    the mean duration 0.125 / 506 ~ 2.5e-4 s; tolerances are 5 SE.  KS tests on 20,000."""
    cfg, p, _ = random_pushes
    p = jax.tree.map(lambda x: np.asarray(x, np.float64), p)
    end = p.t0 + p.duration
    assert np.all(p.t0[:, 1:] >= end[:, :-1])  # never two pushes at once
    pause = np.concatenate([p.t0[:, :1] - cfg.t_start, p.t0[:, 1:] - end[:, :-1]], 1).ravel()
    f = stats.f(cfg.interval_df1, cfg.interval_df2, scale=cfg.interval_scale)
    assert pause.mean() == pytest.approx(1.0, abs=5 * f.std() / math.sqrt(pause.size))
    assert stats.kstest(pause[:20000], f.cdf).pvalue > 1e-3
    d = p.duration.ravel()
    g = stats.gamma(cfg.duration_shape, scale=cfg.duration_mean / cfg.duration_shape)
    assert d.mean() == pytest.approx(0.25, abs=5 * g.std() / math.sqrt(d.size))
    assert stats.kstest(d[:20000], g.cdf).pvalue > 1e-3


def test_random_push_angle_and_height(random_pushes):
    """angle ~ N(0, pi/2): SE mean 1.57/506 = 3.1e-3, SE sd 2.2e-3; height ~ U(0, 0.8 m)."""
    cfg, p, _ = random_pushes
    p = jax.tree.map(lambda x: np.asarray(x, np.float64), p)
    a, h = p.angle.ravel(), p.height.ravel()
    n = a.size
    assert a.mean() == pytest.approx(0.0, abs=5 * (math.pi / 2) / math.sqrt(n))
    assert a.std() == pytest.approx(math.pi / 2, abs=5 * (math.pi / 2) / math.sqrt(2 * n))
    assert stats.kstest(a[:20000], stats.norm(0, math.pi / 2).cdf).pvalue > 1e-3
    assert h.mean() == pytest.approx(0.4, abs=5 * (0.8 / math.sqrt(12)) / math.sqrt(n))
    assert h.min() >= 0 and h.max() <= cfg.trunk_length
    assert stats.kstest(h[:20000], stats.uniform(0, 0.8).cdf).pvalue > 1e-3


def test_random_push_amplitude_ramp(random_pushes):
    """Per push index, mean and SD over 2000 draws rise linearly to (120 N, 20 N) at push 60.

    SE of the mean r_i 20 / sqrt(2000) (5 SE tolerance); SE of the SD ~ 1/sqrt(2n) = 1.6 %
    (8 % tolerance).  Clipping at 0 is negligible (mean/SD = 6)."""
    cfg, p, _ = random_pushes
    p = jax.tree.map(lambda x: np.asarray(x, np.float64), p)
    r = np.minimum((np.arange(cfg.n_pushes) + 1) / cfg.n_ramp, 1.0)
    m, s = p.magnitude.mean(0), p.magnitude.std(0)
    assert np.all(p.magnitude >= 0)
    np.testing.assert_array_less(np.abs(m - 120.0 * r), 5 * 20.0 * r / math.sqrt(N_DRAWS))
    np.testing.assert_allclose(s, 20.0 * r, rtol=0.08)
    slope, intercept = np.polyfit(np.arange(cfg.n_ramp), m[: cfg.n_ramp], 1)
    assert slope == pytest.approx(120.0 / cfg.n_ramp, rel=0.01)
    assert m[cfg.n_ramp :].mean() == pytest.approx(120.0, abs=0.2)


def test_single_push_env():
    cfg = E.get_env_config("push", magnitude=50.0, t_min=2.0, t_max=6.0)
    batch = E.make_env_batch(cfg, jax.random.split(jax.random.key(3), N_DRAWS))
    t0 = np.asarray(batch.pushes.t0[:, 0], np.float64)
    assert t0.min() >= 2.0 and t0.max() <= 6.0
    assert stats.kstest(t0, stats.uniform(2.0, 4.0).cdf).pvalue > 1e-3
    assert np.all(np.asarray(batch.pushes.magnitude[:, 1:]) == 0)
    env = jax.tree.map(lambda x: x[0], batch)
    t = float(env.pushes.t0[0])
    assert float(push_force(env.pushes, t + 0.1)[0]) == pytest.approx(50.0)
    assert float(push_force(env.pushes, t - 0.01)[0]) == 0.0
    assert float(push_force(env.pushes, t + 0.26)[0]) == 0.0


def _overlapping():
    return E.Pushes(
        t0=jnp.array([1.0, 1.2, 3.0, 0.0]),
        duration=jnp.array([0.5, 0.5, 0.25, 0.0]),
        magnitude=jnp.array([10.0, 20.0, 40.0, 0.0]),
        angle=jnp.array([0.0, math.pi / 2, -2.5, 0.0]),
        height=jnp.array([0.2, 0.6, 0.4, 0.0]),
    )


def test_push_force_sums_overlaps_and_is_zero_outside():
    p = _overlapping()
    fx, fz, h = push_force(p, 1.3)  # pushes 0 and 1 overlap
    assert float(fx) == pytest.approx(10.0) and float(fz) == pytest.approx(20.0, abs=1e-5)
    assert float(h) == pytest.approx((10 * 0.2 + 20 * 0.6) / 30)
    for t in [0.0, 0.99, 1.7, 2.5, 3.25, 10.0]:
        assert [float(v) for v in push_force(p, t)] == [0.0, 0.0, 0.0]
    fx, fz, h = push_force(p, 3.1)
    assert float(fx) == pytest.approx(40 * math.cos(-2.5), rel=1e-5)
    assert float(h) == pytest.approx(0.4)


def test_push_force_impulse():
    """Midpoint-rule integral over [0, 4] s with dt = 1e-4 s: error <= 2 F dt per push."""
    p = _overlapping()
    dt = 1e-4
    t = (np.arange(40000) + 0.5) * dt
    fx, fz, _ = push_force_t(p, t)
    fx, fz = np.asarray(fx, np.float64), np.asarray(fz, np.float64)
    jx, jz = float(fx.sum() * dt), float(fz.sum() * dt)
    f, d, a = (np.asarray(v, np.float64) for v in (p.magnitude, p.duration, p.angle))
    tol = 2 * f.sum() * dt + 1e-3
    assert jx == pytest.approx(np.sum(f * d * np.cos(a)), abs=tol)
    assert jz == pytest.approx(np.sum(f * d * np.sin(a)), abs=tol)


def test_empty_pushes_never_push():
    env = E.make_env("wavy", jax.random.key(0))
    t = np.linspace(0.0, 200.0, 2001)
    fx, fz, _ = push_force_t(env.pushes, t)
    assert not np.any(np.asarray(fx)) and not np.any(np.asarray(fz))


def test_f_and_gamma_samplers():
    sample = jax.jit(lambda k: (E.sample_f(k, 6, 12, (20000,)), E.sample_gamma(k, 3, (20000,))))
    f, g = (np.asarray(v, np.float64) for v in sample(jax.random.key(0)))
    assert stats.kstest(f, stats.f(6, 12).cdf).pvalue > 1e-3
    assert stats.kstest(g, stats.gamma(3).cdf).pvalue > 1e-3
    with pytest.raises(ValueError, match="df1"):
        E.sample_f(jax.random.key(0), 5.5, 12, (3,))


def test_weight_support_carries_its_share_of_the_body_weight():
    """``weight_support``: one constant upward force fraction * m * g on the trunk, from
    t = 0 to past any rollout; the same pushes as ``push`` configured as a harness."""
    cfg = E.get_env_config("weight_support", fraction=0.25)
    env = E.make_env(cfg, jax.random.key(3))
    for t in (0.0, 7.3, 1000.0):
        fx, fz, h = push_force(env.pushes, t)
        assert float(fx) == pytest.approx(0.0, abs=1e-3)
        assert float(fz) == pytest.approx(0.25 * 80.0 * 9.81, rel=1e-6)  # 196.2 N
        assert float(h) == pytest.approx(0.3)
    assert float(jnp.count_nonzero(env.pushes.magnitude)) == 1
    harness = E.get_env_config(
        "push", magnitude=196.2, angle=math.pi / 2, t_min=0.0, t_max=0.0, duration=1e6, height=0.3
    )
    a, b = E.make_env(harness, jax.random.key(0)).pushes, env.pushes
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=1e-6, atol=1e-6)
    assert float(E.make_env("weight_support", jax.random.key(0)).pushes.magnitude[0]) == (
        pytest.approx(0.3 * 80.0 * 9.81)
    )
    for bad in (1.0, -0.1):
        with pytest.raises(ValueError, match="fraction"):
            E.get_env_config("weight_support", fraction=bad)
    with pytest.raises(ValueError, match="mass"):
        E.get_env_config("weight_support", mass=0.0)


def test_fading_weight_support_falls_linearly_to_none():
    """``fade_s`` = 8 s, 20 %: 16 steps of 0.5 s whose forces follow the line from 156.96 N
    at t = 0 to 0 at 8 s at each step's middle (step 0: 152.05 N, step 15: 4.91 N); nothing
    from 8 s on; the same total impulse as the line (627.8 N s)."""
    cfg = E.get_env_config("weight_support", fraction=0.2, fade_s=8.0)
    env = E.make_env(cfg, jax.random.key(0))
    full = 0.2 * 80.0 * 9.81
    for t, want in ((0.0, full * 31 / 32), (0.49, full * 31 / 32), (0.5, full * 29 / 32),
                    (7.99, full / 32), (8.0, 0.0), (20.0, 0.0)):  # fmt: skip
        fx, fz, _ = push_force(env.pushes, t)
        assert float(fz) == pytest.approx(want, rel=1e-5, abs=1e-3), t
        assert float(fx) == pytest.approx(0.0, abs=1e-3)
    p = env.pushes
    impulse = float(jnp.sum(p.magnitude * p.duration))
    assert impulse == pytest.approx(full * 8.0 / 2, rel=1e-6)
    assert int(jnp.count_nonzero(p.magnitude)) == E.FADE_STEPS
    with pytest.raises(ValueError, match="fade_s"):
        E.get_env_config("weight_support", fade_s=-1.0)


def test_weight_support_pulls_along_its_angle():
    """``angle`` 0: a tow of 0.05 body weights straight forwards (39.24 N, no vertical part);
    pi/3: the same force split 19.62 N forwards, 33.98 N up; fading, the forward part fades.
    An angle outside [-pi, pi] is refused with its name."""
    w = 0.05 * 80.0 * 9.81
    env = E.make_env(
        E.get_env_config("weight_support", fraction=0.05, angle=0.0), jax.random.key(0)
    )
    fx, fz, _ = push_force(env.pushes, 3.0)
    assert float(fx) == pytest.approx(w, rel=1e-6) and float(fz) == pytest.approx(0.0, abs=1e-4)
    cfg = E.get_env_config("weight_support", fraction=0.05, angle=math.pi / 3)
    fx, fz, _ = push_force(E.make_env(cfg, jax.random.key(0)).pushes, 3.0)
    assert float(fx) == pytest.approx(w / 2, rel=1e-5)
    assert float(fz) == pytest.approx(w * math.sqrt(3) / 2, rel=1e-5)
    cfg = E.get_env_config("weight_support", fraction=0.05, angle=0.0, fade_s=8.0)
    fx, fz, _ = push_force(E.make_env(cfg, jax.random.key(0)).pushes, 0.1)
    assert float(fx) == pytest.approx(w * 31 / 32, rel=1e-5) and abs(float(fz)) < 1e-4
    with pytest.raises(ValueError, match="angle"):
        E.get_env_config("weight_support", angle=4.0)
