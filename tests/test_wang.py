"""Wang et al. 2012: the 8-muscle leg, its controller (sections 4.1-4.3) and effort (5, 5.1)."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import models, sim
from jaxgait.body.joints import q_to_phi
from jaxgait.control import wang as w
from jaxgait.control.fbl import FBL
from jaxgait.control.interface import Sensors
from jaxgait.control.wang_params import (
    INITIAL_SPECS,
    RUN_RANGES,
    STANCE_SPECS,
    SWING_SPECS,
    WANG,
    WANG_RUN,
    WANG_RUN_LD,
)
from jaxgait.core.params import widened
from jaxgait.muscles import effort as ef
from jaxgait.muscles import energy as en
from jaxgait.muscles import mtu
from jaxgait.world import envs

HFL, GLU, HAM, VAS, GAS, SOL, TA, RF = range(8)
P0 = {k: float(v) for k, v in WANG.unpack(np.asarray(WANG.init)).items()}


def _p(**kw):
    return {k: jnp.asarray(v, jnp.float32) for k, v in {**P0, **kw}.items()}


def _row(**kw):
    """One sensor row (1, N_SENSORS): neutral values, then ``F``/``L`` (8,) and W_* columns."""
    s = np.zeros(w.N_SENSORS)
    s[w.W_F] = kw.pop("F", np.zeros(8))
    s[w.W_L] = kw.pop("L", np.ones(8))
    for k, v in kw.items():
        s[getattr(w, "W_" + k.upper())] = v
    return jnp.asarray(s[None], jnp.float32)


# ------------------------------------------------------------------ table and model
def test_table_has_wangs_56_law_parameters_plus_balance_and_initial_state():
    assert (len(STANCE_SPECS), len(SWING_SPECS), WANG.size) == (30, 26, 66)
    assert all(s.source for s in WANG.specs) and len(INITIAL_SPECS) == 8
    # gains with a Geyer-Herr counterpart start from the same values as FBL's table
    fbl = dict(zip(FBL.names, FBL.init, strict=True))
    pairs = {
        "GF_SOL": "G_SOL",
        "GF_GAS": "G_GAS",
        "GF_VAS": "G_VAS",
        "GF_SOL_TA": "G_TA_SOL",
        "GL_TA": "G_TA",
        "HL_TA": "loff_TA",
        "GL_HFL_sw": "G_HFL",
        "HL_HFL_sw": "loff_HFL",
        "GL_HAM_sw": "G_HAM_HFL",
        "HL_HAM_sw": "loff_HAM",
        "k_lean": "k_lean",
        "K_HAM": "k_p1",
        "K_GLU": "k_p2",
        "D_HAM": "k_d",
        "th_HFL": "theta_ref",
        "p_VAS": "S0_VAS",
        "p_HAM": "S0_HAM",
        "s_GLU": "delta_S",
        "k_knee": "k_phi",
    }
    for ours, theirs in pairs.items():
        assert P0[ours] == pytest.approx(fbl[theirs], rel=1e-3), ours
    assert P0["th_knee_off"] == pytest.approx(np.pi - fbl["phi_k_off"], abs=1e-4)


def test_models_take_the_muscle_table_of_their_controller():
    model = models.get_model("wang8")
    assert model.muscles is mtu.WANG8 and model.controller.n_muscles == 8
    assert models.get_model("fbl").muscles is mtu.GEYER7
    assert models.get_model("fblplus").muscles is mtu.GEYER7
    assert model.leg_length == pytest.approx(1.0) and model.table is WANG


def test_rf_flexes_the_hip_and_extends_the_knee_in_the_joint_geometry():
    model = models.get_model("wang8")
    body, rf = model.body, mtu.WANG8.index("RF")
    thigh, shank, foot = (body.mj_model.body(n).id for n in ("thigh_r", "shank_r", "foot_r"))
    frames = jax.jit(body.frames)
    length = jax.jit(jax.grad(lambda q: mtu.mtu_length(mtu.WANG8, q_to_phi(q))[rf]))
    for q_leg in ([0.3, 0.4, 0.0], [-0.1, 0.05, 0.1], [0.8, 1.2, -0.2]):  # Winter hip, knee, ankle
        q_leg = jnp.asarray(q_leg)
        f = jnp.zeros(8).at[rf].set(1000.0)
        tau_q = -np.asarray(mtu.joint_torques(mtu.WANG8, q_to_phi(q_leg), f))  # as the simulator
        assert tau_q[0] > 0 and tau_q[1] < 0 and tau_q[2] == 0  # hip flexion, knee extension
        # the MTU shortens in the directions it pulls (positive work)
        dl = np.asarray(length(q_leg))
        assert dl[0] < 0 and dl[1] > 0 and dl[2] == 0
        # and in the MJCF, +q_hip swings the thigh forward (flexion), +q_knee swings the shank
        # backward relative to the thigh (flexion): RF's torques extend the knee, flex the hip
        qpos = jnp.zeros(9).at[3:6].set(q_leg)

        def alpha(q, a, b):
            return float(_forward_angle(frames(q)[0], a, b))

        hip_up = alpha(qpos.at[3].add(1e-3), thigh, shank) - alpha(qpos, thigh, shank)
        knee_up = alpha(qpos.at[4].add(1e-3), shank, foot) - alpha(qpos, shank, foot)
        assert hip_up > 0 and knee_up < 0  # (the thigh does not move with q_knee)


def _forward_angle(origins, a, b):
    """Angle [rad] of the segment from body a's origin to body b's from the downward
    vertical, forward (+x) positive."""
    v = origins[b] - origins[a]
    return jnp.arctan2(v[0], -v[1])


# ------------------------------------------------------------------ building blocks
def test_force_and_length_feedback_by_hand():
    assert float(w.force_feedback(1.2, 0.5)) == pytest.approx(0.6)
    assert float(w.length_feedback(1.1, 0.8, 0.72)) == pytest.approx(0.088)
    assert float(w.length_feedback(1.1, 0.7, 0.72)) == 0.0


def test_pd_sign_rule_for_extensors_and_flexors():
    assert w.PD_SIGN_HIP.tolist() == [-1, 1, 1, 0, 0, 0, 0, -1]  # HFL, RF flex; GLU, HAM extend
    assert w.PD_SIGN_KNEE.tolist() == [0, 0, -1, 1, -1, 0, 0, 1]  # VAS, RF extend the knee
    # x = K (th - th_m) + D dth = 2 (0.3 - 0.1) + 0.5 * 0.2 = 0.5
    assert float(w.pd_feedback(2.0, 0.5, 0.3, 0.2, 0.1, +1)) == pytest.approx(0.5)  # extensor
    assert float(w.pd_feedback(2.0, 0.5, 0.3, 0.2, 0.1, -1)) == 0.0  # flexor silent
    # x = 2 (0 - 0.1) + 0.5 (-0.2) = -0.3: the flexor pulls with |x|, the extensor is silent
    assert float(w.pd_feedback(2.0, 0.5, 0.0, -0.2, 0.1, -1)) == pytest.approx(0.3)
    assert float(w.pd_feedback(2.0, 0.5, 0.0, -0.2, 0.1, +1)) == 0.0
    assert float(w.pd_feedback(2.0, 0.5, 0.0, -0.2, 0.1, 0)) == 0.0


def test_knee_overextension_and_balance_target_by_hand():
    assert float(w.knee_overextension(2.0, 0.1, -1.0, 0.1745)) == pytest.approx(-0.149)
    assert float(w.knee_overextension(2.0, 0.1, +1.0, 0.1745)) == 0.0  # flexing again
    assert float(w.knee_overextension(2.0, 0.3, -1.0, 0.1745)) == 0.0  # bent past the offset
    assert float(w.balance_target(0.4, 0.5, 0.2, 0.2, 1.3)) == pytest.approx(0.4 + 0.1 + 0.26)


def test_delay_groups_follow_section_4_1():
    # 5 ms: muscles on the hip (HFL, GLU, HAM, RF); 10 ms: VAS; 20 ms: on the ankle
    assert w.MUSCLE_DELAY_GROUP.tolist() == [0, 0, 0, 1, 2, 2, 2, 0]


# ------------------------------------------------------------------ laws by hand
_F = [0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.1, 0.25]
_L = [0.9, 1.1, 1.0, 0.95, 1.0, 1.05, 0.8, 1.0]


def test_stance_laws_by_hand():
    s = _row(F=_F, L=_L, trunk=0.2, dtrunk=0.5, knee=0.1, dknee=-1.0)
    u = np.asarray(w.stance_excitation(_p(), s, jnp.array([True]), jnp.array([False])))[0]
    x_ham = 1.9099 * (0.2 - 0.1047) + 0.2 * 0.5  # trunk ahead of its target: extensors pull
    x_glu = 0.7 * 1.9099 * (0.2 - 0.1047) + 0.7 * 0.2 * 0.5
    want = [
        0.05,
        0.05 + x_glu,
        0.05 + x_ham,
        0.08 + 1.2 * 0.5 + 2.0 * (0.1 - 0.1745),
        0.01 + 1.1 * 0.6,
        0.01 + 1.2 * 0.7,
        0.01 + 1.1 * (0.8 - 0.72) - 0.4 * 0.7,
        0.01,
    ]
    np.testing.assert_allclose(u, want, rtol=1e-4, atol=1e-6)
    # trunk behind its target and falling back: only HFL pulls
    s_back = _row(F=_F, L=_L, trunk=-0.1, dtrunk=-0.5, knee=0.3)
    u = np.asarray(w.stance_excitation(_p(), s_back, jnp.array([True]), jnp.array([False])))[0]
    x_hfl = -(1.9099 * (-0.1 - 0.1047) + 0.2 * -0.5)
    np.testing.assert_allclose(u[[HFL, GLU, HAM, VAS]], [0.05 + x_hfl, 0.05, 0.05, 0.68], rtol=1e-4)
    # not the lead leg: no trunk PD; swing initiation adds -s_VAS, +s_RF, -s_GLU, +s_HFL
    p = _p(s_RF=0.3)
    lead = np.asarray(w.stance_excitation(p, s, jnp.array([True]), jnp.array([True])))[0]
    trail = np.asarray(w.stance_excitation(p, s, jnp.array([False]), jnp.array([True])))[0]
    np.testing.assert_allclose(trail[[HFL, GLU, HAM]], [0.05 + 0.25, 0.05 - 0.25, 0.05], rtol=1e-5)
    base = np.asarray(w.stance_excitation(p, s, jnp.array([True]), jnp.array([False])))[0]
    np.testing.assert_allclose(lead - base, [0.25, -0.25, 0, -0.6, 0, 0, 0, 0.3], atol=1e-6)


def test_swing_laws_by_hand():
    s = _row(F=_F, L=[0.9, 1.1, 1.0, 1.0, 1.0, 1.0, 0.8, 1.0], theta_to=0.15)
    u = np.asarray(w.swing_excitation(_p(), s, jnp.array([False])))[0]
    ham = 4.0 * (1.0 - 0.85)
    want = [0.01 + 0.5 * (0.9 - 0.65) - ham + 1.1459 * (0.15 - 0.1047), 0.01 + 0.5 * (1.1 - 1.0),
            0.01 + ham, 0.01, 0.01, 0.01, 0.01 + 1.1 * (0.8 - 0.72), 0.01]  # fmt: skip
    np.testing.assert_allclose(u, want, rtol=1e-4, atol=1e-6)


def test_stance_preparation_pd_and_simbicon_target_shift():
    s = _row(L=[0.9, 1.1, 1.0, 1.0, 1.0, 1.0, 0.8, 1.0], hip=0.2, knee=0.3, dknee=0.5,
             bal_d=0.2, bal_v=1.0)  # fmt: skip
    sw = np.asarray(w.swing_excitation(_p(), s, jnp.array([False])))[0]
    sp = np.asarray(w.swing_excitation(_p(), s, jnp.array([True])))[0]
    # hip 0.2 rad short of the target 0.4: HFL flexes, GLU silent; VAS extends the bent knee
    np.testing.assert_allclose(sp[HFL], 0.01 + 1.9099 * 0.2, rtol=1e-4)
    assert sp[GLU] == pytest.approx(0.01)
    np.testing.assert_allclose(sp[VAS], 0.01 + 1.9099 * (0.3 - 0.0873) + 0.2 * 0.5, rtol=1e-4)
    keep = [HAM, GAS, SOL, TA, RF]
    np.testing.assert_array_equal(sp[keep], sw[keep])
    # SIMBICON: target 0.4 + 1.0 * 0.2 + 0.5 * 1.0 = 1.1 rad
    sp = np.asarray(w.swing_excitation(_p(c_d=1.0, c_v=0.5), s, jnp.array([True])))[0]
    np.testing.assert_allclose(sp[HFL], 0.01 + 1.9099 * 0.9, rtol=1e-4)
    # a thigh past the target (and flexing further) brings GLU in, HFL out
    s2 = _row(hip=0.6, dhip=1.0)
    sp = np.asarray(w.swing_excitation(_p(), s2, jnp.array([True])))[0]
    np.testing.assert_allclose(sp[[GLU, HFL]], [0.01 + 1.9099 * 0.2 + 0.2, 0.01], rtol=1e-4)


def test_laws_are_jit_and_vmap_friendly():
    vecs = jnp.asarray(np.stack([WANG.init, WANG.pack({"c_d": 1.0})]), jnp.float32)
    rows = jnp.concatenate([_row(hip=0.1), _row(hip=0.1, dleg=0.7, contact=1)])
    f = jax.jit(jax.vmap(lambda v: w.wang_excitation(WANG.unpack(v), rows,
                                                     jnp.array([w.SP, w.SI]),
                                                     jnp.array([False, True]))))  # fmt: skip
    out = np.asarray(f(vecs))
    assert out.shape == (2, 2, 8) and np.isfinite(out).all()


# ------------------------------------------------------------------ the state machine
def _run_phases(contact, ds, d, start):
    ph, out = jnp.asarray(start, jnp.int32), []
    for c, b, x in zip(contact, ds, d, strict=True):
        ph = w.update_phase(ph, jnp.asarray(c, bool), jnp.asarray(b, bool), x, 0.5, -0.3)
        out.append(int(ph))
    return out


def test_swing_initiation_by_distance_and_stance_preparation_by_distance():
    contact = [1, 1, 1, 1, 0, 0, 0, 0, 1, 1]
    d = [-0.2, 0.3, 0.6, 0.2, 0.3, -0.1, -0.4, 0.0, -0.3, 0.1]
    got = _run_phases(contact, [0] * 10, d, w.STANCE)
    S, I, W, P = w.STANCE, w.SI, w.SWING, w.SP
    assert got == [S, S, I, I, W, W, P, P, S, S]  # SI and SP are latched


def test_swing_initiation_by_double_stance_and_direct_transitions():
    got = _run_phases([1, 1, 1, 0], [0, 1, 0, 0], [0.1, 0.2, 0.3, 0.4], w.STANCE)
    assert got == [w.STANCE, w.SI, w.SI, w.SWING]
    # lift-off straight from stance, touchdown straight from swing
    assert _run_phases([0, 1], [0, 0], [0.0, 0.0], w.STANCE) == [w.SWING, w.STANCE]


def _sensors(stance=(1.0, 0.0), ds=(0.0, 0.0), dleg=(0.0, 0.0), trunk=0.0, f_norm=None):
    z2, z23 = jnp.zeros(2), jnp.zeros((2, 3))
    f = jnp.zeros((2, 8)) if f_norm is None else jnp.asarray(f_norm, jnp.float32)
    return Sensors(
        t=jnp.zeros(()), f_mtu=f * 1000.0, f_norm=f, l_ce=jnp.ones((2, 8)) * 0.1,
        l_norm=jnp.ones((2, 8)), phi=z23 + jnp.pi, dphi=z23, trunk=jnp.asarray(trunk),
        dtrunk=jnp.zeros(()), load=jnp.asarray(stance), stance=jnp.asarray(stance) > 0.5,
        touchdown=jnp.zeros(2, bool), double_support=jnp.asarray(ds) > 0.5,
        theta_to=z2, com=z2, com_vel=z2, feet=jnp.zeros((4, 2)), dcom=z2,
        ankle=jnp.zeros((2, 2)), ankle_vel=jnp.zeros((2, 2)), dleg=jnp.asarray(dleg),
    )  # fmt: skip


@pytest.fixture(scope="module")
def stepper():
    ctrl, dt = w.WANG_CONTROLLER, 0.0005
    cmd = {"lean_offset": jnp.zeros(()), "hip_target_offset": jnp.zeros(())}
    step = jax.jit(lambda st, sens: ctrl.step(ctrl, _p(), sens, st, cmd, dt))
    return lambda sens: ctrl.init(ctrl, sens, dt), step


def test_state_machine_sees_ground_contact_10_ms_late(stepper):
    init, step = stepper
    st = init(_sensors())
    assert st.phase.tolist() == [w.STANCE, w.SWING]
    phases = []
    for k in range(60):  # the left leg lands at step 0 (double stance, right leg trailing)
        if k < 30:
            sens = _sensors(stance=(1.0, 1.0), ds=(1.0, 0.0))
        else:  # the right leg lifts off; the CoM is 0.7 leg lengths ahead of its ankle
            sens = _sensors(stance=(0.0, 1.0), dleg=(0.7, -0.1))
        _, st = step(st, sens)
        phases.append(st.phase.tolist())
    # 10 ms = 20 steps of 0.5 ms: the touchdown and the double stance show at step 20
    assert phases[19] == [w.STANCE, w.SWING] and phases[20] == [w.SI, w.STANCE]
    assert phases[49] == [w.SI, w.STANCE] and phases[50] == [w.SWING, w.STANCE]
    assert phases[59] == [w.SWING, w.STANCE]  # d = 0.7 > d_SP: no stance preparation


def test_each_muscle_sees_its_own_delay(stepper):
    init, step = stepper
    st = init(_sensors())
    moved = _sensors(trunk=0.3, f_norm=np.full((2, 8), 0.5))
    out = []
    for _ in range(45):
        stim, st = step(st, moved)
        out.append(np.asarray(stim)[0])
    out = np.stack(out)
    base = out[0]
    changed = lambda m: int(np.argmax(np.abs(out[:, m] - base[m]) > 1e-6))
    assert changed(HAM) == 10 and changed(VAS) == 20 and changed(SOL) == 40


# ------------------------------------------------------------------ effort and return
def _scone_wang2012(mass, ratio, u, a, l_norm, v, f, f_active):
    """Per-muscle rate of SCONE's EffortMeasure::GetWang2012 (scone-core), written out."""
    fa = 40 * ratio * math.sin(math.pi / 2 * u) + 133 * (1 - ratio) * (
        1 - math.cos(math.pi / 2 * u)
    )
    fm = 74 * ratio * math.sin(math.pi / 2 * a) + 111 * (1 - ratio) * (
        1 - math.cos(math.pi / 2 * a)
    )
    g = 0.5 if l_norm < 0.5 else l_norm if l_norm < 1 else -2 * l_norm + 3 if l_norm < 1.5 else 0
    return mass * fa + mass * g * fm + max(0.0, 0.25 * f * -v) + max(0.0, f_active * -v)


