"""Tests of jaxgait.muscles.mtu against hand-computed values of the thesis equations (2.1-2.30)."""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxgait.muscles import mtu as mu
from jaxgait.muscles.mtu import GEYER7, MUSCLES, WANG8, MuscleState

LN005 = math.log(0.05)  # -2.995732...
DEG = math.pi / 180.0


@pytest.fixture(autouse=True)
def x64():
    """Numerical checks in double precision (restored afterwards)."""
    with jax.enable_x64(True):
        yield


def _row(table, name):
    return table.index(name)


# jitted entry points (the table, sub-steps and scheme are static)
_step = jax.jit(mu.muscle_step, static_argnums=(0, 5, 6, 7))
_init_state = jax.jit(mu.init_muscle_state, static_argnums=(0, 3))
_init_lce = jax.jit(mu.init_lce, static_argnums=0)
_velocity = jax.jit(mu.contraction_velocity, static_argnums=0)
_balance = jax.jit(mu.force_velocity_balance, static_argnums=0)
_mtu_length = jax.jit(mu.mtu_length, static_argnums=0)


# ----------------------------------------------------------------------------------------------
# tables


def test_geyer7_table_values_and_errata():
    t = GEYER7
    assert t.names == MUSCLES == ("HFL", "GLU", "HAM", "VAS", "GAS", "SOL", "TA")
    np.testing.assert_allclose(t.f_max, [2000, 1500, 3000, 6000, 1500, 4000, 800])
    np.testing.assert_allclose(t.v_max, [12, 12, 12, 12, 12, 6, 12])
    np.testing.assert_allclose(t.l_opt, [0.11, 0.11, 0.10, 0.08, 0.05, 0.04, 0.06])
    np.testing.assert_allclose(t.l_slack, [0.10, 0.13, 0.31, 0.23, 0.40, 0.26, 0.24])
    np.testing.assert_allclose(t.type1, [0.5, 0.5, 0.54, 0.44, 0.81, 0.7, 0.5])
    spans = {n: tuple(np.array(mu.JOINTS)[t.spans[i]]) for i, n in enumerate(t.names)}
    # SPEC section 8: SOL uniarticular ankle, GAS knee + ankle.
    assert spans == {
        "HFL": ("hip",),
        "GLU": ("hip",),
        "HAM": ("hip", "knee"),
        "VAS": ("knee",),
        "GAS": ("knee", "ankle"),
        "SOL": ("ankle",),
        "TA": ("ankle",),
    }
    sol, gas = _row(t, "SOL"), _row(t, "GAS")
    assert t.r0[sol, 2] == 0.05 and t.rho[sol, 2] == 0.5
    assert t.phi_max[sol, 2] == pytest.approx(110 * DEG)
    assert t.phi_ref[sol, 2] == pytest.approx(80 * DEG)
    assert t.phi_max[gas, 1] == pytest.approx(140 * DEG)
    assert t.phi_ref[gas, 1] == pytest.approx(165 * DEG)
    assert t.rho[gas, 1] == t.rho[gas, 2] == 0.7
    # hip arms constant, knee/ankle arms cosine
    assert set(t.arm[:, 0][t.spans[:, 0]]) == {1}
    assert set(t.arm[:, 1:][t.spans[:, 1:]]) == {2}
    assert (t.w, t.N, t.K, t.eps_ref, t.tau_act) == (0.56, 1.5, 5.0, 0.04, 0.01)
    assert t.c == pytest.approx(LN005)


def test_signs():
    t = GEYER7
    expected = {
        ("GLU", 0): 1,
        ("HFL", 0): -1,
        ("HAM", 0): 1,
        ("HAM", 1): -1,
        ("VAS", 1): 1,
        ("GAS", 1): -1,
        ("GAS", 2): 1,
        ("SOL", 2): 1,
        ("TA", 2): -1,
    }
    got = {
        (n, j): int(t.sign[i, j]) for i, n in enumerate(t.names) for j in range(3) if t.sign[i, j]
    }
    assert got == expected


