"""Muscle-capacity study: a muscle table with stimulation headroom (``stim_max`` above 1,
jaxgait.muscles.tables.with_headroom) and the registered capacity model."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import models
from jaxgait.muscles import mtu as mu
from jaxgait.muscles.mtu import MuscleState
from jaxgait.muscles.tables import GEYER7, with_headroom


def test_with_headroom_sets_only_the_named_ceilings():
    t = with_headroom(GEYER7, {"HFL": 1.25, "SOL": 2.0}, "study")
    np.testing.assert_array_equal(t.stim_max, [1.25, 1, 1, 1, 1, 2.0, 1])
    np.testing.assert_array_equal(GEYER7.stim_max, np.ones(7))  # the source is untouched
    for k in ("f_max", "v_max", "l_opt", "l_slack", "type1", "r0", "phi_ref", "rho", "sign"):
        np.testing.assert_array_equal(getattr(t, k), getattr(GEYER7, k))
    assert t.source.endswith("; study")
    np.testing.assert_array_equal(t.tiled(2).stim_max, [1.25, 1, 1, 1, 1, 2.0, 1] * 2)


@pytest.mark.parametrize(
    "factors, match",
    [({"RF": 2.0}, "no muscles"), ({"HFL": 0.9}, ">= 1"), ({"HFL": np.nan}, ">= 1")],
)
def test_with_headroom_rejects_bad_factors(factors, match):
    with pytest.raises(ValueError, match=match):
        with_headroom(GEYER7, factors, "bad")


def test_table_rejects_a_ceiling_below_one():
    with pytest.raises(ValueError, match="stim_max"):
        dataclasses.replace(GEYER7, stim_max=np.full(7, 0.5))


@jax.jit
def _forces(stim):
    """MTU forces over 400 steps (0.2 s) at a fixed length: GEYER7 and GEYER7 with HFL's
    stimulation allowed up to 1.25."""
    strong = with_headroom(GEYER7, {"HFL": 1.25}, "x")
    l_mtu = jnp.asarray(GEYER7.l_opt + GEYER7.l_slack) * 1.02

    def run(table):
        s0 = MuscleState(act=jnp.full(7, 0.01), l_ce=jnp.asarray(GEYER7.l_opt))

        def f(s, _):
            s, info = mu.muscle_step(table, s, stim, l_mtu, 5e-4)
            return s, (info["f_mtu"], s.act)

        return jax.lax.scan(f, s0, None, length=400)[1]

    return run(GEYER7), run(strong)


def test_headroom_pulls_as_before_below_one_and_harder_above():
    s = np.array([0.6, 0.3, 0.2, 0.5, 0.4, 0.7, 0.1])
    (fb, ab), (fs, as_) = _forces(jnp.asarray(s))
    np.testing.assert_array_equal(fs, fb)  # the same program values, bit for bit
    s[0] = 1.2  # HFL asked for 1.2: the source muscle delivers activation 1, this one 1.2
    (fb, ab), (fs, as_) = _forces(jnp.asarray(s))
    assert float(ab[-1, 0]) == pytest.approx(1.0, abs=1e-5)
    assert float(as_[-1, 0]) == pytest.approx(1.2, abs=1e-5)
    assert 1.1 < float(fs[-1, 0] / fb[-1, 0]) < 1.25  # more active force, less than 1.2x
    np.testing.assert_array_equal(fs[:, 1:], fb[:, 1:])


@pytest.mark.parametrize(
    "name, ceilings",
    [("fblplus_bal_run_sr_hfl125", [1.25] + [1.0] * 6), ("fblplus_bal_run_sr_hr125", [1.25] * 7)],
)
def test_capacity_models_registered(name, ceilings):
    base = models.get_model("fblplus_bal_run_sr")
    m = models.get_model(name)
    assert m.name == name
    assert m.table is base.table  # the runner's presets load into it unchanged
    np.testing.assert_array_equal(m.muscles.f_max, base.muscles.f_max)
    np.testing.assert_array_equal(m.muscles.stim_max, ceilings)
    assert m.metabolic == base.metabolic == "thesis"
