"""jaxgait.muscles.energy against hand-computed values (thesis eq. 2.41-2.44, Wang 2012)."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait.muscles import energy as en
from jaxgait.muscles.mtu import GEYER7, WANG8


@pytest.fixture(autouse=True)
def x64():
    """Numerical checks in double precision (restored afterwards)."""
    with jax.enable_x64(True):
        yield


SOL = GEYER7.index("SOL")


def test_muscle_mass():
    m = en.muscle_mass(GEYER7)
    # SOL: 4000 / 0.25e6 * 0.04 * 1059.7 = 0.016 m^2 * 0.04 m * 1059.7 kg/m^3 = 0.678208 kg
    assert m[SOL] == pytest.approx(4000 / 0.25e6 * 0.04 * 1059.7)
    assert m[SOL] == pytest.approx(0.678208)
    # HFL: 2000 / 0.25e6 * 0.11 * 1059.7 = 0.932536 kg
    assert m[GEYER7.index("HFL")] == pytest.approx(0.932536)
    assert en.muscle_mass(WANG8).shape == (8,)


def test_rate_functions_hand_values():
    # f_A(s) = 40 t sin(pi s/2) + 133 (1 - t)(1 - cos(pi s/2)); t = 0.5:
    #   s = 0 -> 0; s = 1 -> 20 + 66.5 = 86.5
    np.testing.assert_allclose(en.activation_heat_rate(jnp.array([0.0, 1.0]), 0.5), [0.0, 86.5])
    # f_M(a) = 74 t sin(pi a/2) + 111 (1 - t)(1 - cos(pi a/2)); t = 0.5, a = 1 -> 37 + 55.5
    np.testing.assert_allclose(en.maintenance_heat_rate(jnp.array([0.0, 1.0]), 0.5), [0.0, 92.5])
    # pure slow (t = 1) at s = 0.5: 40 sin(pi/4) = 28.284271; pure fast (t = 0): 133 (1 - 0.707107)
    assert float(en.activation_heat_rate(0.5, 1.0)) == pytest.approx(40 * math.sqrt(0.5))
    assert float(en.activation_heat_rate(0.5, 0.0)) == pytest.approx(133 * (1 - math.sqrt(0.5)))
    # stimulation/activation clipped to [0, 1]
    assert float(en.activation_heat_rate(1.7, 0.5)) == pytest.approx(86.5)


def test_maintenance_length_factor():
    # eq. 2.43: 0.5 on [0, 0.5], 1 on (0.5, 1], 3 - 2 l on (1, 1.5], else 0
    l = jnp.array([-0.1, 0.0, 0.3, 0.5, 0.51, 1.0, 1.2, 1.5, 1.6])
    np.testing.assert_allclose(
        en.maintenance_length_factor(l), [0, 0.5, 0.5, 0.5, 1.0, 1.0, 0.6, 0.0, 0.0], atol=1e-12
    )


def _state(v_sol):
    """SOL: s = 0.5, a = 0.4, l_ce = 1.2 l_opt, F_ce = 2000 N, F_mtu = 2500 N."""
    z = jnp.zeros(7)
    return dict(
        stim=z.at[SOL].set(0.5),
        act=z.at[SOL].set(0.4),
        l_ce=jnp.asarray(GEYER7.l_opt).at[SOL].set(1.2 * 0.04),
        v_ce=z.at[SOL].set(v_sol),
        f_ce=z.at[SOL].set(2000.0),
        f_mtu=z.at[SOL].set(2500.0),
    )


def test_metabolic_rate_hand_values():
    # SOL, t_I = 0.7, m = 0.678208 kg, shortening at 0.1 m/s (v_ce = -0.1):
    # A = m [40*0.7 sin(pi/4) + 133*0.3 (1 - cos(pi/4))] = 0.678208 * (19.798990 + 11.686439)
    #   = 0.678208 * 31.485429 = 21.353670 W
    # M = m g(1.2) f_M(0.4)
    #   = 0.678208 * (3 - 2.4) * [74*0.7 sin(0.2 pi) + 111*0.3 (1 - cos(0.2 pi))]
    #   = 0.678208 * 0.6 * (30.447276 + 6.359734) = 0.678208 * 0.6 * 36.807010 = 14.977685 W
    # S = 0.25 * 2500 N * 0.1 m/s = 62.5 W;  W = 2000 N * 0.1 m/s = 200 W
    c = en.metabolic_components(GEYER7, **_state(-0.1))
    assert float(c["activation"][SOL]) == pytest.approx(21.3536700373)
    assert float(c["maintenance"][SOL]) == pytest.approx(14.9776852464)
    assert float(c["shortening"][SOL]) == pytest.approx(62.5)
    assert float(c["work"][SOL]) == pytest.approx(200.0)
    e = en.metabolic_rate(GEYER7, **_state(-0.1))
    assert e.shape == (7,)
    assert float(e[SOL]) == pytest.approx(21.3536700373 + 14.9776852464 + 62.5 + 200.0)
    # other muscles: s = a = 0 -> no heat; l_ce = l_opt, v = 0
    np.testing.assert_allclose(np.delete(np.asarray(e), SOL), 0.0, atol=1e-12)


def test_shortening_heat_and_work_only_while_shortening():
    for v in (0.0, 0.1, 2.0):  # isometric or lengthening
        c = en.metabolic_components(GEYER7, **_state(v))
        assert float(c["shortening"][SOL]) == 0.0
        assert float(c["work"][SOL]) == 0.0
        assert float(c["activation"][SOL]) == pytest.approx(21.3536700373)
    e_len = en.metabolic_rate(GEYER7, **_state(0.3))[SOL]
    e_sh = en.metabolic_rate(GEYER7, **_state(-0.3))[SOL]
    assert float(e_sh - e_len) == pytest.approx((0.25 * 2500 + 2000) * 0.3)


def test_metabolic_rate_broadcasts_over_legs():
    st = {k: jnp.stack([v, v]) for k, v in _state(-0.1).items()}
    e = en.metabolic_rate(GEYER7, **st)
    assert e.shape == (2, 7)
    np.testing.assert_allclose(e[0], e[1])


def test_basal_and_wang_effort():
    # basal: 1.51 W/kg * 80 kg = 120.8 W
    assert float(en.basal_rate(80.0)) == pytest.approx(120.8)
    # 4 steps, muscle power per step summed over (2, 7): 10, 20, 30, 40 -> mean 25 W
    rate = jnp.arange(1, 5, dtype=jnp.float64)[:, None, None] * jnp.full((1, 2, 7), 10.0 / 14)
    # soft-limit torques: (T, 2, 3) with one non-zero entry 2 N m at t = 1 -> mean of sum sq = 1
    lim = jnp.zeros((4, 2, 3)).at[1, 0, 2].set(2.0)
    j = en.wang_effort(rate, lim, body_mass=80.0)
    assert float(j["J_M"]) == pytest.approx(120.8 + 25.0)
    assert float(j["J_L"]) == pytest.approx(1.0)
    assert float(j["J_R"]) == 0.0
    assert float(j["J"]) == pytest.approx(100 * 145.8 + 0.5 * 1.0)
    # other torques 3 N m at every step -> J_R = 9; mask out the last two steps
    j = en.wang_effort(rate, lim, 80.0, other_torque=jnp.full((4, 1), 3.0), mask=[1, 1, 0, 0])
    assert float(j["J_M"]) == pytest.approx(120.8 + 15.0)
    assert float(j["J_L"]) == pytest.approx(2.0)
    assert float(j["J_R"]) == pytest.approx(9.0)


def test_cost_of_transport():
    # 2100 J over 10 m: 210 J/m; with 80 kg: 2.625 J/(kg m)
    assert float(en.energy_per_distance(2100.0, 10.0)) == pytest.approx(210.0)
    assert float(en.cost_of_transport(2100.0, 10.0, 80.0)) == pytest.approx(2.625)


def test_energy_from_muscle_step_info():
    """metabolic_rate takes muscle_step's info directly."""
    from jaxgait.muscles import mtu as mu

    t = GEYER7
    l_mtu = jnp.asarray(t.l_opt + t.l_slack) * 1.03
    s = mu.MuscleState(act=jnp.full(7, 0.3), l_ce=jnp.asarray(t.l_opt))
    step = jax.jit(mu.muscle_step, static_argnums=(0, 5, 6))
    _, info = step(t, s, jnp.full(7, 0.6), l_mtu, 5e-4, 1, False)
    e = en.metabolic_rate(
        t, info["stim"], info["act"], info["l_ce"], info["v_ce"], info["f_ce"], info["f_mtu"]
    )
    assert e.shape == (7,) and bool(jnp.all(e > 0))


def test_metabolic_rate_over_legs_and_time_equals_per_row():
    """(T, legs, M) inputs (merged to one muscle axis inside) give the per-row rates."""
    rng = np.random.default_rng(5)
    t = GEYER7
    shape = (3, 2, 7)
    stim, act = rng.uniform(0, 1, shape), rng.uniform(0, 1, shape)
    l_ce = np.asarray(t.l_opt) * rng.uniform(0.4, 1.6, shape)
    v_ce = rng.normal(0, 0.3, shape)
    f_ce, f_mtu = rng.uniform(0, 2000, shape), rng.uniform(0, 2000, shape)
    e = en.metabolic_rate(t, stim, act, l_ce, v_ce, f_ce, f_mtu)
    assert e.shape == shape
    for i in range(3):
        for leg in range(2):
            row = [x[i, leg] for x in (stim, act, l_ce, v_ce, f_ce, f_mtu)]
            np.testing.assert_allclose(e[i, leg], en.metabolic_rate(t, *row), rtol=1e-6)
