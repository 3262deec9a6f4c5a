"""Terrain builders (thesis 2.2.4): fixed knot counts, geometry, wavy ground, increasing slope."""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from jaxgait.world import terrain as T

WAVY = T.WavyConfig()
INC = T.IncreasingSlopeConfig()


K = T.DEFAULT_N_KNOTS


@functools.cache
def _terrains():
    """One terrain per kind, all with K knots (one compilation of the checks below)."""
    return {
        "flat": T.flat(n_knots=K),
        "slope_up": T.slope(0.07, n_knots=K),
        "slope_down": T.slope(-0.07, n_knots=K),
        "wavy": T.wavy(jax.random.key(3), WAVY),
        "increasing_slope": T.increasing_slope(INC),
    }


def test_existing_api_unchanged():
    f, s = T.flat(), T.slope(0.1)
    assert f.xs.shape == (2,) and s.xs.shape == (3,)
    assert float(s.height(12.0)) == pytest.approx(1.0, abs=1e-5)
    assert float(f.height(5.0)) == 0.0


def test_with_knots_preserves_profile():
    xs, zs = np.array([-10.0, 1.0, 20.0]), np.array([0.0, 0.0, -3.8])
    x = np.linspace(-30.0, 60.0, 901)

    @jax.jit
    def profiles(xs, zs):  # jnp path (as inside the jitted builders)
        base = T.Terrain(xs=xs, zs=zs)
        padded = T.with_knots(base, 40, spacing=0.5)
        f = lambda t: (jax.vmap(t.height)(x), jax.vmap(t.slope)(x))
        return padded.xs, f(padded), f(base)

    pxs, (h1, s1), (h0, s0) = profiles(xs, zs)
    assert pxs.shape == (40,) and np.all(np.diff(np.asarray(pxs)) > 0)
    np.testing.assert_allclose(h1, h0, atol=1e-4)
    np.testing.assert_allclose(s1, s0, atol=1e-5)
    padded_np = T.with_knots(T.Terrain(xs=xs, zs=zs), 40, spacing=0.5)  # NumPy path
    assert isinstance(padded_np.xs, np.ndarray)
    np.testing.assert_allclose(padded_np.xs, pxs, rtol=1e-6)
    with pytest.raises(ValueError, match="more than"):
        T.with_knots(padded_np, 10)


@jax.jit
def _tangent_and_normal(t, x, e):
    h = jax.vmap(t.height)
    dz = (h(x + e) - h(x - e)) / (2 * e)
    tangent = jnp.stack([jnp.ones_like(dz), dz], -1)
    tangent = tangent / jnp.linalg.norm(tangent, axis=-1, keepdims=True)
    return tangent, jax.vmap(t.normal)(x)


@pytest.mark.parametrize("name", ["flat", "slope_up", "slope_down", "wavy", "increasing_slope"])
def test_normal_consistent_with_height(name):
    """The normal is unit, points up and is orthogonal to the finite-difference tangent."""
    t = _terrains()[name]
    xs = np.asarray(t.xs, np.float64)
    mid = 0.5 * (xs[1:] + xs[:-1])
    eps = 0.25 * np.diff(xs)  # stay inside the segment: the profile is linear there
    mid = np.concatenate([mid, [xs[0] - 3.0, xs[-1] + 3.0]])  # and the extrapolated ends
    eps = np.concatenate([eps, [1.0, 1.0]])
    x, e = jnp.asarray(mid, jnp.float32), jnp.asarray(eps, jnp.float32)
    tangent, n = _tangent_and_normal(t, x, e)
    np.testing.assert_allclose(jnp.linalg.norm(n, axis=-1), 1.0, atol=1e-6)
    assert bool(jnp.all(n[:, 1] > 0))
    np.testing.assert_allclose(jnp.sum(n * tangent, -1), 0.0, atol=1e-3)


def test_fixed_knot_count_and_stackable():
    ts = list(_terrains().values())
    assert all(t.xs.shape == (K,) for t in ts)
    batch = jax.tree.map(lambda *a: jnp.stack(a), *ts)
    z = jax.jit(jax.vmap(lambda t: t.height(50.0)))(batch)
    assert z.shape == (5,) and float(z[1]) > 0 > float(z[2])


@pytest.fixture(scope="module")
def wavy_batch():
    keys = jax.random.split(jax.random.key(2), 500)
    return keys, jax.jit(jax.vmap(lambda k: T.wavy(k, WAVY)))(keys)


def test_wavy_replay_jit_vmap(wavy_batch):
    keys, batch = wavy_batch
    a, b = T.wavy(keys[2], WAVY), T.wavy(keys[2], WAVY)  # wavy is jitted, cfg static
    np.testing.assert_array_equal(a.xs, b.xs)  # replay is exact
    np.testing.assert_array_equal(a.zs, b.zs)
    assert not np.allclose(a.xs, T.wavy(keys[3], WAVY).xs)
    assert batch.xs.shape == (500, WAVY.n_knots)
    np.testing.assert_allclose(batch.xs[2], a.xs, rtol=1e-6)  # vmap draws the same numbers
    np.testing.assert_allclose(batch.zs[2], a.zs, rtol=1e-6, atol=1e-7)
    assert np.all(np.diff(np.asarray(batch.xs), axis=-1) > 0)


