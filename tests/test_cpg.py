"""Feedforward pattern generation (thesis 6.3-6.4): periodic splines, the arbitrary-wave
oscillator, the central clock and the periodic-variability factors."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxgait.analysis.variability import (
    cycle_starts,
    noisy_sine,
    pattern_correlation,
    variability,
)
from jaxgait.control import cpg


def _shape(phase):
    return np.sin(2 * np.pi * phase) + 0.3 * np.cos(4 * np.pi * phase)


def test_periodic_spline_through_knots_and_c1_across_the_period():
    knots = _shape(np.arange(100) / 100)
    coef = jnp.asarray(cpg.periodic_spline(knots), jnp.float32)
    g, dg = cpg.spline_eval(coef, jnp.arange(100) / 100.0)
    np.testing.assert_allclose(np.asarray(g), knots, atol=1e-5)
    # value and slope continuous through phase 1 == 0
    g0, d0 = cpg.spline_eval(coef, jnp.asarray(1e-9))
    g1, d1 = cpg.spline_eval(coef, jnp.asarray(1 - 1e-9))
    assert abs(float(g0 - g1)) < 1e-4 and abs(float(d0 - d1)) < 1e-2
    # derivative against the analytic one of the smooth shape it samples
    th = np.linspace(0, 1, 37, endpoint=False)
    exact = 2 * np.pi * np.cos(2 * np.pi * th) - 1.2 * np.pi * np.sin(4 * np.pi * th)
    np.testing.assert_allclose(
        np.asarray(cpg.spline_eval(coef, jnp.asarray(th))[1]), exact, atol=2e-3
    )


def test_periodic_spline_resamples_other_lengths_and_rejects_bad_patterns():
    coef = cpg.periodic_spline(_shape(np.arange(220) / 220))
    assert coef.shape == (100, 4)
    with pytest.raises(ValueError, match="non-finite"):
        cpg.periodic_spline([0.0, np.nan, 1.0, 2.0])
    with pytest.raises(ValueError, match="at least 3"):
        cpg.periodic_spline([0.0, 1.0])


def _awo_run(omega_of_t, t_end, dt=5e-4, x0=0.0):
    coef = jnp.asarray(cpg.periodic_spline(_shape(np.arange(100) / 100)), jnp.float32)
    spline = cpg.PeriodicSpline(coef)
    omegas = jnp.asarray([omega_of_t(k * dt) for k in range(int(round(t_end / dt)))], jnp.float32)

    def body(carry, w):
        theta, x = carry
        x = cpg.awo_step(x, theta, w, spline, dt)
        theta = jnp.mod(theta + w * dt, 1.0)
        return (theta, x), x - spline(theta)[0]

    _, errs = jax.lax.scan(body, (jnp.zeros(()), jnp.asarray(x0, jnp.float32)), omegas)
    return np.abs(np.asarray(errs))


def test_awo_converges_to_its_shape_at_rate_gamma():
    err = _awo_run(lambda t: 1.0, 0.2, x0=2.0)
    # |e| decays as exp(-gamma t): below 2 e^-10 (plus the Euler error) after 0.1 s
    assert err[199] < 2 * np.exp(-10) + 0.02
    assert err[-100:].max() < 0.02


def test_awo_tracks_a_changed_frequency():
    err = _awo_run(lambda t: 0.8 if t < 1.0 else 1.6, 2.0, x0=float(_shape(0.0)))
    assert err.max() < 0.03  # g' theta' carries the new rate: no re-convergence needed


@jax.jit
def _clock_scan_impl(td, omega, dt):
    def body(th, td_k):
        th, _ = cpg.clock_step(th, omega, td_k, dt)
        return th, th

    return jax.lax.scan(body, jnp.zeros(()), td)[1]


def _clock_scan(td, omega, dt):
    return _clock_scan_impl(td, jnp.asarray(omega, jnp.float32), jnp.asarray(dt, jnp.float32))


@settings(max_examples=40, deadline=None)
@given(
    omega=st.floats(0.2, 3.0),
    dt=st.sampled_from([2.5e-4, 5e-4, 1e-3]),
    td_times=st.lists(st.floats(0.05, 6.0), min_size=0, max_size=6),
)
def test_clock_restarts_at_touchdown_and_never_passes_one(omega, dt, td_times):
    n = int(6.0 / dt)
    td = np.zeros(n, bool)
    for t in td_times:
        td[min(int(t / dt), n - 1)] = True
    thetas = np.asarray(_clock_scan(jnp.asarray(td), omega, dt))
    assert np.all(thetas >= 0) and np.all(thetas < 1)
    assert np.all(thetas[td] == 0)


def test_clock_waiting_long_stays_below_one():
    # no touchdown for 8 s at 3 cycles/s: 1 - theta underflows the float32 spacing near 1
    thetas = np.asarray(_clock_scan(jnp.zeros(16000, bool), 3.0, 5e-4))
    assert thetas.max() < 1.0 and thetas[-1] > 0.999


def test_clock_rate_is_omega_before_p_and_continuous_at_p():
    omega, p = 0.9, cpg.CLOCK_SLOW_PHASE
    assert float(cpg.clock_rate(jnp.asarray(0.5), omega)) == pytest.approx(omega)
    below = float(cpg.clock_rate(jnp.asarray(p - 1e-7), omega))
    above = float(cpg.clock_rate(jnp.asarray(p + 1e-7), omega))
    assert above == pytest.approx(below, rel=1e-5)  # theta(t) is C^1 at p
    # the exact step matches the law: from p, 1 - theta decays as exp(-omega t / (1 - p))
    th, _ = cpg.clock_step(jnp.asarray(p), omega, jnp.asarray(False), 0.2)
    assert float(1 - th) == pytest.approx((1 - p) * np.exp(-omega * 0.2 / (1 - p)), rel=1e-5)
    # a step that crosses p: linear up to p, then the exponential approach
    th, _ = cpg.clock_step(jnp.asarray(p - 0.05), omega, jnp.asarray(False), 0.1)
    rest = 0.1 - 0.05 / omega
    assert float(th) == pytest.approx(1 - (1 - p) * np.exp(-omega * rest / (1 - p)), rel=1e-5)


# ----------------------------------------------------------------------- variability


def test_stability_factor_of_a_pure_sine_is_zero_and_its_pattern_is_the_sine():
    t, y, starts = noisy_sine(0.0, m=20)
    v = variability(t, y, starts)
    assert v.s < 1e-20 and v.v_mu < 1e-12 and v.v_sigma < 1e-12
    ref = np.sin(2 * np.pi * np.arange(100) / 100) / np.std(
        np.sin(2 * np.pi * np.arange(100) / 100)
    )
    np.testing.assert_allclose(v.pattern, ref, atol=1e-9)


@pytest.mark.parametrize("noise", [0.1, 0.25, 0.5, 0.75])
def test_stability_factor_of_a_noisy_sine_calibrates_to_sigma_squared(noise):
    # eq. 6.13: s ~ sigma^2; each cycle is normalised by its own SD (that of sine + noise),
    # so the exact expectation is sigma^2 / (1 + sigma^2), ~sigma^2 for small noise
    t, y, starts = noisy_sine(noise, m=400, seed=1)
    v = variability(t, y, starts)
    assert v.s == pytest.approx(noise**2 / (1 + noise**2), rel=0.1)


def test_offsets_and_amplitudes_show_in_v_mu_and_v_sigma():
    rng = np.random.default_rng(3)
    n, m = 100, 300
    off, amp = rng.normal(0, 0.2, m), 1 + rng.normal(0, 0.1, m)
    ph = np.arange(n) / n
    cycles = [o + a * np.sin(2 * np.pi * ph) for o, a in zip(off, amp, strict=True)]
    y = np.concatenate(cycles + [[off[0]]])
    t = np.arange(y.size) / n
    v = variability(t, y, np.arange(0, m * n + 1, n))
    assert v.s < 1e-12  # the shape is the same in every cycle
    assert v.v_mu == pytest.approx(np.std(off), rel=1e-6)
    assert v.v_sigma == pytest.approx(np.std(amp * np.std(np.sin(2 * np.pi * ph))), rel=1e-6)


def test_cycle_cutting_gates_and_errors():
    stance = np.array([0, 0, 1, 1, 0, 1, 1, 1, 0, 0, 1], bool)
    np.testing.assert_array_equal(cycle_starts(stance), [2, 5, 10])
    t = np.arange(11.0)
    y = np.where(stance, 2.0, 0.0)
    v = variability(t, y, cycle_starts(stance), active=stance)
    assert v.mean_active == 2.0 and v.n_cycles == 2
    with pytest.raises(ValueError, match="at least 2 whole cycles"):
        variability(t, y, cycle_starts(stance), skip=1)
    assert pattern_correlation(np.arange(5.0), 2 * np.arange(5.0)) == pytest.approx(1.0)
    assert pattern_correlation(np.ones(5), np.arange(5.0)) == 0.0