def test_wang8_rf():
    t = WANG8
    assert t.names == MUSCLES + ("RF",)
    rf = _row(t, "RF")
    np.testing.assert_allclose(
        [t.f_max[rf], t.v_max[rf], t.l_opt[rf], t.l_slack[rf]], [1200, 12, 0.08, 0.35]
    )
    assert t.sign[rf].tolist() == [-1.0, 1.0, 0.0]  # hip flexor, knee extensor
    assert t.arm[rf].tolist() == [1, 2, 0]
    # the first seven muscles are GEYER7's
    for k in ("f_max", "v_max", "l_opt", "l_slack", "type1"):
        np.testing.assert_array_equal(getattr(t, k)[:7], getattr(GEYER7, k))
    for k in ("r0", "phi_max", "phi_ref", "rho", "sign", "arm"):
        np.testing.assert_array_equal(getattr(t, k)[:7], getattr(GEYER7, k))


def test_table_validation():
    with pytest.raises(ValueError):
        mu.MuscleTable(
            names=("A",),
            f_max=[1.0, 2.0],
            v_max=[1.0],
            l_opt=[1.0],
            l_slack=[1.0],
            type1=[0.5],
            r0=np.zeros((1, 3)),
            phi_max=np.zeros((1, 3)),
            phi_ref=np.zeros((1, 3)),
            rho=np.zeros((1, 3)),
            sign=np.zeros((1, 3)),
            arm=np.zeros((1, 3)),
        )


# ----------------------------------------------------------------------------------------------
# element characteristics


def test_f_l_hand_values():
    # eq. 2.4: f_l = exp(ln0.05 * |(l - 1)/0.56|^3)
    # l = 1.28: |0.28/0.56|^3 = 0.5^3 = 0.125 -> exp(-2.995732 * 0.125) = exp(-0.374467) = 0.687656
    # l = 0.72: same distance below -> 0.687656; l = 1 -> 1; l = 0.44, 1.56 (= 1 -+ w) -> 0.05
    got = mu.f_l(jnp.array([1.0, 1.28, 0.72, 0.44, 1.56]))
    np.testing.assert_allclose(got, [1.0, 0.6876560219, 0.6876560219, 0.05, 0.05], rtol=1e-9)


def test_f_v_hand_values():
    # concentric: (1 + v)/(1 - 5 v): v = -0.5 -> 0.5 / 3.5 = 0.142857; v = -1 -> 0
    # eccentric: 1.5 + 0.5 (v - 1)/(37.8 v + 1): v = 0 -> 1.5 - 0.5 = 1;
    #   v = 0.5 -> 1.5 - 0.25 / 19.9 = 1.487437; v = 1 -> 1.5
    got = mu.f_v(jnp.array([-1.0, -0.5, 0.0, 0.5, 1.0]))
    np.testing.assert_allclose(got, [0.0, 0.5 / 3.5, 1.0, 1.5 - 0.25 / 19.9, 1.5], rtol=1e-12)
    # fast lengthening: f_v -> N + (N - 1)/(7.56 K) = 1.5 + 0.5/37.8 = 1.513228 ~ N
    assert float(mu.f_v(1e6)) == pytest.approx(1.5 + 0.5 / 37.8, rel=1e-5)
    assert abs(float(mu.f_v(3.0)) - 1.5) < 0.02


def test_f_v_increasing_and_continuous():
    v = jnp.linspace(-1.0, 5.0, 6001)
    f = mu.f_v(v)
    assert np.all(np.diff(np.asarray(f)) > 0)
    # continuity at v = 0 from both sides
    assert float(mu.f_v(-1e-9)) == pytest.approx(1.0, abs=1e-7)
    assert float(mu.f_v(1e-9)) == pytest.approx(1.0, abs=1e-7)


def test_v_from_fv_hand_values():
    # fv <= 1: (fv - 1)/(5 fv + 1): 0.5 -> -0.5/3.5 = -0.142857; 0 -> -1; 1 -> 0
    # 1 < fv <= 1.5: x = (fv - 1.5)/0.5, v = (x + 1)/(1 - 37.8 x):
    #   fv = 1.25 -> x = -0.5 -> 0.5 / 19.9 = 0.0251256; fv = 1.5 -> 1
    # fv > 1.5: 0.01 (fv - 1.5) + 1: fv = 2 -> 1.005; fv = 101.5 -> 2
    got = mu.v_from_fv(jnp.array([0.0, 0.5, 1.0, 1.25, 1.5, 2.0, 101.5]))
    np.testing.assert_allclose(
        got, [-1.0, -0.5 / 3.5, 0.0, 0.5 / 19.9, 1.0, 1.005, 2.0], rtol=1e-12
    )
    # finite gradient everywhere, including at the branch points
    g = jax.vmap(jax.grad(mu.v_from_fv))(jnp.array([0.0, 1.0, 1.5, 1.513, 5.0]))
    assert np.all(np.isfinite(g))


