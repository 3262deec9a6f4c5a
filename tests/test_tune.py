"""Training the command law (jaxgait.spinal.tune) and the control experiments' commands
(range, climb): the tracking cost on hand-made paths, the random profiles, and each command
end to end at a tiny size."""

import json

import jax
import numpy as np
import pytest

from jaxgait.spinal.auto import moving_speed
from jaxgait.spinal.record import SpinalError
from jaxgait.spinal.tune import Tuning, random_profiles, tracking_cost


def _path(speed_of_t, total=20.0, dt=0.1):
    t = np.arange(0.0, total + 1e-9, dt)
    v = np.array([speed_of_t(x) for x in t])
    x = np.concatenate([[0.0], np.cumsum(v[1:] * dt)])
    return t, x


def test_moving_speed_of_a_constant_speed_path():
    t, x = _path(lambda _: 1.2)
    v = moving_speed(t, x, 0.1)
    assert np.all(np.isnan(v[:10])) and np.allclose(v[10:], 1.2)


def test_tracking_cost_on_hand_made_paths():
    tc = Tuning(segments=2, segment_s=10.0, settle_s=3.0, fall_penalty=1.0)
    prof = np.array([[1.0, 1.4]])
    # exact tracking of the profile, changed sharply at 10 s: zero error after settling
    t, x = _path(lambda s: 1.0 if s < 10 else 1.4)
    alive = np.ones_like(t, bool)
    cost, rms = tracking_cost(t[None], x[None], alive[None], prof, tc)
    assert rms[0] == pytest.approx(0.0, abs=1e-9) and cost[0] == pytest.approx(0.0, abs=1e-9)
    # 0.1 m/s too slow everywhere: RMS 0.1
    t, x = _path(lambda s: 0.9 if s < 10 else 1.3)
    cost, rms = tracking_cost(t[None], x[None], alive[None], prof, tc)
    assert rms[0] == pytest.approx(0.1, abs=1e-9)
    # a fall at 5 s: three quarters of the profile lost, penalty 0.75 on top of the RMS
    dead = t > 5.0
    cost, rms = tracking_cost(t[None], x[None], (~dead)[None], prof, tc)
    assert rms[0] == pytest.approx(0.1, abs=1e-9)
    assert cost[0] == pytest.approx(0.1 + 0.75, abs=1e-6)


def test_random_profiles_lie_in_the_range_and_depend_on_the_key():
    tc = Tuning(v_range=(0.8, 1.6), segments=4)
    a = random_profiles(jax.random.PRNGKey(0), 50, tc)
    b = random_profiles(jax.random.PRNGKey(1), 50, tc)
    assert a.shape == (50, 4) and a.min() >= 0.8 and a.max() <= 1.6
    assert not np.allclose(a, b)
    np.testing.assert_array_equal(a, random_profiles(jax.random.PRNGKey(0), 50, tc))


def test_bad_tuning_settings_are_refused():
    with pytest.raises(SpinalError, match="v_range"):
        Tuning(v_range=(1.5, 1.0))
    with pytest.raises(SpinalError, match="settle_s"):
        Tuning(segment_s=5.0, settle_s=5.0)
    with pytest.raises(SpinalError, match="nothing to tune"):
        Tuning(tune=())
    from jaxgait.spinal.tune import Tasks

    with pytest.raises(SpinalError, match="unknown gains"):
        Tasks("3fbl_auto", Tuning(tune=("k_zz",)))
    with pytest.raises(SpinalError, match="no v_target"):
        Tasks("3fbl_walk", Tuning())
    with pytest.raises(SpinalError, match="grade in"):
        Tuning(grade=0.8)


def test_tracking_on_a_grade_runs_on_ground_that_rises_to_it():
    """``Tuning(grade=g)``: the tracking ground is level to 2 m, then rises to grade g over
    ``grade_ramp_m`` and keeps it (the grade anchors' training ground)."""
    from jaxgait.spinal.tune import Tasks
    from jaxgait.world.terrain import Terrain

    t = Tasks("3fbl_auto", Tuning(grade=0.1, grade_ramp_m=8.0)).track_env.terrain
    h = [float(Terrain.height(t, x)) for x in (1.0, 10.0, 20.0, 30.0)]
    assert h[0] == 0.0
    assert h[1] == pytest.approx(0.5 * 0.1 / 8.0 * 8.0**2, rel=1e-3)  # the ramp's rise
    np.testing.assert_allclose(np.diff(h[1:]), 1.0, rtol=1e-3)  # 10 % over 10 m
    assert float(Terrain.height(Tasks("3fbl_auto", Tuning()).track_env.terrain, 20.0)) == 0.0


@pytest.mark.slow
def test_tune_range_and_climb_commands_run_at_a_tiny_size(tmp_path):
    from jaxgait.spinal.cli import main

    rc = main(
        [
            "tune", "3fbl_auto", "--name", "t_tuned", "--gains", "k_p,k_i",
            "--segments", "2", "--segment", "3", "--settle", "1", "--profiles", "1",
            "--slope", "2", "--popsize", "2", "--generations", "1", "--held-out", "1",
            "--out-dir", str(tmp_path / "m"), "--out", str(tmp_path / "t"),
        ]
    )  # fmt: skip
    assert rc == 0
    doc = json.loads((tmp_path / "m" / "t_tuned.json").read_text())
    rep = json.loads((tmp_path / "t" / "tuning_t_tuned.json").read_text())
    assert doc["model"] == "t_tuned" and doc["tuning"]["chosen"] in ("start", "best", "mean")
    assert len(rep["history"]) == 2 and set(rep["held_out"]) == {"start", "trained"}
    # only the named gains moved
    from jaxgait.presets import load_preset

    _, start, _ = load_preset("3fbl_auto")
    names = list(doc["params"])
    for k, n in enumerate(names):
        if n not in ("k_p", "k_i"):
            assert doc["params"][n] == pytest.approx(float(start[k]))
    rc = main(
        ["range", "3fbl_auto", "--targets", "1.3", "--duration", "3", "--measure", "1",
         "--out", str(tmp_path / "r")]
    )  # fmt: skip
    assert rc == 0
    r = json.loads((tmp_path / "r" / "speed_range.json").read_text())["models"]["3fbl_auto"]
    assert len(r["held"]) == 1 and r["fell"] == [False]
    rc = main(
        ["climb", "fbl_walk", "--seeds", "1", "--duration", "2", "--out", str(tmp_path / "c")]
    )
    assert rc == 0
    c = json.loads((tmp_path / "c" / "climb.json").read_text())
    assert c["fbl_walk"]["slope_distance_m"] > 0
    assert main(["range", "3fbl_walk", "--out", str(tmp_path / "x")]) == 2  # no v_target