def test_metabolic_rate_matches_scone_wang2012_reference():
    t = mtu.WANG8
    u = np.array([0.05, 0.3, 0.6, 1.0, 0.2, 0.8, 0.01, 0.5])
    a = np.array([0.1, 0.25, 0.5, 0.9, 0.3, 0.7, 0.02, 0.4])
    ln = np.array([0.4, 0.7, 0.95, 1.1, 1.3, 1.6, 0.5, 1.0])
    v = np.array([-0.3, 0.2, -1.0, 0.0, -0.05, 0.4, -0.2, -0.6])
    f = np.array([500.0, 300.0, 1200.0, 4000.0, 800.0, 2500.0, 100.0, 600.0])
    fa = 0.8 * f
    got = np.asarray(ef.wang_metabolic_rate(t, u, a, ln * t.l_opt, v, fa, f))
    mass = t.f_max / 0.25e6 * 1059.7 * t.l_opt
    want = [_scone_wang2012(*x) for x in zip(mass, t.type1, u, a, ln, v, f, fa, strict=True)]
    np.testing.assert_allclose(got, want, rtol=1e-5)


def test_wang_and_thesis_rates_differ_only_in_g_below_optimal_length():
    t = mtu.GEYER7
    args = lambda ln: (np.full(7, 0.4), np.full(7, 0.5), ln * t.l_opt, np.full(7, -0.1),
                       np.full(7, 300.0), np.full(7, 400.0))  # fmt: skip
    np.testing.assert_allclose(ef.wang_length_factor(np.array([0.3, 0.75, 1.0, 1.25, 1.6])),
                               [0.5, 0.75, 1.0, 0.5, 0.0])  # fmt: skip
    for ln, ratio in ((0.75, 0.75), (1.25, 1.0)):
        wang = ef.wang_metabolic_components(t, *args(ln))
        thesis = en.metabolic_components(t, *args(ln))
        np.testing.assert_allclose(wang["maintenance"], ratio * thesis["maintenance"], rtol=1e-6)
        for k in ("activation", "shortening", "work"):
            np.testing.assert_allclose(wang[k], thesis[k], rtol=1e-6)