_v_roundtrip = jax.jit(lambda v: mu.v_from_fv(mu.f_v(v)))
_f_roundtrip = jax.jit(lambda f: mu.f_v(mu.v_from_fv(f)))


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=-1.0, max_value=1.0, allow_nan=False))
def test_roundtrip_v(v):
    """v_from_fv(f_v(v)) = v on v_n in [-1, 1] (f_v maps it onto [0, N])."""
    with jax.enable_x64(True):
        back = float(_v_roundtrip(jnp.float64(v)))
    assert back == pytest.approx(v, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=0.0, max_value=1.5, allow_nan=False))
def test_roundtrip_f(f):
    """f_v(v_from_fv(f)) = f on f in [0, N]."""
    with jax.enable_x64(True):
        back = float(_f_roundtrip(jnp.float64(f)))
    assert back == pytest.approx(f, abs=1e-10)


def test_f_se_hand_values():
    # eq. 2.9: ((l_se/l_slack - 1)/0.04)^2; l_slack = 0.26 (SOL)
    # l_se = 1.02 l_slack: (0.02/0.04)^2 = 0.25; 1.04 l_slack: 1; slack (<= l_slack): 0
    ls = 0.26
    got = mu.f_se(jnp.array([0.9, 1.0, 1.02, 1.04]) * ls, ls, 0.04)
    np.testing.assert_allclose(got, [0.0, 0.0, 0.25, 1.0], atol=1e-12)


def test_f_pe_star_and_f_be_hand_values():
    # eq. 2.12: ((l - 1)/0.56)^2 for l > 1: l = 1.28 -> 0.5^2 = 0.25; l = 1.56 -> 1; l <= 1 -> 0
    np.testing.assert_allclose(mu.f_pe_star(jnp.array([0.9, 1.0, 1.28, 1.56])), [0, 0, 0.25, 1.0])
    # eq. 2.11 (erratum): ((l - 0.44)/0.28)^2 for l < 0.44: l = 0.3 -> (-0.14/0.28)^2 = 0.25;
    # l = 0.16 -> 1; l >= 0.44 -> 0
    np.testing.assert_allclose(
        mu.f_be(jnp.array([0.16, 0.3, 0.44, 0.5, 1.0])), [1.0, 0.25, 0, 0, 0], atol=1e-12
    )


# ----------------------------------------------------------------------------------------------
# geometry


@pytest.mark.parametrize("table", [GEYER7, WANG8], ids=["GEYER7", "WANG8"])
def test_lmtu_at_phi_ref(table):
    for i in range(table.n):
        phi = jnp.asarray(table.phi_ref[i])  # joints not spanned are ignored
        lm = mu.mtu_length(table, phi)
        assert float(lm[i]) == pytest.approx(table.l_opt[i] + table.l_slack[i], abs=1e-12)


def test_lmtu_hand_values():
    t = GEYER7
    # SOL at ankle 90 deg: dL = 0.5*0.05*[sin(80-110) - sin(90-110)] = 0.025*(-0.5 + 0.342020)
    #   = -0.0039495 -> l_mtu = 0.04 + 0.26 - 0.0039495 = 0.2960505
    # HFL at hip 170 deg: dL = +0.5*0.1*(170-180)deg = 0.05*(-0.174533) = -0.0087266
    #   -> l_mtu = 0.11 + 0.10 - 0.0087266 = 0.2012734 (flexing the hip shortens HFL)
    # TA at ankle 90 deg: dL = -0.7*0.04*[sin(30) - sin(10)] = -0.028*(0.5 - 0.173648)
    #   = -0.0091379 -> l_mtu = 0.06 + 0.24 - 0.0091379 = 0.2908621
    phi = jnp.array([170 * DEG, 180 * DEG, 90 * DEG])
    lm = mu.mtu_length(t, phi)
    assert float(lm[_row(t, "SOL")]) == pytest.approx(0.30 - 0.025 * (0.5 - math.sin(20 * DEG)))
    assert float(lm[_row(t, "HFL")]) == pytest.approx(0.21 - 0.05 * 10 * DEG)
    assert float(lm[_row(t, "TA")]) == pytest.approx(0.30 - 0.028 * (0.5 - math.sin(10 * DEG)))


