"""Gait measures on hand-made rollouts whose answers are known."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait.analysis import measures as M
from jaxgait.analysis import refdata
from jaxgait.sim.trace import Events, Summary, Trace

WINTER = refdata.winter_walking_kinematics()
DT = 0.01  # trace sample period [s]
PERIOD = 1.0  # gait cycle [s]


def periodic(curve_pct, curve, t, t0, period=PERIOD):
    """Values of a gait-cycle curve repeated periodically, heel strike at t0 + k period."""
    phase = np.mod(t - t0, period) / period * 100.0
    return np.interp(phase, curve_pct, curve)


def make_rollout(
    *,
    T=600,
    t0=0.5,
    n_alive=None,
    angle_fn=None,
    events=None,
    n_events=None,
    E=32,
    stance=None,
    distance=7.0,
    duration=None,
    energy=1400.0,
    mass=80.0,
    lean_sum=None,
    garbage_after_end=False,
):
    """A Trace/Events/Summary whose right-leg angles follow ``angle_fn`` (deg, (T, 3))."""
    t = np.arange(T) * DT
    n_alive = T if n_alive is None else n_alive
    alive = np.arange(T) < n_alive
    if angle_fn is None:
        angle_fn = lambda tt: np.stack(  # noqa: E731
            [periodic(WINTER.gait_cycle_pct, c, tt, t0) for c in WINTER.mean_deg.T], axis=1
        )
    qpos = np.zeros((T, 9))
    qpos[:, 0] = 1.3 * t
    qpos[:, 1] = 1.0
    qpos[:, 2] = 0.05
    qpos[:, 3:6] = np.deg2rad(angle_fn(t))
    qpos[:, 6:9] = np.deg2rad(angle_fn(t - PERIOD / 2))
    grf = np.zeros((T, 2, 2))
    grf[:, 0, 1] = 800.0 * (1.0 + np.sin(2 * np.pi * (t - t0) / PERIOD))
    st = np.zeros((T, 2), bool) if stance is None else stance
    if garbage_after_end:
        qpos[~alive] = np.nan
        grf[~alive] = np.nan
        t = np.where(alive, t, 0.0)
    trace = Trace(
        t=jnp.asarray(t, jnp.float32),
        qpos=jnp.asarray(qpos, jnp.float32),
        com=jnp.zeros((T, 2), jnp.float32),
        com_vel=jnp.zeros((T, 2), jnp.float32),
        grf=jnp.asarray(grf, jnp.float32),
        stance=jnp.asarray(st),
        act=jnp.zeros((T, 2, 7), jnp.float32),
        stim=jnp.zeros((T, 2, 7), jnp.float32),
        energy=jnp.linspace(0.0, energy, T, dtype=jnp.float32),
        alive=jnp.asarray(alive),
    )
    if events is None:  # right/left touchdowns alternating every half period until the end
        k = np.arange(E)
        ev_t = t0 + k * PERIOD / 2
        keep = ev_t < n_alive * DT
        events = (ev_t[keep], (k % 2)[keep], np.full(int(keep.sum()), 0.65))
    ev_t, ev_leg, sl = (np.asarray(a) for a in events)
    n = len(ev_t) if n_events is None else n_events
    pad = E - len(ev_t)
    ev = Events(
        t=jnp.asarray(np.pad(ev_t, (0, pad)), jnp.float32),
        leg=jnp.asarray(np.pad(ev_leg, (0, pad)), jnp.int32),
        x_td=jnp.asarray(np.pad(sl + 10.0, (0, pad)), jnp.float32),
        x_other=jnp.full((E,), 10.0, jnp.float32),
        n=jnp.asarray(n, jnp.int32),
    )
    dur = n_alive * DT if duration is None else duration
    summary = Summary(
        duration=jnp.asarray(dur, jnp.float32),
        distance=jnp.asarray(distance, jnp.float32),
        fell=jnp.asarray(False),
        energy=jnp.asarray(energy, jnp.float32),
        trunk_lean_sum=jnp.asarray(0.05 * dur if lean_sum is None else lean_sum, jnp.float32),
        mass=jnp.asarray(mass, jnp.float32),
    )
    return trace, ev, summary


def measure(*rollout, **kw):
    """compute_measures as a dict of NumPy arrays."""
    return jax.tree.map(np.asarray, M.compute_measures(*rollout, **kw))


def assert_finite(out):
    for k, v in out.items():
        assert np.all(np.isfinite(np.asarray(v, np.float64))), k


# ----------------------------------------------------------------------------- C_angles


@pytest.mark.parametrize("t0", [0.5, 0.513])  # aligned and not aligned with the samples
def test_winter_angles_correlate_perfectly(t0):
    out = measure(*make_rollout(t0=t0))
    for k in ("corr_hip", "corr_knee", "corr_ankle", "c_angles"):
        assert float(out[k]) > 0.995, k
    assert bool(out["cycle_valid"])
    assert out["cycle_angles_deg"].shape == (WINTER.n_samples, 3)
    tol = 1e-3 if t0 == 0.5 else 3.0  # linear interpolation between 10 ms samples
    # the data are not exactly periodic (100 % differs from 0 %); the repeated curve is
    np.testing.assert_allclose(out["cycle_angles_deg"][:-1], WINTER.mean_deg[:-1], atol=tol)
    # the last full right cycle: right touchdowns every 1 s from t0, trace ends at 6 s
    assert float(out["cycle_end_s"]) == pytest.approx(t0 + 5.0, abs=1e-5)
    assert float(out["cycle_start_s"]) == pytest.approx(t0 + 4.0, abs=1e-5)


def test_the_mean_cycle_averages_the_last_cycles_a_single_cycle_does_not():
    """Cycles alternately one human SD above and below Winter's mean (5 full cycles, the
    last above): the last cycle scores 1 SD, the mean of the five 1/5 SD (samples at a
    cycle's 100 % belong to the next cycle, hence the tolerance)."""
    sd = np.stack([WINTER.hip_sd_deg, WINTER.knee_sd_deg, WINTER.ankle_sd_deg], axis=1)

    def alternating(tt):
        sign = np.where(np.floor((tt - 0.5) / PERIOD) % 2 == 0, 1.0, -1.0)[:, None]
        curves = [periodic(WINTER.gait_cycle_pct, c, tt, 0.5) for c in WINTER.mean_deg.T]
        offsets = [periodic(WINTER.gait_cycle_pct, c, tt, 0.5) for c in sd.T]
        return np.stack(curves, 1) + sign * np.stack(offsets, 1)

    out = measure(*make_rollout(angle_fn=alternating))
    assert int(out["n_mean_cycles"]) == M.MEAN_CYCLES == 5
    assert float(out["standard_score"]) == pytest.approx(1.0, abs=0.06)
    assert float(out["mean_cycle_standard_score"]) == pytest.approx(0.2, abs=0.06)
    plain = measure(*make_rollout())
    for j in ("hip", "knee", "ankle"):
        assert float(plain[f"mean_cycle_corr_{j}"]) > 0.995
        assert float(out[f"mean_cycle_corr_{j}"]) > float(out[f"corr_{j}"]) - 1e-6


def test_shifted_and_negated_angles_score_lower():
    def shifted(tt):
        return np.stack(
            [periodic(WINTER.gait_cycle_pct, c, tt, 0.5 + 0.25) for c in WINTER.mean_deg.T],
            axis=1,
        )

    def neg_hip(tt):
        a = np.stack([periodic(WINTER.gait_cycle_pct, c, tt, 0.5) for c in WINTER.mean_deg.T], 1)
        a[:, 0] = -a[:, 0]
        return a

    good = measure(*make_rollout())
    out = measure(*make_rollout(angle_fn=shifted))
    assert float(out["c_angles"]) < float(good["c_angles"]) - 0.3
    out = measure(*make_rollout(angle_fn=neg_hip))
    assert float(out["corr_hip"]) == pytest.approx(-1.0, abs=1e-4)
    assert float(out["corr_knee"]) == pytest.approx(1.0, abs=1e-4)
    assert float(out["c_angles"]) == pytest.approx(-1.0, abs=1e-4)


def test_pearson_matches_numpy_and_constant_is_zero():
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(40, 3)), rng.normal(size=(40, 3))
    r = jax.jit(M.pearson)(jnp.asarray(x), jnp.asarray(y))
    ref = [np.corrcoef(x[:, i], y[:, i])[0, 1] for i in range(3)]
    np.testing.assert_allclose(r, ref, atol=1e-5)
    assert float(jax.jit(M.pearson)(jnp.ones(10), jnp.arange(10.0))) == 0.0