def test_effort_task_terms_and_return_on_a_hand_made_trajectory():
    rate = jnp.array([[10.0, 20.0], [30.0, 40.0], [50.0, 60.0], [70.0, 80.0]])  # (T, muscles)
    lim = jnp.array([[1.0, 0, 0], [0, 2.0, 0], [0, 0, 0], [3.0, 0, 0]])
    e = ef.effort(rate, lim, body_mass=80.0)
    assert float(e["J_M"]) == pytest.approx(120.8 + 90.0)  # basal 1.51 W/kg + mean of sums
    assert float(e["J_L"]) == pytest.approx(3.5) and float(e["J_R"]) == 0.0
    assert float(e["J"]) == pytest.approx(100 * 210.8 + 0.5 * 3.5)
    t = jnp.array([0.0, 0.5, 1.0, 1.5])
    vx, trunk = jnp.array([1.0, 1.2, 1.4, 1.0]), jnp.array([0.1, 0.0, -0.1, 0.2])
    # no fall: trailing 1 s means 1.0, 1.1, 1.3, 1.2 against 1.3 m/s
    k = ef.task_terms(t, vx, trunk, 1.3, dt=0.5)
    assert float(k["speed"]) == pytest.approx(100 * 0.5 * (0.09 + 0.04 + 0 + 0.01))
    assert float(k["upright"]) == pytest.approx(100 * 0.5 * (0.01 + 0 + 0.01 + 0.04))
    assert float(k["fall"]) == 0.0 and float(k["total"]) == pytest.approx(10.0)
    # a fall at 1.2 s: the last sample drops out, 8.8 s of the 10 s horizon are lost
    k = ef.task_terms(t, vx, trunk, 1.3, dt=0.5, t_fall=1.2)
    assert float(k["total"]) == pytest.approx(6.5 + 1.0 + 1000 * 8.8)
    r = ef.wang_return(k, e, body_mass=80.0)
    assert float(r["w_e"]) == pytest.approx(5e-5)
    assert float(r["R"]) == pytest.approx(-(6.5 + 1.0 + 8800.0) - 5e-5 * 21081.75, rel=1e-6)
    em = ef.effort(rate, lim, 80.0, mask=t < 1.2)  # effort over the samples before the fall
    assert float(em["J"]) == pytest.approx(100 * (120.8 + 70.0) + 0.5 * 5.0 / 3.0)