@pytest.mark.parametrize("table", [GEYER7, WANG8], ids=["GEYER7", "WANG8"])
def test_moment_arms_match_length_gradient(table):
    """arm[m, j] = -(1/rho) d(dL_m)/d(phi_j) for every muscle-joint pair."""
    rng = np.random.default_rng(0)
    phi = jnp.asarray(rng.uniform([140, 120, 70], [200, 180, 120], size=(8, 3)) * DEG)
    jac = jax.jit(jax.vmap(jax.jacfwd(lambda p: mu.mtu_length(table, p))))(phi)  # (8, M, 3)
    arms = mu.moment_arms(table, phi)
    rho = np.where(table.spans, table.rho, 1.0)
    np.testing.assert_allclose(arms, -jac / rho, atol=1e-12)
    assert np.all(np.asarray(arms)[:, ~table.spans] == 0.0)


def test_joint_torque_directions_and_values():
    t = GEYER7
    phi = jnp.array([170 * DEG, 165 * DEG, 110 * DEG])
    for name, sign in [("GLU", (1, 0, 0)), ("HFL", (-1, 0, 0)), ("HAM", (1, -1, 0)),
                       ("VAS", (0, 1, 0)), ("GAS", (0, -1, 1)), ("SOL", (0, 0, 1)),
                       ("TA", (0, 0, -1))]:  # fmt: skip
        f = jnp.zeros(7).at[_row(t, name)].set(1000.0)
        tau = np.asarray(mu.joint_torques(t, phi, f))
        assert np.array_equal(np.sign(np.round(tau, 9)), sign), name
    # VAS at its phi_max (165 deg): tau = 0.06 * cos(0) * 1000 = 60 N m
    f = jnp.zeros(7).at[_row(t, "VAS")].set(1000.0)
    assert float(mu.joint_torques(t, phi, f)[1]) == pytest.approx(60.0)
    # SOL at ankle 110 deg = phi_max: +0.05 * 1000 = 50; GLU at hip: +0.1 * 1000 = 100
    f = jnp.zeros(7).at[_row(t, "SOL")].set(1000.0).at[_row(t, "GLU")].set(1000.0)
    np.testing.assert_allclose(mu.joint_torques(t, phi, f), [100.0, 0.0, 50.0], atol=1e-12)


def test_geometry_broadcasts():
    t = GEYER7
    phi = jnp.broadcast_to(jnp.array([175.0, 170.0, 90.0]) * DEG, (5, 2, 3))
    assert mu.mtu_length(t, phi).shape == (5, 2, 7)
    assert mu.moment_arms(t, phi).shape == (5, 2, 7, 3)
    assert mu.joint_torques(t, phi, jnp.ones((5, 2, 7))).shape == (5, 2, 3)
    lm1 = mu.mtu_length(t, phi[0, 0])
    np.testing.assert_allclose(mu.mtu_length(t, phi)[3, 1], lm1)


# ----------------------------------------------------------------------------------------------
# force balance, initialisation


def test_mtu_force_and_velocity_hand_values():
    t = GEYER7
    i = _row(t, "SOL")
    l_opt, l_slack = 0.04, 0.26
    # tendon at 2 % strain: f_se = (0.02/0.04)^2 = 0.25 -> F_mtu = 0.25 * 4000 = 1000 N
    l_ce = jnp.full(7, 1.0) * jnp.asarray(t.l_opt)
    l_mtu = l_ce + jnp.asarray(t.l_slack) * 1.02
    f = mu.mtu_force(t, 1.0, l_ce, l_mtu)
    assert float(f[i]) == pytest.approx(1000.0)
    # A = 1, l_ce = l_opt: f_v = 0.25 / (1 * 1 + 0) = 0.25 -> v_n = -0.75 / 2.25 = -1/3
    #   -> v_ce = -1/3 * 6 * 0.04 = -0.08 m/s
    v = mu.contraction_velocity(t, 1.0, l_ce, l_mtu)
    assert float(v[i]) == pytest.approx(-0.08)
    # A = 0.5: f_v = 0.5 -> v_n = -0.5/3.5 -> v_ce = -0.142857 * 0.24 = -0.0342857 m/s
    v = mu.contraction_velocity(t, 0.5, l_ce, l_mtu)
    assert float(v[i]) == pytest.approx(-0.5 / 3.5 * 6 * l_opt)
    # A = 0 is treated as 0.01: f_v = 0.25 / 0.01 = 25 -> v_n = 0.01 * 23.5 + 1 = 1.235
    v = mu.contraction_velocity(t, 0.0, l_ce, l_mtu)
    assert float(v[i]) == pytest.approx(1.235 * 6 * l_opt)
    assert l_slack == t.l_slack[i]