def test_running_reference_and_no_skip():
    run = refdata.running_kinematics()
    sl = np.array([0.1, 0.2, 0.60, 0.70, 0.62, 0.68])
    t = 0.5 + 0.5 * np.arange(6)
    out = measure(*make_rollout(events=(t, np.arange(6) % 2, sl)), reference=run, skip=0)
    assert out["cycle_angles_deg"].shape == (run.n_samples, 3)
    assert -1.0 <= float(out["c_angles"]) <= 1.0
    assert int(out["n_steps_used"]) == 6
    assert float(out["step_length_mean_m"]) == pytest.approx(sl.mean(), abs=1e-6)


def test_dead_rows_are_ignored():
    # rollout ends at 4.2 s; rows after it hold NaN and t = 0; last full right cycle 3.5-4.5
    # is not complete in the events (td at 4.5 > end), so the cycle is 2.5 -> 3.5
    trace, ev, summ = make_rollout(n_alive=420, garbage_after_end=True)
    out = measure(trace, ev, summ)
    assert_finite(out)
    assert float(out["cycle_end_s"]) == pytest.approx(3.5)
    assert float(out["c_angles"]) > 0.995


# ----------------------------------------------------------------------------- steps


def test_step_lengths_mean_snr_and_sides():
    sl = np.array([0.1, 0.2, 0.60, 0.70, 0.62, 0.68, 0.64, 0.66])  # first two are start-up
    legs = np.arange(8) % 2
    t = 0.5 + 0.5 * np.arange(8)
    out = measure(*make_rollout(events=(t, legs, sl)), skip=2)
    used = sl[2:]
    assert int(out["n_steps"]) == 8
    assert int(out["n_steps_used"]) == 6
    assert float(out["step_length_mean_m"]) == pytest.approx(used.mean(), abs=1e-6)
    assert float(out["step_length_var_m2"]) == pytest.approx(used.var(), abs=1e-7)
    assert float(out["step_length_snr"]) == pytest.approx(
        np.log(used.mean() / used.var()), abs=1e-3
    )
    right, left = sl[2:][legs[2:] == 0], sl[2:][legs[2:] == 1]
    assert float(out["step_length_right_mean_m"]) == pytest.approx(right.mean(), abs=1e-6)
    assert float(out["step_length_left_mean_m"]) == pytest.approx(left.mean(), abs=1e-6)
    assert float(out["step_length_right_var_m2"]) == pytest.approx(right.var(), abs=1e-7)
    assert float(out["step_length_left_var_m2"]) == pytest.approx(left.var(), abs=1e-7)
    assert int(out["n_steps_right"]) == 3 and int(out["n_steps_left"]) == 3
    np.testing.assert_allclose(out["step_lengths_m"][:8], np.r_[0, 0, used], atol=1e-6)


