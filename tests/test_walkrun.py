"""Walk-run (thesis 7.3.2): the ramp schedule, the per-window gait measures, the command."""

import json

import numpy as np
import pytest

from jaxgait import models
from jaxgait.control.commands import as_dict
from jaxgait.spinal.record import SpinalError
from jaxgait.spinal.walkrun import WalkRun, walkrun_schedule, window_gait


def test_the_schedule_ramps_up_holds_and_comes_back():
    wr = WalkRun({"A_INBAS": (1.0, 1.6), "lean_offset": (0.0, 0.1)}, 10, 20, 10, 20, 10)
    cmds = models.get_model("3fbl_walk").controller.commands
    sched = walkrun_schedule(cmds, wr)
    at = lambda t: {k: float(v) for k, v in as_dict(cmds, sched.at(t)).items()}
    assert wr.duration == 70
    for t, a, lean in ((5, 1.0, 0.0), (20, 1.3, 0.05), (35, 1.6, 0.1), (50, 1.3, 0.05), (65, 1, 0)):
        got = at(float(t))
        assert got["A_INBAS"] == pytest.approx(a) and got["lean_offset"] == pytest.approx(lean)
        assert got["A_INCPG"] == 1.0  # not driven: its default
    assert [wr.phase_of(t) for t in (5, 15, 35, 45, 65)] == list(
        ("walk", "ramp up", "hold", "ramp down", "walk again")
    )
    with pytest.raises(SpinalError, match="not this model's"):
        walkrun_schedule(cmds, WalkRun({"A_NOPE": (1, 2)}))
    with pytest.raises(SpinalError, match="durations"):
        WalkRun(walk_s=-1)
    with pytest.raises(SpinalError, match="walking value, running value"):
        WalkRun({"A_INBAS": (1.0,)})


def test_window_measures_of_a_walk_then_a_run():
    # 4 s at 1 ms: 2 s of walking (each leg 60 % stance, so 20 % double stance, 1 Hz), then
    # 2 s of running (each leg 30 % stance: 40 % flight, 2 Hz); the CoM at 1.2 then 3 m/s
    dt = 0.001
    t = np.arange(1, 4001) * dt
    period = np.where(t <= 2.0, 1.0, 0.5)
    duty = np.where(t <= 2.0, 0.6, 0.3)
    right = (t % period) / period < duty
    left = ((t + period / 2) % period) / period < duty
    stance = np.stack([right, left], 1)
    x = np.where(t <= 2.0, 1.2 * t, 2.4 + 3.0 * (t - 2.0))
    td = np.concatenate([np.arange(0, 2.0, 1.0), np.arange(2.0, 4.0, 0.5)]) + dt
    w = window_gait(t, x, stance, td, window_s=2.0)
    assert w["t_end_s"].tolist() == [2.0, 4.0]
    assert w["speed_mps"] == pytest.approx([1.2, 3.0], rel=1e-3)
    assert w["double_stance_fraction"] == pytest.approx([0.2, 0.0], abs=5e-3)
    assert w["flight_fraction"] == pytest.approx([0.0, 0.4], abs=5e-3)
    assert w["cycle_frequency_hz"] == pytest.approx([1.0, 2.0], rel=1e-6)
    # a fall at 3 s blanks the window that ends after it
    w = window_gait(t, x, stance, td, window_s=2.0, fell_at=3.0)
    assert np.isfinite(w["speed_mps"][0]) and np.isnan(w["speed_mps"][1])
    # a trace cut by a fall still gives every window of the requested duration
    w = window_gait(t[:2500], x[:2500], stance[:2500], td, 1.0, fell_at=2.5, duration=4.0)
    assert w["t_end_s"].tolist() == [1.0, 2.0, 3.0, 4.0]
    assert np.isfinite(w["speed_mps"][:2]).all() and np.isnan(w["speed_mps"][2:]).all()


@pytest.mark.slow
def test_walkrun_command_runs_at_a_tiny_size(tmp_path, capsys):
    from jaxgait.spinal.cli import main

    out = tmp_path / "wr"
    args = ["walkrun", "3fbl_walk", "--phases", "1,1,0.5,1,0.5", "--window", "0.5"]
    assert main(args + ["--drive", "A_INBAS=1:1.3", "--out", str(out)]) == 0
    r = json.loads((out / "walkrun_3fbl_walk.json").read_text())
    assert r["drive"] == {"A_INBAS": [1.0, 1.3]} and len(r["windows"]["speed_mps"]) == 8
    assert r["windows"]["commands"]["A_INBAS"][3] == pytest.approx(1.3)  # end of the hold
    assert 1.0 < r["distance_m"] < 8.0 and not r["fell"]  # 4 s of walking
    assert (out / "walkrun_3fbl_walk.png").stat().st_size > 0
    assert main(["walkrun", "3fbl_walk", "--drive", "A_INBAS"]) == 2
    assert "NAME=WALK:RUN" in capsys.readouterr().err