def test_init_lce_slack_and_taut():
    t = GEYER7
    rest = jnp.asarray(t.l_opt + t.l_slack)
    # slack (eq. 2.25): l_ce = l_opt
    np.testing.assert_allclose(mu.init_lce(t, rest * 0.97), t.l_opt, rtol=1e-12)
    np.testing.assert_allclose(mu.init_lce(t, rest), t.l_opt, rtol=1e-12)
    # taut (eq. 2.29-2.30): F_pe = F_se with f_v = 1
    for frac in (1.001, 1.02, 1.08):
        l_mtu = rest * frac
        l_ce = mu.init_lce(t, l_mtu)
        assert np.all(np.asarray(l_ce) > t.l_opt)
        fpe = mu.f_pe_star(l_ce / t.l_opt)
        fse = mu.f_se(l_mtu - l_ce, t.l_slack)
        np.testing.assert_allclose(fpe, fse, rtol=1e-10)
        assert np.all(np.asarray(fse) > 0)
    # hand value, SOL with l_mtu = 0.31 (1 cm over rest):
    # l_se = 0.26 (0.04*0.56 + 0.04 (0.31 - 0.04)) / (0.04*0.56 + 0.04*0.26)
    #      = 0.26 * 0.0332 / 0.0328 = 0.2631707 -> l_ce = 0.31 - 0.2631707 = 0.0468293
    l_mtu = rest.at[_row(t, "SOL")].set(0.31)
    assert float(mu.init_lce(t, l_mtu)[_row(t, "SOL")]) == pytest.approx(
        0.31 - 0.26 * 0.0332 / 0.0328
    )


def test_init_lce_with_activation_is_at_rest():
    t = GEYER7
    rest = jnp.asarray(t.l_opt + t.l_slack)
    for frac in (0.95, 1.0, 1.04):
        for act in (0.01, 0.2, 1.0):
            l_mtu = rest * frac
            l_ce = _init_lce(t, l_mtu, act)
            v = mu.contraction_velocity(t, act, l_ce, l_mtu)
            assert np.all(np.abs(np.asarray(v) / (t.v_max * t.l_opt)) < 1e-8), (frac, act)
    # A -> small and taut tendon: close to the thesis closed form (A = 0)
    l_mtu = rest * 1.05
    np.testing.assert_allclose(_init_lce(t, l_mtu, 1e-12), mu.init_lce(t, l_mtu), rtol=2e-3)
    s = _init_state(t, jnp.broadcast_to(rest, (2, 7)))
    assert s.act.shape == s.l_ce.shape == (2, 7)


# ----------------------------------------------------------------------------------------------
# muscle_step


@functools.partial(jax.jit, static_argnums=(0, 5, 7, 8))
def _hold(table, stim, l_mtu, l_ce0, act0, n, dt=5e-4, implicit=True, substeps=1):
    """n steps at fixed l_mtu and stim; returns the final state and v_ce per step."""

    def f(s, _):
        s, info = mu.muscle_step(table, s, stim, l_mtu, dt, substeps, implicit)
        return s, info["v_ce"]

    s0 = MuscleState(act=jnp.full_like(l_ce0, act0), l_ce=l_ce0)
    return jax.lax.scan(f, s0, None, length=n)


def test_activation_update_and_stim_clip():
    t = GEYER7
    l_mtu = jnp.asarray(t.l_opt + t.l_slack)
    s = MuscleState(act=jnp.full(7, 0.2), l_ce=jnp.asarray(t.l_opt))
    stim = jnp.array([0.5, 2.0, -1.0, 0.0, 1.0, 0.01, 0.3])
    s1, info = _step(t, s, stim, l_mtu, 0.002)
    # exact first-order step: A1 = S + (A0 - S) exp(-dt/tau), S clipped to [0.01, 1]
    # e.g. S = 0.5: 0.5 + (0.2 - 0.5) exp(-0.2) = 0.5 - 0.3 * 0.818731 = 0.254381
    sc = np.clip(np.asarray(stim), 0.01, 1.0)
    np.testing.assert_allclose(info["stim"], sc)
    np.testing.assert_allclose(s1.act, sc + (0.2 - sc) * math.exp(-0.2), rtol=1e-12)
    assert float(s1.act[0]) == pytest.approx(0.254381, abs=1e-6)
    # info at the start of the step
    np.testing.assert_allclose(info["act"], 0.2)
    np.testing.assert_allclose(info["f_mtu"], mu.mtu_force(t, s.act, s.l_ce, l_mtu), atol=1e-9)