def test_snr_guards():
    assert float(M.snr(jnp.float32(0.7), jnp.float32(0.0), 5)) == pytest.approx(
        np.log(0.7 / M.VAR_FLOOR), rel=1e-5
    )
    assert float(M.snr(jnp.float32(0.7), jnp.float32(0.0), 1)) == M.SNR_UNDEFINED
    assert np.isfinite(float(M.snr(jnp.float32(-0.3), jnp.float32(0.01), 4)))


def test_overflowed_events_use_capacity_only():
    E = 32  # every slot filled, 40 touchdowns happened
    sl = np.linspace(0.6, 0.7, E)
    t = 0.1 + 0.15 * np.arange(E)
    out = measure(*make_rollout(events=(t, np.arange(E) % 2, sl), n_events=40))
    assert int(out["n_steps"]) == 40
    assert int(out["n_steps_used"]) == E - 2
    assert float(out["step_length_mean_m"]) == pytest.approx(sl[2:].mean(), abs=1e-6)


# ----------------------------------------------------------------------------- scalars


def test_energy_speed_cot_and_lean_by_hand():
    out = measure(*make_rollout(distance=7.0, duration=5.0, energy=1400.0, mass=80.0, lean_sum=0.4))
    assert float(out["mean_speed_mps"]) == pytest.approx(1.4)
    assert float(out["energy_J_per_m"]) == pytest.approx(200.0)
    assert float(out["cost_of_transport"]) == pytest.approx(2.5)
    assert float(out["cost_of_transport_dimless"]) == pytest.approx(2.5 / 9.81, rel=1e-6)
    assert float(out["mean_trunk_lean_rad"]) == pytest.approx(0.08)
    assert float(out["mean_trunk_lean_trace_rad"]) == pytest.approx(0.05)
    assert float(out["distance_m"]) == 7.0 and float(out["duration_s"]) == 5.0
    assert not bool(out["fell"])
    assert set(out) == set(M.MEASURE_UNITS)
    for k in M.MEASURE_UNITS:
        assert f"``{k}``" in M.compute_measures.__doc__, k


def _alternating_stance(duty):
    """(t, stance (T, 2)): 1 s cycles from t = 0.5 s, each leg in stance for ``duty`` of the
    cycle, the left half a cycle after the right."""
    t = np.arange(600) * DT
    ph = np.mod(t - 0.5, 1.0)
    return t, np.stack([ph < duty, np.mod(ph + 0.5, 1.0) < duty], axis=1)