# ------------------------------------------------------------------ the model rolls out
def test_running_table_widens_only_the_listed_ranges():
    """wang8_run: wang8's names in wang8's order, each listed range containing the old one,
    every other entry unchanged, so a wang8 vector (e.g. a shipped runner) is a valid one."""
    assert WANG_RUN.names == WANG.names and WANG_RUN.name == "wang8_run"
    for old, new in zip(WANG.specs, WANG_RUN.specs, strict=True):
        assert new.init == old.init
        if old.name in RUN_RANGES:
            assert (new.lower, new.upper) == RUN_RANGES[old.name]
            assert new.lower <= old.lower and new.upper >= old.upper
            assert (new.lower, new.upper) != (old.lower, old.upper)
        else:
            assert new == old
    from jaxgait.presets import load_preset

    _, vec, _ = load_preset("wang_run_2p5")
    WANG_RUN.check(vec)
    with pytest.raises(ValueError, match="does not contain"):
        widened(WANG, "x", {"GF_SOL": (0.5, 5.0)}, "")
    with pytest.raises(ValueError, match="no parameters"):
        widened(WANG, "x", {"G_nope": (0.0, 1.0)}, "")


def test_running_model_is_the_same_step_with_another_box():
    """The same parameters roll out alike on wang8 and wang8_run (one step, two tables), and
    a search on wang8_run may leave wang8's box."""
    spec = models.get_spec("wang8_run")
    assert spec.table is WANG_RUN and spec.commands == models.get_spec("wang8").commands
    cfg = sim.SimConfig(duration=0.3, log_dt=0.01)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    p = jnp.asarray(WANG.init, jnp.float32)
    a = sim.rollout(models.get_model("wang8"), cfg, p, env)[0]
    b = sim.rollout(models.get_model("wang8_run"), cfg, p, env)[0]
    np.testing.assert_array_equal(np.asarray(b.qpos), np.asarray(a.qpos))
    v = np.asarray(WANG.init, float).copy()
    v[WANG.index("GF_SOL")] = 4.0
    WANG_RUN.check(v)
    with pytest.raises(ValueError, match="GF_SOL=4 not in"):
        WANG.check(v)