@pytest.mark.parametrize("implicit", [True, False])
def test_converges_to_equilibrium_typical(implicit):
    """Fixed l_mtu and stim at dt = 0.5 ms, one sub-step: l_ce settles at the balance."""
    t = GEYER7
    rest = jnp.asarray(t.l_opt + t.l_slack)
    for frac, stim in [(1.02, 0.05), (1.04, 0.3), (0.98, 0.6), (1.06, 1.0)]:
        l_mtu = rest * frac
        s, v = _hold(t, jnp.full(7, stim), l_mtu, mu.init_lce(t, l_mtu), 0.01, 2000, 5e-4, implicit)
        v_n = np.asarray(v) / (t.v_max * t.l_opt)
        assert np.all(np.isfinite(v_n))
        # settled: the last 0.2 s shows no oscillation and tiny velocity
        assert np.all(np.abs(v_n[-400:]) < 2e-3), (frac, stim, np.abs(v_n[-400:]).max(0))
        assert np.all(np.abs(np.diff(np.sign(np.round(v_n[-400:], 6)), axis=0)).sum(0) <= 2)
        eq = _init_lce(t, l_mtu, stim)
        np.testing.assert_allclose(s.l_ce / t.l_opt, eq / t.l_opt, atol=2e-3)


def test_implicit_stable_where_explicit_chatters():
    """Minimum activation with the tendon at slack length: the balance is stiff
    (A f_l ~ 0.01); explicit Euler at 0.5 ms chatters at +-v_max for HFL/GLU, backward Euler
    settles."""
    t = GEYER7
    l_mtu = jnp.asarray(t.l_opt + t.l_slack)
    stim = jnp.full(7, 0.01)
    _, v = _hold(t, stim, l_mtu, mu.init_lce(t, l_mtu), 0.01, 2000, 5e-4, True)
    v_n = np.asarray(v) / (t.v_max * t.l_opt)
    assert np.all(np.abs(v_n[-200:]) < 1e-6)
    _, v = _hold(t, stim, l_mtu, mu.init_lce(t, l_mtu), 0.01, 2000, 5e-4, False)
    v_n = np.asarray(v) / (t.v_max * t.l_opt)
    assert np.abs(v_n[-200:, _row(t, "HFL")]).max() > 0.5  # documents the explicit limit


_be_reference = jax.jit(mu.backward_euler_velocity, static_argnums=(0, 5))


def _v_n_of_step(table, state, l_mtu, dt, solve_iters=None):
    args = () if solve_iters is None else (1, True, solve_iters)
    _, info = _step(table, state, state.act, l_mtu, dt, *args)
    return np.asarray(info["v_ce"]) / (table.v_max * table.l_opt)