def test_wavy_angles_equal_up_down_and_increase(wavy_batch):
    _, batch = wavy_batch
    xs, zs = np.asarray(batch.xs[:20], np.float64), np.asarray(batch.zs[:20], np.float64)
    s = np.diff(zs, axis=-1) / np.diff(xs, axis=-1)
    i = np.arange(WAVY.n_structures)
    up, top, down, gap = s[:, 4 * i + 1], s[:, 4 * i + 2], s[:, 4 * i + 3], s[:, 4 * i + 4]
    alpha = T.wavy_angles(WAVY)
    np.testing.assert_allclose(up, np.broadcast_to(np.tan(alpha), up.shape), rtol=1e-3)
    np.testing.assert_allclose(down, -up, rtol=1e-3)  # equal up and down angles
    np.testing.assert_allclose(top, 0.0, atol=1e-6)
    np.testing.assert_allclose(gap, 0.0, atol=1e-6)
    assert np.all(s[:, 0] == 0) and np.all(s[:, -1] == 0)  # level before and after
    assert np.all(np.diff(alpha) > 0) and alpha[-1] == pytest.approx(WAVY.alpha_max)
    sat = T.wavy_angles(T.WavyConfig(n_structures=12, n_increase=8, alpha_max=0.2, n_knots=60))
    np.testing.assert_allclose(sat, 0.2 * np.minimum((np.arange(12) + 1) / 8, 1.0))


def test_wavy_lengths_and_gaps_are_normal(wavy_batch):
    """Mean and SD of 500 x 30 lengths/gaps; SE of the mean 0.5/sqrt(15000) = 0.004 m."""
    _, batch = wavy_batch
    xs = np.asarray(batch.xs, np.float64)
    i = np.arange(WAVY.n_structures)
    lengths = xs[:, 4 * i + 4] - xs[:, 4 * i + 1]
    gaps = xs[:, 4 * i + 5] - xs[:, 4 * i + 4]
    for v, mean, sd in [(lengths, WAVY.length_mean, WAVY.length_sd), (gaps, WAVY.gap_mean, 0.5)]:
        assert v.mean() == pytest.approx(mean, abs=5 * sd / math.sqrt(v.size))
        assert v.std() == pytest.approx(sd, rel=0.05)
        assert v.min() >= WAVY.min_length - 1e-5


def test_increasing_slope_reaches_final_grade():
    t = T.increasing_slope(INC)
    end = INC.start + INC.length
    assert float(t.slope(INC.start - 1.0)) == 0.0
    assert float(t.slope(end + 0.5)) == pytest.approx(0.30, abs=1e-5)
    assert float(t.slope(end + 500.0)) == pytest.approx(0.30, abs=1e-4)
    assert float(t.slope(end - 0.5)) == pytest.approx(0.30, abs=0.3 / 160)  # last piece
    assert float(t.slope(INC.start + 80.2)) == pytest.approx(0.15, abs=0.3 / 160)
    assert float(t.height(end)) == pytest.approx(0.5 * 0.30 * 160.0, rel=1e-5)  # 24 m


def test_increasing_slope_height_is_integral_of_grade():
    """h(x) vs the trapezoid-rule integral of g on a 1 cm grid; interpolation error bound
    final_grade / length * dx^2 / 8 = 2.3e-4 m for 1 m knots."""
    t = T.increasing_slope(INC)
    x = np.linspace(-5.0, INC.start + INC.length + 20.0, 18501)
    g = np.asarray(T.increasing_slope_grade(INC, x), np.float64)
    ref = cumulative_trapezoid(g, x, initial=0.0)
    h = np.asarray(jax.jit(jax.vmap(t.height))(jnp.asarray(x, jnp.float32)), np.float64)
    np.testing.assert_allclose(h, ref, atol=2.4e-4 + 1e-5)


def test_polyline_mesh_hfield():
    t = T.wavy(jax.random.key(4), WAVY)
    p = T.terrain_polyline(t, 0.0, 20.0)
    assert p[0, 0] == 0.0 and p[-1, 0] == 20.0 and np.all(np.diff(p[:, 0]) > 0)
    inside = np.asarray(t.xs)[(np.asarray(t.xs) > 0) & (np.asarray(t.xs) < 20)]
    assert len(p) == len(inside) + 2
    np.testing.assert_allclose(p[1:-1, 1], np.asarray(t.zs)[np.isin(np.asarray(t.xs), inside)])
    v, f = T.terrain_mesh(t, 0.0, 20.0, width=1.0, n=50)
    assert v.shape == (100, 3) and f.shape == (98, 3)
    e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
    assert np.all(np.cross(e1, e2)[:, 2] > 0)  # faces look up
    hf = T.terrain_hfield(t, 0.0, 20.0, ncol=81)
    rx, ry, ez, bz = hf["size"]
    z = hf["pos"][2] + hf["elevation"][0] * ez
    np.testing.assert_allclose(z, T.terrain_polyline(t, 0.0, 20.0, 81)[:, 1], atol=1e-6)
    assert hf["elevation"].shape == (2, 81) and rx == 10.0
    with pytest.raises(ValueError):
        T.terrain_polyline(t, 5.0, 1.0)


def test_config_validation():
    with pytest.raises(ValueError, match="n_knots"):
        T.WavyConfig(n_structures=30, n_knots=100)
    with pytest.raises(ValueError, match="ramp_fraction"):
        T.WavyConfig(ramp_fraction=0.5)
    with pytest.raises(ValueError, match="n_knots"):
        T.IncreasingSlopeConfig(n_segments=300)