# ------------------------------------------------------------------ the landing brake
def test_landing_brake_by_hand():
    """TA gets s_pre in late swing (SWING or SP with d < d_pre), s_ld in the first t_ld of
    stance (STANCE or SI), nothing else; t_ld = 0 gives no stance term at all."""
    phase = jnp.asarray([w.SWING, w.SP, w.SWING, w.STANCE, w.SI, w.STANCE, w.STANCE])
    dleg = jnp.asarray([-0.4, -0.5, -0.1, 0.0, 0.0, 0.0, 0.3])
    t = jnp.asarray([0.0, 0.0, 0.0, 0.01, 0.02, 0.03, 0.0005])
    out = w.landing_brake(0.2, -0.3, 0.5, 0.025, phase, dleg, t)
    np.testing.assert_allclose(np.asarray(out), [0.2, 0.2, 0.0, 0.5, 0.5, 0.0, 0.5])
    none = w.landing_brake(0.2, -0.3, 0.5, 0.0, phase, dleg, t)
    np.testing.assert_allclose(np.asarray(none), [0.2, 0.2, 0.0, 0.0, 0.0, 0.0, 0.0])


def test_landing_brake_counts_stance_time_from_the_delayed_contact():
    """The stance timer starts when the state machine sees the touchdown (10 ms late) and
    the brake's TA excitation lasts T_ld from then; off (s = 0) the TA is wang8_run's."""
    ctrl, dt = w.WANG_RUN_LD_CONTROLLER, 0.0005
    cmd = {"lean_offset": jnp.zeros(()), "hip_target_offset": jnp.zeros(())}
    p_ld = {k: float(v) for k, v in WANG_RUN_LD.unpack(np.asarray(WANG_RUN_LD.init)).items()}
    on = {
        k: jnp.asarray(v, jnp.float32) for k, v in {**p_ld, "s_TA_ld": 0.4, "T_ld": 0.0052}.items()
    }
    off = {k: jnp.asarray(v, jnp.float32) for k, v in p_ld.items()}
    runs = {}
    for name, p in (("on", on), ("off", off)):
        step = jax.jit(lambda st, sens, p=p: ctrl.step(ctrl, p, sens, st, cmd, dt))
        st = ctrl.init(ctrl, _sensors(stance=(0.0, 1.0)), dt)
        ta, ts = [], []
        for _ in range(50):  # the right leg lands at step 0
            stim, st = step(st, _sensors(stance=(1.0, 1.0), ds=(0.0, 1.0)))
            ta.append(float(stim[0, TA]))
            ts.append(int(st.n_stance[0]))
        runs[name] = np.asarray(ta), np.asarray(ts)
    ta_on, ts = runs["on"]
    ta_off, _ = runs["off"]
    assert ts[19] == 0 and ts[20] == 1 and ts[29] == 10
    diff = ta_on - ta_off
    # seen at step 20 (10 ms), held while the time in stance <= 5.2 ms: steps 20-29
    np.testing.assert_allclose(diff[20:30], 0.4, atol=1e-6)
    assert np.abs(diff[:20]).max() < 1e-7 and np.abs(diff[31:]).max() < 1e-7