def test_implicit_step_root_on_the_line_branch():
    """A soleus state from a walking rollout (low activation, CE at 0.53 l_opt, fast
    lengthening): the root lies just beyond v_n = 1, on eq. 2.16's third branch, which the
    solver intersects as a line (taking the Moebius piece there left the step at v_n = 0)."""
    t = GEYER7
    i = _row(t, "SOL")
    act = np.full(7, 0.1)
    act[i] = 0.14744776
    l_ce = np.array(t.l_opt, float)
    l_ce[i] *= 0.52915318
    l_mtu = np.array(t.l_opt + t.l_slack, float)
    l_mtu[i] = 0.2834329
    s = MuscleState(act=jnp.asarray(act), l_ce=jnp.asarray(l_ce))
    ref = np.asarray(_be_reference(t, s.act, s.l_ce, jnp.asarray(l_mtu), 5e-4, 200))
    assert 1.0 < ref[i] < 1.01
    v = _v_n_of_step(t, s, jnp.asarray(l_mtu), 5e-4)  # default iterations
    assert v[i] == pytest.approx(ref[i], abs=1e-8)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-2.0, 0.0), min_size=7, max_size=7),
    st.lists(st.floats(0.4, 1.7), min_size=7, max_size=7),
    st.lists(st.floats(0.8, 1.2), min_size=7, max_size=7),
)
def test_implicit_step_converges_to_the_backward_euler_root(log_act, l_norm, mtu_ratio):
    """Any state (A in [0.01, 1], l_ce in [0.4, 1.7] l_opt, l_mtu within 20 % of
    l_opt + l_slack): the step stays in the bracket between 0 and the explicit step, and
    the solver's iterations converge to the bisection root."""
    t = GEYER7
    s = MuscleState(
        act=jnp.asarray(10.0 ** np.array(log_act)), l_ce=jnp.asarray(np.array(l_norm) * t.l_opt)
    )
    l_mtu = jnp.asarray(np.array(mtu_ratio) * (t.l_opt + t.l_slack))
    v_e = np.asarray(_velocity(t, s.act, s.l_ce, l_mtu)) / (t.v_max * t.l_opt)
    v = _v_n_of_step(t, s, l_mtu, 5e-4)
    assert np.all(v * np.sign(v_e) >= 0.0) and np.all(np.abs(v) <= np.abs(v_e) * (1 + 1e-12))
    ref = np.asarray(_be_reference(t, s.act, s.l_ce, l_mtu, 5e-4, 200))
    err = np.abs(_v_n_of_step(t, s, l_mtu, 5e-4, solve_iters=12) - ref) * 5e-4 * t.v_max
    assert err.max() < 1e-10  # [l_opt]


@functools.lru_cache(maxsize=1)
def _gait_inputs_cached():
    """0.6 s of gait-like joint motion and stimulation sampled at 0.5 ms (float64)."""
    n, dt = 1200, 5e-4
    t = np.arange(n) * dt
    w = 2 * np.pi / 1.1
    phi = np.stack(
        [165 + 20 * np.sin(w * t), 160 + 25 * np.sin(w * t + 1.0), 90 + 12 * np.sin(w * t + 2.0)],
        -1,
    )
    with jax.enable_x64(True):
        lm = _mtu_length(GEYER7, jnp.asarray(phi * DEG))
    stim = 0.01 + 0.99 * np.clip(np.sin(w * t[:, None] + np.arange(7)[None] * 0.9), 0, 1) ** 3
    return np.asarray(stim), np.asarray(lm)


def _gait_inputs(n):
    stim, lm = _gait_inputs_cached()
    return jnp.asarray(stim[:n]), jnp.asarray(lm[:n])


@functools.partial(jax.jit, static_argnums=(3, 4))
def _rollout(stim, lm, dt, substeps, implicit=True):
    t = GEYER7

    def f(s, x):
        s, info = mu.muscle_step(t, s, x[0], x[1], dt, substeps, implicit)
        return s, (s.l_ce, info["f_mtu"], info["v_ce"])

    s0 = mu.init_muscle_state(t, lm[0])
    return jax.lax.scan(f, s0, (stim, lm))[1]


def test_substeps_agree():
    """Gait-like joint motion and stimulation, 0.6 s: dt = 0.5 ms with one and four sub-steps."""
    dt = 5e-4
    stim, lm = _gait_inputs(1200)
    l1, f1, _ = _rollout(stim, lm, dt, 1)
    l4, f4, _ = _rollout(stim, lm, dt, 4)
    t = GEYER7
    assert np.abs(np.asarray(l1 - l4)).max(0).max() / t.l_opt.min() < 5e-3
    assert np.all(np.abs(np.asarray(f1 - f4)).max(0) / t.f_max < 0.02)


