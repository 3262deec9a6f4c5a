"""Per-stance vertical-GRF peaks measured at the physics step (issue: see the transient)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import models, sim
from jaxgait.analysis.measures import compute_measures, stance_grf_peaks
from jaxgait.sim.step import _record_touchdowns, _stance_peaks
from jaxgait.sim.trace import Events
from jaxgait.world import envs

DT = 0.0005
JOINTS = ("hip", "knee", "ankle")


def empty(E=6):
    z = jnp.zeros(E, jnp.float32)
    return Events(
        t=z,
        leg=jnp.zeros(E, jnp.int32),
        x_td=z,
        x_other=z,
        n=jnp.zeros((), jnp.int32),
        peak_grf=z,
        peak_t=z,
        loading_rate=z,
        open=jnp.full((2,), -1, jnp.int32),
    )


def feed(ev, series):
    """Run the per-step bookkeeping over rows (td_r, td_l, st_r, st_l, fz_r, fz_l)."""
    prev = jnp.zeros(2, jnp.float32)
    for k, (td_r, td_l, st_r, st_l, fr, fl) in enumerate(series):
        t = jnp.asarray(k * DT, jnp.float32)
        ev = _record_touchdowns(ev, jnp.array([td_r, td_l]), t, jnp.array([1.0, 0.4]))
        fz = jnp.array([fr, fl], jnp.float32)
        ev = _stance_peaks(ev, jnp.array([st_r, st_l]), fz, prev, t, DT, jnp.asarray(True))
        prev = fz
    return ev


def test_peak_time_and_loading_rate_of_a_hand_made_stance():
    # right heel strike at step 1: a slow heel load, then a 2-step forefoot slap at step 5,
    # a second hump; the left leg touches down at step 7 with a gentle load
    rows = [
        (0, 0, 0, 0, 0.0, 0.0),
        (1, 0, 1, 0, 100.0, 0.0),
        (0, 0, 1, 0, 200.0, 0.0),
        (0, 0, 1, 0, 300.0, 0.0),
        (0, 0, 1, 0, 350.0, 0.0),
        (0, 0, 1, 0, 2350.0, 0.0),  # +2000 N in one step: the slap
        (0, 0, 1, 0, 1500.0, 0.0),
        (0, 1, 1, 1, 900.0, 50.0),
        (0, 0, 1, 1, 700.0, 250.0),
        (0, 0, 0, 1, 0.0, 400.0),  # the right leg lifts off; its peak is kept
        (0, 0, 0, 1, 0.0, 380.0),
    ]
    ev = feed(empty(), rows)
    assert int(ev.n) == 2 and list(np.asarray(ev.leg[:2])) == [0, 1]
    assert float(ev.peak_grf[0]) == pytest.approx(2350.0)
    assert float(ev.peak_t[0]) == pytest.approx(4 * DT)  # step 5 - touchdown at step 1
    assert float(ev.loading_rate[0]) == pytest.approx(2000.0 / DT)
    assert float(ev.peak_grf[1]) == pytest.approx(400.0)
    assert float(ev.peak_t[1]) == pytest.approx(2 * DT, rel=1e-4)
    assert float(ev.loading_rate[1]) == pytest.approx(200.0 / DT)
    m = stance_grf_peaks(ev, weight=1000.0, skip=0)
    assert float(m["grf_peak_max_bw"]) == pytest.approx(2.35)
    assert float(m["grf_peak_mean_bw"]) == pytest.approx((2.35 + 0.4) / 2)
    assert float(m["grf_loading_rate_max_bw_s"]) == pytest.approx(2.0 / DT)
    assert int(m["n_stances_measured"]) == 2
    m1 = stance_grf_peaks(ev, weight=1000.0, skip=1)  # the start-up stance left out
    assert float(m1["grf_peak_max_bw"]) == pytest.approx(0.4)


def test_a_full_buffer_stops_measuring_instead_of_overwriting():
    rows = [(1, 0, 1, 0, 500.0, 0.0), (0, 1, 1, 1, 400.0, 100.0), (1, 0, 1, 1, 9000.0, 0.0)]
    ev = feed(empty(E=2), rows)
    assert int(ev.n) == 3 and int(ev.open[0]) == -1  # the third touchdown found no slot
    assert float(ev.peak_grf[0]) == pytest.approx(500.0)  # not overwritten by the 9 kN
    assert float(ev.peak_grf[1]) == pytest.approx(100.0)


def test_fbl_walk_peaks_in_the_rollout_agree_with_a_fine_trace():
    """The in-rollout peak of each stance equals the maximum of the vertical GRF logged at
    every physics step over that stance (log_dt = dt)."""
    model = models.get_model("fbl")
    from jaxgait.presets import load_preset

    _, vec, _ = load_preset("fbl_walk")
    cfg = sim.SimConfig(duration=3.0, log_dt=model.dt)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    tr, ev, sm, _ = sim.make_rollout(model, cfg, batched=False)(model.table.as_jnp(vec), env)
    t, fz = np.asarray(tr.t), np.asarray(tr.grf)[:, :, 1]
    n = int(ev.n)
    for k in range(2, n - 1):
        leg, t0 = int(ev.leg[k]), float(ev.t[k])
        nxt = [float(ev.t[j]) for j in range(k + 1, n) if int(ev.leg[j]) == leg]
        t1 = nxt[0] if nxt else t[-1]
        w = (t > t0 + 0.5 * model.dt) & (t < t1 - 0.5 * model.dt)
        assert float(ev.peak_grf[k]) == pytest.approx(fz[w, leg].max(), rel=1e-5)
    m = jax.tree.map(np.asarray, compute_measures(tr, ev, sm))
    assert float(m["grf_peak_max_bw"]) > float(m["grf_peak_mean_bw"]) > 0.5


def test_human_likeness_of_winter_itself_and_of_a_shifted_copy():
    """A trace whose right leg follows Winter's angles and vertical GRF exactly scores
    grf_corr 1 and no range-of-motion difference; the GRF shifted by 20 % of the cycle
    correlates less; the criteria read them as documented."""
    from jaxgait.analysis import refdata
    from jaxgait.analysis.measures import human_likeness
    from jaxgait.train.objective import criterion_value

    ref, grf = refdata.winter_walking_kinematics(), refdata.winter_walking_grf()
    dt, period, t0 = 0.01, 1.0, 0.5
    t = np.arange(1, 601) * dt
    phase = ((t - t0) % period) / period * 100.0
    fz = np.interp(phase, grf.gait_cycle_pct, grf.mean_bw, period=100.0) * 800.0
    shifted = (
        np.interp((phase + 20.0) % 100.0, grf.gait_cycle_pct, grf.mean_bw, period=100.0) * 800.0
    )
    right = t0 + np.arange(0, 6) * period
    E = 16
    ev = Events(
        t=jnp.asarray(np.pad(right, (0, E - right.size)), jnp.float32),
        leg=jnp.zeros(E, jnp.int32),
        x_td=jnp.zeros(E, jnp.float32),
        x_other=jnp.zeros(E, jnp.float32),
        n=jnp.asarray(right.size, jnp.int32),
    )
    out = {}
    for name, f in (("winter", fz), ("shifted", shifted)):
        g = np.zeros((t.size, 2, 2), np.float32)
        g[:, 0, 1] = f
        tr = sim.trace.Trace(
            t=jnp.asarray(t, jnp.float32),
            qpos=jnp.zeros((t.size, 9)),
            com=jnp.zeros((t.size, 2)),
            com_vel=jnp.zeros((t.size, 2)),
            grf=jnp.asarray(g),
            stance=jnp.zeros((t.size, 2), bool),
            act=jnp.zeros((t.size, 2, 7)),
            stim=jnp.zeros((t.size, 2, 7)),
            energy=jnp.zeros(t.size),
            alive=jnp.ones(t.size, bool),
        )
        out[name] = human_likeness(tr, ev, 800.0, ref.mean_deg, True, ref)
    assert float(out["winter"]["grf_corr"]) > 0.999
    assert float(out["shifted"]["grf_corr"]) < 0.8
    for j in ("hip", "knee", "ankle"):
        assert float(out["winter"][f"rom_{j}_diff_deg"]) == pytest.approx(0.0, abs=1e-4)
    m = {
        "grf_peak_max_bw": jnp.asarray(1.8),
        "grf_peak_mean_bw": jnp.asarray(1.5),
        "rom_knee_diff_deg": jnp.asarray(-5.0),
        "rom_ankle_diff_deg": jnp.asarray(15.0),
        "grf_corr": out["shifted"]["grf_corr"],
        "grf_loading_rate_max_bw_s": jnp.asarray(2100.0),
    }
    assert float(criterion_value("grf_peak", m, {})) == pytest.approx(-0.5)
    assert float(criterion_value("grf_peak_mean", m, {})) == pytest.approx(-0.2)
    assert float(criterion_value("grf_loading_rate", m, {})) == pytest.approx(-2.0)
    m["grf_loading_rate_max_bw_s"] = jnp.asarray(80.0)  # a heel landing: no penalty
    assert float(criterion_value("grf_loading_rate", m, {})) == 0.0
    assert float(criterion_value("rom", m, {})) == pytest.approx(-2.0)
    assert float(criterion_value("grf_corr", m, {})) == float(out["shifted"]["grf_corr"])


def test_corr_floor_is_zero_above_the_floor_and_sums_each_shortfall_below_it():
    """The hinge constraint on the correlations: nothing while every one clears the floor,
    then the sum of the shortfalls (mean-cycle knee 0.1 and GRF 0.3 below it: -0.4)."""
    from jaxgait.train.objective import CORR_FLOOR, CORR_FLOOR_KEYS, criterion_value

    m = {k: jnp.asarray(CORR_FLOOR + 0.01) for k in CORR_FLOOR_KEYS}
    assert float(criterion_value("corr_floor", m, {})) == 0.0
    m["mean_cycle_corr_knee"] = jnp.asarray(CORR_FLOOR - 0.1)
    m["grf_corr"] = jnp.asarray(CORR_FLOOR - 0.3)
    assert float(criterion_value("corr_floor", m, {})) == pytest.approx(-0.4, abs=1e-6)


def test_standard_score_criteria_of_winter_an_offset_copy_and_no_cycle():
    """Wang's standard score as a criterion: 0 for Winter's own curves, -1 for every joint
    one human SD off (an offset a correlation does not see), capped for no full cycle."""
    from jaxgait.analysis import refdata
    from jaxgait.analysis.measures import SCORE_UNDEFINED, standard_scores
    from jaxgait.train.objective import STANDARD_SCORE_CAP, criterion_value

    ref = refdata.winter_walking_kinematics()
    mean, sd = np.asarray(ref.mean_deg), np.asarray(ref.sd_deg)
    for curves, want in ((mean, 0.0), (mean + sd, 1.0), (mean - 2 * sd, 2.0)):
        z = np.asarray(standard_scores(jnp.asarray(curves, jnp.float32), ref))
        np.testing.assert_allclose(z, want, atol=1e-5)
        m = {
            "standard_score": jnp.asarray(z.mean()),
            **{f"standard_score_{j}": jnp.asarray(z[i]) for i, j in enumerate(JOINTS)},
        }
        for name in ("standard_score", *(f"standard_score_{j}" for j in JOINTS)):
            assert float(criterion_value(name, m, {})) == pytest.approx(-want, abs=1e-5)
    fell = {"standard_score": jnp.asarray(SCORE_UNDEFINED)}
    assert float(criterion_value("standard_score", fell, {})) == -STANDARD_SCORE_CAP


def test_evaluate_logs_at_the_interval_asked_and_refuses_a_fraction_of_a_step():
    from jaxgait import evaluation

    run = evaluation.run("fbl_walk", duration=0.2, log_dt=0.001)
    assert np.asarray(run.trace.t).shape == (200,)  # 0.2 s at 1 ms
    with pytest.raises(evaluation.EvaluateError, match="whole multiple of the physics step"):
        evaluation.run("fbl_walk", duration=0.2, log_dt=0.0007)