def test_landing_brake_off_moves_as_wang8_run():
    """A wang8_run vector on wang8_run_ld (the brake's parameters at their init, s = 0)
    rolls out bit for bit as on wang8_run; switched on, the TA is excited harder."""
    assert WANG_RUN_LD.names[: WANG_RUN.size] == WANG_RUN.names
    assert WANG_RUN_LD.names[WANG_RUN.size :] == ("s_TA_pre", "d_TA_pre", "s_TA_ld", "T_ld")
    cfg = sim.SimConfig(duration=0.4, log_dt=0.01)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    v = np.asarray(WANG_RUN.init, float)
    a = sim.rollout(models.get_model("wang8_run"), cfg, jnp.asarray(v, jnp.float32), env)[0]
    ld = models.get_model("wang8_run_ld")
    v_ld = WANG_RUN_LD.pack(WANG_RUN.unpack(v))
    b = sim.rollout(ld, cfg, jnp.asarray(v_ld, jnp.float32), env)[0]
    np.testing.assert_array_equal(np.asarray(b.qpos), np.asarray(a.qpos))
    on = WANG_RUN_LD.pack({"s_TA_ld": 0.5, "T_ld": 0.05, "s_TA_pre": 0.3}, base=v_ld)
    c = sim.rollout(ld, cfg, jnp.asarray(on, jnp.float32), env)[0]
    assert float(np.asarray(c.stim)[..., 0, TA].sum()) > float(np.asarray(a.stim)[..., 0, TA].sum())