def test_step_info_consistent_and_batched():
    t = GEYER7
    dt = 5e-4
    stim, lm = _gait_inputs(3)
    lm2 = jnp.stack([lm[1], lm[2] * 1.01])  # (2, 7): two legs
    s = _init_state(t, lm2, 0.1)
    s1, info = _step(t, s, jnp.stack([stim[1], stim[2]]), lm2, dt)
    assert s1.act.shape == s1.l_ce.shape == info["f_mtu"].shape == (2, 7)
    # v_ce is the velocity of the (backward-Euler) step; f_ce the active force at its end point
    np.testing.assert_allclose(info["v_ce"], (s1.l_ce - s.l_ce) / dt, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(
        info["v_ce"], _velocity(t, s.act, s1.l_ce, lm2), rtol=1e-6, atol=1e-9
    )
    # balance at the end point: F_ce = F_se + F_be - F_pe
    fv, a_fl = _balance(t, s.act, s1.l_ce, lm2)
    np.testing.assert_allclose(info["f_ce"], t.f_max * a_fl * fv)
    # legs are independent: leg 1 alone gives the same step
    s_leg = MuscleState(act=s.act[1], l_ce=s.l_ce[1])
    s_leg1, _ = _step(t, s_leg, stim[2], lm2[1], dt)
    np.testing.assert_allclose(s_leg1.l_ce, s1.l_ce[1], rtol=1e-12)


def test_step_over_batch_and_legs_equals_per_row():
    """(B, legs, M) states (legs and muscles merged to one axis inside) step row by row."""
    t = GEYER7
    stim, lm = _gait_inputs(6)
    lm3 = jnp.stack([lm[0:2], lm[2:4] * 1.01, lm[4:6] * 0.99])  # (3, 2, 7)
    st3 = jnp.stack([stim[0:2], stim[2:4], stim[4:6]])
    s = _init_state(t, lm3, 0.1)
    s1, info = _step(t, s, st3, lm3, 5e-4)
    assert s1.l_ce.shape == info["f_ce"].shape == (3, 2, 7)
    for b in range(3):
        for leg in range(2):
            sb = MuscleState(act=s.act[b, leg], l_ce=s.l_ce[b, leg])
            r1, rinfo = _step(t, sb, st3[b, leg], lm3[b, leg], 5e-4)
            np.testing.assert_allclose(s1.l_ce[b, leg], r1.l_ce, rtol=1e-12)
            np.testing.assert_allclose(info["f_ce"][b, leg], rinfo["f_ce"], rtol=1e-12)


def test_step_gradient_matches_finite_differences():
    """d(sum F_mtu)/d(stim gain) through 0.1 s of implicit steps (implicit-function-theorem
    derivative of the CE solve) against central differences."""
    t = GEYER7
    stim, lm = _gait_inputs(200)

    @jax.jit
    @jax.value_and_grad
    def loss(gain):
        def f(s, x):
            s, info = mu.muscle_step(t, s, gain * x[0], x[1], 5e-4)
            return s, info["f_mtu"]

        s0 = mu.init_muscle_state(t, lm[0])
        return jnp.sum(jax.lax.scan(f, s0, (stim, lm))[1]) * 1e-4

    val, g = loss(0.8)
    eps = 1e-5
    fd = (loss(0.8 + eps)[0] - loss(0.8 - eps)[0]) / (2 * eps)
    assert np.isfinite(float(val)) and float(g) > 0
    assert float(g) == pytest.approx(float(fd), rel=1e-3)


def test_step_keeps_float32():
    t = GEYER7
    with jax.enable_x64(False):
        x = jnp.ones((2, 7), jnp.float32)
        s = MuscleState(act=0.1 * x, l_ce=x * jnp.asarray(t.l_opt, jnp.float32))
        out = jax.eval_shape(lambda s: mu.muscle_step(t, s, 0.2 * x, 3.0 * s.l_ce, 5e-4), s)
        assert {leaf.dtype for leaf in jax.tree.leaves(out)} == {jnp.dtype(jnp.float32)}
        # the eight-muscle table goes through the same code
        x8 = jnp.ones((2, 8), jnp.float32)
        s8 = MuscleState(act=0.1 * x8, l_ce=x8 * jnp.asarray(WANG8.l_opt, jnp.float32))
        out = jax.eval_shape(lambda s: mu.muscle_step(WANG8, s, 0.2 * x8, 3.0 * s.l_ce, 5e-4), s8)
        assert out[0].l_ce.shape == out[1]["f_ce"].shape == (2, 8)


def test_init_lce_gradient():
    """d l_ce / d l_mtu of the exact resting equilibrium against central differences."""
    t = GEYER7
    l_mtu = jnp.asarray(t.l_opt + t.l_slack) * 1.02
    jac = jax.jit(jax.jacfwd(lambda x: mu.init_lce(t, x, 0.3)))(l_mtu)
    eps = 1e-7
    fd = (_init_lce(t, l_mtu + eps, 0.3) - _init_lce(t, l_mtu - eps, 0.3)) / (2 * eps)
    np.testing.assert_allclose(np.diag(np.asarray(jac)), fd, rtol=1e-5)
    assert np.allclose(np.asarray(jac) - np.diag(np.diag(np.asarray(jac))), 0.0)
    assert np.all((fd > 0) & (fd < 1))
