"""Criteria (thesis eq. 2.51-2.61) on hand-made measures, and stopping criteria."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait.analysis import criteria as C
from jaxgait.analysis import measures as M


def fake_measures(**over):
    m = {
        "distance_m": 30.0,
        "duration_s": 25.0,
        "mean_speed_mps": 1.2,
        "energy_J": 6000.0,
        "c_angles": 0.83,
        "step_length_snr": 6.5,
        "step_length_mean_m": 0.68,
        "step_length_left_mean_m": 0.70,
        "step_length_left_var_m2": 1e-3,
        "step_length_right_mean_m": 0.66,
        "step_length_right_var_m2": 2e-3,
        "n_steps_left": 20,
        "n_steps_right": 20,
        "mean_trunk_lean_rad": 0.05,
    }
    m.update(over)
    return {k: jnp.asarray(v) for k, v in m.items()}


def test_criteria_by_hand():
    m = fake_measures()
    assert float(C.criterion("distance", m)) == 30.0
    assert float(C.criterion("angles", m)) == pytest.approx(0.83)
    assert float(C.criterion("steplengths", m)) == pytest.approx(6.5)
    assert float(C.criterion("speed", m, v_desired=1.3)) == pytest.approx(-0.1)
    assert float(C.criterion("steplength", m, sl_desired=0.6)) == pytest.approx(-0.08)
    assert float(C.criterion("cot", m)) == pytest.approx(30.0**2 / 6000.0)
    assert float(C.criterion("energy", m)) == -6000.0
    lr = -math.log1p(abs(0.70 / 1e-3 - 0.66 / 2e-3))
    assert float(C.criterion("left_right", m)) == pytest.approx(lr, rel=1e-5)


def test_thesis_spellings_and_errors():
    m = fake_measures()
    assert float(C.criterion("C_speed", m, v_desired=1.0)) == pytest.approx(-0.2)
    assert float(C.criterion("d", m)) == 30.0
    assert float(C.criterion("-E", m)) == -6000.0
    assert C.resolve_name("C_left_right") == "left_right"
    with pytest.raises(ValueError, match=r"unknown criterion 'speeed'.*'speed'"):
        C.criterion("speeed", m)
    with pytest.raises(ValueError, match="v_desired"):
        C.criterion("speed", m)
    with pytest.raises(TypeError, match="v_target"):
        C.criterion("distance", m, v_target=1.3)
    # targets a criterion does not use are ignored (one target set for a whole stage list)
    assert float(C.criterion("distance", m, v_desired=1.3, sl_desired=0.7)) == 30.0


@pytest.mark.parametrize(
    "lean, expect",
    [(0.05, 0.0), (0.0, 0.0), (0.105, 0.0), (0.2, -0.095), (-0.03, -0.03)],
)
def test_trunk_band(lean, expect):
    v = C.criterion("trunk", fake_measures(mean_trunk_lean_rad=lean))
    assert float(v) == pytest.approx(expect, abs=1e-7)


def test_trunk_band_is_adjustable_and_maximal_inside():
    leans = jnp.linspace(-0.3, 0.4, 71)
    v = C.c_trunk(fake_measures(mean_trunk_lean_rad=leans))
    inside = (leans >= 0) & (leans <= 0.105)
    assert bool(jnp.all(jnp.where(inside, v == 0, v < 0)))
    v2 = C.criterion("trunk", fake_measures(mean_trunk_lean_rad=0.15), trunk_hi=0.2)
    assert float(v2) == 0.0


def test_left_right_symmetry_is_maximal_and_undefined_sentinel():
    sym = fake_measures(step_length_right_mean_m=0.70, step_length_right_var_m2=1e-3)
    assert float(C.c_left_right(sym)) == 0.0
    assert float(C.c_left_right(fake_measures())) < 0.0
    few = fake_measures(n_steps_left=1)
    assert float(C.c_left_right(few)) == C.LEFT_RIGHT_UNDEFINED


def test_cot_guards():
    assert float(C.c_cot(fake_measures(energy_J=0.0))) > 0
    assert np.isfinite(float(C.c_cot(fake_measures(energy_J=0.0))))
    assert float(C.c_cot(fake_measures(distance_m=-2.0))) < 0  # backwards is not rewarded


def test_batched_measures_and_registry():
    m = fake_measures(distance_m=[10.0, 20.0, 35.0], energy_J=[1000.0, 1000.0, 2000.0])
    for name in C.CRITERIA:
        v = C.criterion(name, m, v_desired=1.3, sl_desired=0.7)
        assert v.shape in ((), (3,)), name
    np.testing.assert_allclose(C.criterion("cot", m), [0.1, 0.4, 35.0**2 / 2000.0], rtol=1e-6)


def test_weighted_sum():
    m = fake_measures()
    f = C.weighted_sum(m, {"distance": 1.0, "energy": 0.001, "angles": 2.0})
    assert float(f) == pytest.approx(30.0 - 6.0 + 1.66, rel=1e-6)


def test_criteria_consume_compute_measures_keys():
    keys = set()

    class Spy(dict):
        def __getitem__(self, k):
            keys.add(k)
            return jnp.asarray(1.0)

    for name in C.CRITERIA:
        C.criterion(name, Spy(), v_desired=1.0, sl_desired=1.0)
    assert "distance_m" in keys and "n_steps_left" in keys
    doc = M.compute_measures.__doc__
    for k in keys:
        assert f"``{k}``" in doc, k


# ----------------------------------------------------------------------------- stopping


def test_should_stop():
    s = C.StopCriteria(d_lim=35.0)
    assert not bool(C.should_stop(s, 34.9, 1e6, 1e9))
    assert bool(C.should_stop(s, 35.0, 0.0, 0.0))
    s = C.StopCriteria(t_lim=20.0, e_lim=5000.0)
    assert bool(C.should_stop(s, 0.0, 20.0, 0.0))
    assert bool(C.should_stop(s, 0.0, 0.0, 5000.0))
    assert not bool(C.should_stop(s, 1e3, 19.0, 4999.0))
    h = C.StopCriteria.human_energy(35.0)
    assert h.e_lim == pytest.approx(35.0 * 210.0) and h.d_lim == math.inf


def test_should_stop_in_scan_and_vmap():
    stop = C.StopCriteria(d_lim=1.0, t_lim=10.0)

    def run(speed):
        def body(carry, _):
            d, t, done = carry
            done = done | C.should_stop(stop, d, t, 0.0)
            d = jnp.where(done, d, d + speed * 0.1)
            t = jnp.where(done, t, t + 0.1)
            return (d, t, done), None

        (d, t, done), _ = jax.lax.scan(body, (0.0, 0.0, False), None, length=200)
        return t

    ts = jax.jit(jax.vmap(run))(jnp.array([1.0, 0.5, 0.01]))
    np.testing.assert_allclose(ts, [1.0, 2.0, 10.0], atol=0.11)
    # as a traced pytree argument, batched over limits
    batch = C.StopCriteria(d_lim=jnp.array([1.0, 2.0]), t_lim=jnp.array([5.0, 5.0]))
    axes = (C.StopCriteria(d_lim=0, t_lim=0, e_lim=None), None, None, None)
    out = jax.vmap(C.should_stop, in_axes=axes)(batch, 1.5, 0.0, 0.0)
    assert out.tolist() == [True, False]


def test_stop_criteria_validation():
    with pytest.raises(ValueError, match="d_lim"):
        C.StopCriteria(d_lim=-1.0)
    with pytest.raises(ValueError, match="e_lim"):
        C.StopCriteria(e_lim=float("nan"))