def test_wang8_model_rolls_out_with_eight_muscles():
    model = models.get_model("wang8")
    f = sim.make_rollout(model, sim.SimConfig(duration=0.5), batched=False)  # as test_controllers
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    vec = np.asarray(WANG.init)
    trace, _, summary, final = f(jnp.asarray(vec, jnp.float32), env)
    assert np.asarray(trace.stim).shape[-2:] == (2, 8) and np.asarray(trace.act).shape[-1] == 8
    for x in jax.tree.leaves(final):
        assert np.isfinite(np.asarray(x, float)).all()
    assert float(summary.duration) == pytest.approx(0.5) and not bool(summary.fell)
    assert set(np.asarray(final.ctrl.phase).tolist()) <= {w.STANCE, w.SI, w.SWING, w.SP}
    # the initial-state parameters move the start: +0.1 rad swing knee, +0.3 m/s
    moved = WANG.pack({"init_knee_sw": 0.1, "init_dv": 0.3})
    trace2, *_ = f(jnp.asarray(moved, jnp.float32), env)
    q0, q1 = np.asarray(trace.qpos[0]), np.asarray(trace2.qpos[0])
    assert q1[7] - q0[7] == pytest.approx(0.1, abs=0.03)  # knee_l after 10 ms
    assert float(trace2.com_vel[0, 0] - trace.com_vel[0, 0]) == pytest.approx(0.3, abs=0.1)


# ------------------------------------------- Wang's metabolic model inside the rollout
def test_models_integrate_their_own_metabolic_model():
    assert models.get_model("wang8").metabolic == "wang2012"
    assert models.get_model("fbl").metabolic == "thesis"
    with pytest.raises(ValueError, match="unknown metabolic model 'bhargava'"):
        sim.model.planar_model(w.WANG_CONTROLLER, metabolic="bhargava")


def test_rollout_energy_follows_the_chosen_metabolic_model():
    """The same wang8 rollout with the thesis's and with Wang's rate: the motion is the same,
    the energies differ; the soft-limit integral is recorded, and the effort measures are
    J_M = 1.51 W/kg m + E/T and J = 100 J_M + 0.5 J_L."""
    from jaxgait.analysis.measures import compute_measures

    env = envs.make_env("flat", jax.random.PRNGKey(0))
    vec = jnp.asarray(WANG.init, jnp.float32)
    cfg = sim.SimConfig(duration=0.3)
    out = {}
    for kind in ("wang2012", "thesis"):
        model = sim.model.planar_model(w.WANG_CONTROLLER, metabolic=kind)
        out[kind] = sim.make_rollout(model, cfg, batched=False)(vec, env)
    (tw, ew, sw, _), (tt, _, st, _) = out["wang2012"], out["thesis"]
    np.testing.assert_array_equal(np.asarray(tw.qpos), np.asarray(tt.qpos))
    assert float(sw.energy) > 0 and float(st.energy) > 0
    assert abs(float(sw.energy) / float(st.energy) - 1.0) > 0.01
    assert float(sw.limit_torque_sq) >= 0.0
    m = jax.tree.map(np.asarray, compute_measures(tw, ew, sw))
    T, mass = float(sw.duration), float(sw.mass)
    j_m = 1.51 * mass + float(sw.energy) / T
    assert float(m["effort_J_M_W"]) == pytest.approx(j_m, rel=1e-5)
    assert float(m["effort_J_L"]) == pytest.approx(float(sw.limit_torque_sq) / T, rel=1e-5)
    assert float(m["effort"]) == pytest.approx(100 * j_m + 0.5 * float(m["effort_J_L"]), rel=1e-5)


def test_effort_criterion_is_wangs_weighted_term():
    from jaxgait.train.objective import criterion_value

    m = {"effort": jnp.asarray(40000.0), "mass_kg": jnp.asarray(80.0)}
    assert float(criterion_value("effort", m, {})) == pytest.approx(-0.004 * 40000.0 / 80.0)


def test_standard_score_of_table_1_by_hand():
    """Wang's Table 1 score: Winter's mean scores 0, the mean shifted by one SD scores 1 at
    every joint, a shift by 2 SD at the knee only scores (0, 2, 0) and 2/3 on average."""
    from jaxgait.analysis import refdata
    from jaxgait.analysis.measures import standard_scores

    ref = refdata.winter_walking_kinematics()
    mean = np.asarray(ref.mean_deg)
    sd = np.stack([ref.hip_sd_deg, ref.knee_sd_deg, ref.ankle_sd_deg], -1)
    np.testing.assert_allclose(np.asarray(standard_scores(mean, ref)), 0.0, atol=1e-6)
    np.testing.assert_allclose(np.asarray(standard_scores(mean - sd, ref)), 1.0, rtol=1e-5)
    knee = mean + np.array([0.0, 2.0, 0.0]) * sd
    z = np.asarray(standard_scores(knee, ref))
    np.testing.assert_allclose(z, [0.0, 2.0, 0.0], atol=1e-5)
    assert float(z.mean()) == pytest.approx(2.0 / 3.0, rel=1e-5)


# ------------------------------------------------------------ the shipped Wang presets
def _wang_gaits() -> list[str]:
    from jaxgait import presets

    return sorted(
        p
        for p in presets.list_presets()
        if p.startswith(("wang_walk_", "wang_run_")) and p != "wang_run_start"
    )