def test_double_stance_fraction_and_cycle_frequency():
    t, st = _alternating_stance(0.6)  # each leg in stance 60 % of the cycle
    out = measure(*make_rollout(stance=st), skip=2)
    window = t >= 1.5  # from the touchdown of event 2 on
    expect = np.mean(st[window, 0] & st[window, 1])
    assert float(out["double_stance_fraction"]) == pytest.approx(expect, abs=1e-6)
    assert expect == pytest.approx(0.2, abs=0.02)
    assert float(out["cycle_frequency_hz"]) == pytest.approx(1.0, rel=1e-5)
    assert int(out["n_cycles"]) == 5  # right touchdowns at 0.5 ... 5.5
    assert float(out["flight_fraction"]) == 0.0  # a walk: some foot is always down


def test_flight_fraction_of_a_run():
    t, st = _alternating_stance(0.3)  # each leg in stance 30 % of the cycle
    out = measure(*make_rollout(stance=st), skip=2)
    window = t >= 1.5
    expect = np.mean(~st[window, 0] & ~st[window, 1])
    assert expect == pytest.approx(0.4, abs=0.02)  # two flights of 20 % per cycle
    assert float(out["flight_fraction"]) == pytest.approx(expect, abs=1e-6)
    assert float(out["double_stance_fraction"]) == 0.0


def test_no_events_no_nan():
    trace, ev, summ = make_rollout(events=([], [], []), n_events=0)
    out = measure(trace, ev, summ)
    assert_finite(out)
    assert float(out["c_angles"]) == M.CORR_UNDEFINED
    assert not bool(out["cycle_valid"])
    assert float(out["step_length_snr"]) == M.SNR_UNDEFINED
    assert float(out["cycle_frequency_hz"]) == 0.0
    assert int(out["n_cycles"]) == 0


def test_zero_duration_no_nan():
    out = measure(
        *make_rollout(events=([], [], []), n_events=0, n_alive=0, duration=0.0, distance=0.0)
    )
    assert_finite(out)


# ----------------------------------------------------------------------------- curves, batch


def test_mean_gait_cycle_of_grf():
    trace, ev, _ = make_rollout()
    pct = refdata.winter_walking_grf().gait_cycle_pct
    mean, sd, n = M.mean_gait_cycle(trace, ev, trace.grf[:, 0, :], pct, n_cycles=8)
    assert int(n) == 5  # right touchdowns at 0.5, 1.5, ..., 5.5 s
    assert mean.shape == (pct.shape[0], 2)
    expect = 800.0 * (1.0 + np.sin(2 * np.pi * pct / 100.0))
    np.testing.assert_allclose(mean[:, 1], expect, atol=1.0)
    assert float(jnp.max(sd)) < 1e-2
    curves, valid = M.gait_cycle_curves(trace, ev, trace.grf[:, 0, :], pct, n_cycles=8)
    assert curves.shape == (8, pct.shape[0], 2)
    assert valid.tolist() == [True] * 5 + [False] * 3
    assert float(jnp.max(jnp.abs(curves[5:]))) == 0.0


def test_jit_and_vmap_over_a_batch():
    rolls = [
        make_rollout(t0=0.5),
        make_rollout(t0=0.5, events=([], [], []), n_events=0),
        make_rollout(t0=0.5, energy=700.0, distance=3.0),
    ]
    batch = jax.tree.map(lambda *xs: jnp.stack(xs), *rolls)
    f = jax.jit(jax.vmap(functools.partial(M.compute_measures, skip=2)))
    out = jax.tree.map(np.asarray, f(*batch))
    assert out["c_angles"].shape == (3,)
    assert out["cycle_angles_deg"].shape == (3, WINTER.n_samples, 3)
    for i, r in enumerate(rolls):
        single = measure(*r)
        for k, v in single.items():
            np.testing.assert_allclose(out[k][i], v, atol=1e-4, err_msg=k)


def test_running_task_terms_count_only_for_a_rollout_that_stays_up():
    from jaxgait.train.objective import criterion_value

    def m(fell):
        return {
            "fell": jnp.asarray(fell),
            "distance_m": jnp.asarray(10.0),
            "double_stance_fraction": jnp.asarray(0.1),
            "flight_fraction": jnp.asarray(0.25),
        }

    assert float(criterion_value("flight", m(False), {})) == pytest.approx(0.25)
    assert float(criterion_value("no_double_stance", m(False), {})) == pytest.approx(-0.1)
    assert float(criterion_value("flight", m(True), {})) == 0.0  # a fall earns no flight
    assert float(criterion_value("no_double_stance", m(True), {})) == -1.0


def test_flight_time_rewards_the_time_in_the_air_of_a_fall_too():
    from jaxgait.train.objective import criterion_value

    m = {"flight_fraction": jnp.asarray(0.25), "duration_s": jnp.asarray(4.0)}
    for fell in (False, True):  # 0.25 of 4 s in the air, whether the rollout fell or not
        got = criterion_value("flight_time", {**m, "fell": jnp.asarray(fell)}, {})
        assert float(got) == pytest.approx(1.0)