@pytest.mark.slow
def test_every_shipped_wang_preset_walks_or_runs_20s_near_its_target():
    """Each Wang walking or running preset, named by its target speed (``wang_walk_1p25``,
    or with a suffix: ``wang_walk_1p25_human``), goes 20 s on flat ground without a fall
    within 0.1 m/s of the speed its name gives (the push-tolerant ones are checked against
    their pushes below)."""
    from jaxgait.presets import load_preset, preset_dynamics

    names = _wang_gaits()
    assert "wang_walk_1p25" in names
    model = models.get_model("wang8")
    vecs, starts, targets = [], [], []
    for n in names:
        _, vec, doc = load_preset(n)
        vecs.append(vec)
        # each with the start speed and the dynamics it was made with
        starts.append((float(doc.get("v0", 1.3)), preset_dynamics(doc)))
        targets.append(float(n.split("_")[2].replace("p", ".")))
    for v0, dynamics in sorted(set(starts)):  # one batch per start (both are static)
        idx = [i for i, v in enumerate(starts) if v == (v0, dynamics)]
        cfg = sim.SimConfig(duration=20.0, log_dt=0.1, v0=v0, dynamics=dynamics)
        env = envs.make_env_batch("flat", jax.random.split(jax.random.PRNGKey(0), len(idx)))
        f = sim.make_rollout(model, cfg, batched=True)
        _, _, s, _ = f(jnp.asarray(np.stack([vecs[i] for i in idx]), jnp.float32), env)
        for k, i in enumerate(idx):
            assert not bool(s.fell[k]), names[i]
            v = float(s.distance[k]) / float(s.duration[k])
            assert abs(v - targets[i]) < 0.1, (names[i], v)


def _falls_under_pushes(names, magnitude: float, times=(4.0, 6.3)) -> dict[str, list[bool]]:
    """Per preset of ``names``: did it fall within 20 s on flat ground under one forward
    ``magnitude`` [N], 0.4 s push on the trunk at each of ``times`` [s] (one rollout each,
    from the preset's v0)?"""
    from jaxgait.presets import load_preset, preset_dynamics

    model = models.get_model("wang8")
    cfgs = [
        envs.get_env_config("push", magnitude=magnitude, duration=0.4, t_min=t, t_max=t)
        for t in times
    ]
    env = jax.tree.map(lambda *x: jnp.stack(x), *[c.build(jax.random.PRNGKey(0)) for c in cfgs])
    fell = {}
    for name in names:
        _, vec, doc = load_preset(name)
        v0, dynamics = float(doc.get("v0", 1.3)), preset_dynamics(doc)
        cfg = sim.SimConfig(duration=20.0, log_dt=0.1, v0=v0, dynamics=dynamics)
        f = sim.make_rollout(model, cfg, batched=True)
        params = jnp.broadcast_to(jnp.asarray(vec, jnp.float32), (len(times), vec.size))
        fell[name] = np.asarray(f(params, env)[2].fell).tolist()
    return fell


@pytest.mark.slow
def test_the_push_tolerant_walker_survives_wangs_push_where_nwalk_falls():
    """wang_push_walk_1p25 walks 20 s with a 100 N, 0.4 s forward push on the trunk at 4 s
    and at 6.3 s; nwalk, from which it was optimised, falls under the same push."""
    from jaxgait.presets import list_presets

    if "wang_push_walk_1p25" not in list_presets():
        pytest.skip("wang_push_walk_1p25 is not shipped")
    fell = _falls_under_pushes(("wang_push_walk_1p25", "wang_walk_1p25"), 100.0)
    assert fell["wang_push_walk_1p25"] == [False, False], fell
    assert any(fell["wang_walk_1p25"]), fell


@pytest.mark.slow
def test_every_shipped_wang_runner_has_flight_and_no_double_stance():
    """A ``wang_run_*`` preset runs: over 20 s on flat ground it spends time with neither foot
    on the ground and (next to) none with both."""
    from jaxgait import evaluation

    runners = [n for n in _wang_gaits() if n.startswith("wang_run_")]
    assert runners, "no running preset ships"
    for name in runners:
        rep = evaluation.run(name, duration=20.0).report
        assert not rep["fell"], name
        assert rep["flight_fraction"] > 0.01, (name, rep["flight_fraction"])
        assert rep["double_stance_fraction"] < 0.01, (name, rep["double_stance_fraction"])


@pytest.mark.slow
def test_the_push_tolerant_runner_runs_and_survives_pushes_where_its_start_falls():
    """wang_push_run_2p5 runs 20 s on flat ground with flight and no double stance, and runs
    through a 50 N, 0.4 s forward push on the trunk at 4 s and at 6.3 s (Wang's push-tolerant
    runner's magnitude); wang_run_2p5, from which it was optimised, falls under them."""
    from jaxgait import evaluation
    from jaxgait.presets import list_presets

    if "wang_push_run_2p5" not in list_presets():
        pytest.skip("wang_push_run_2p5 is not shipped")
    rep = evaluation.run("wang_push_run_2p5", duration=20.0).report
    assert not rep["fell"]
    assert rep["flight_fraction"] > 0.01 and rep["double_stance_fraction"] < 0.01, rep
    fell = _falls_under_pushes(("wang_push_run_2p5", "wang_run_2p5"), 50.0)
    assert fell["wang_push_run_2p5"] == [False, False], fell
    assert any(fell["wang_run_2p5"]), fell
