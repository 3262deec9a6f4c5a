"""Systematic searches of the control vector (thesis 7.3.2-7.3.3): the grid's schedules, the
per-setting measuring windows and the speed-law fit (eq. 7.1)."""

import numpy as np
import pytest

from jaxgait import models
from jaxgait.sim.trace import Events, Trace
from jaxgait.spinal.record import SpinalError
from jaxgait.spinal.search import (
    Search,
    column_schedules,
    fit_speed_law,
    window_measures,
    windows,
)


def test_windows_are_the_last_seconds_of_each_setting():
    s = Search("O_INBAS", (-0.1, 0.0, 0.1), "omega", (0.8,), hold_s=10.0, measure_s=4.0)
    assert windows(s) == [(16.0, 20.0), (26.0, 30.0), (36.0, 40.0)]  # after a 10 s warm-up
    s = Search("O_INBAS", (-0.1, 0.0), "omega", (0.8,), measure_s=4.0, warmup_s=0.0)
    assert windows(s) == [(6.0, 10.0), (16.0, 20.0)]
    with pytest.raises(SpinalError, match="measure_s"):
        Search("a", (1.0,), "b", (1.0,), hold_s=2.0, measure_s=3.0)
    with pytest.raises(SpinalError, match="differ"):
        Search("a", (1.0,), "a", (1.0,))


def test_column_schedules_step_through_x_per_lane():
    cmds = models.get_model("fbl_net").controller.commands  # A_INSEN, O_INSEN, lean_offset
    s = Search("A_INSEN", (0.9, 1.0, 1.1), "O_INSEN", (-0.01, 0.02), hold_s=5.0, warmup_s=2.0)
    b = column_schedules(cmds, s)
    assert b.values.shape == (2, 4, 3) and b.t.shape == (2, 4)
    lane1 = type(b)(t=b.t[1], values=b.values[1], interp=b.interp)
    np.testing.assert_allclose(np.asarray(lane1.at(1.0)), [1.0, 0.0, 0.0], atol=1e-7)  # defaults
    np.testing.assert_allclose(np.asarray(lane1.at(9.0)), [1.0, 0.02, 0.0], atol=1e-7)
    np.testing.assert_allclose(np.asarray(lane1.at(6.999)), [0.9, 0.02, 0.0], atol=1e-7)
    with pytest.raises(SpinalError, match="not one of this model's"):
        column_schedules(cmds, Search("omega", (1.0,), "O_INSEN", (0.0,)))


def test_a_third_command_repeats_the_grid_for_each_of_its_values():
    cmds = models.get_model("3fbl_walk").controller.commands
    names = [c.name for c in cmds]
    s = Search(
        "O_INBAS", (-0.01, 0.01), "A_INCPG", (0.8, 1.2, 1.6), hold_s=5.0, warmup_s=0.0,
        z="omega", z_values=(0.7, 1.1),
    )  # fmt: skip
    b = column_schedules(cmds, s)
    assert b.values.shape[0] == 6  # z outer, y inner
    iw, ia, io = names.index("omega"), names.index("A_INCPG"), names.index("O_INBAS")
    for lane, (w, a) in enumerate([(w, a) for w in (0.7, 1.1) for a in (0.8, 1.2, 1.6)]):
        one = type(b)(t=b.t[lane], values=b.values[lane], interp=b.interp)
        v = np.asarray(one.at(7.0))
        assert v[iw] == pytest.approx(w) and v[ia] == pytest.approx(a)
        assert v[io] == pytest.approx(0.01)
    with pytest.raises(SpinalError, match="third command"):
        Search("O_INBAS", (0.0,), "omega", (1.0,), z="omega", z_values=(1.0,))


def _synthetic(speed=(1.0, 1.5), fall_at=None):
    """A 20 s straight walk logged like a rollout; its last row is "done" (alive False), as
    at a rollout's time limit."""
    dt = 0.01
    t = np.arange(1, 2001) * dt  # 20 s, two settings of 10 s
    v = np.where(t <= 10, speed[0], speed[1])
    x = np.cumsum(v * dt)
    alive = t < (20.0 if fall_at is None else fall_at)
    n = t.size
    stance = np.stack([np.sin(2 * np.pi * t) > -0.3, np.sin(2 * np.pi * t + np.pi) > -0.3], 1)
    trace = Trace(
        t=t,
        qpos=np.zeros((n, 9)),
        com=np.stack([x, np.ones(n)], 1),
        com_vel=np.zeros((n, 2)),
        grf=np.zeros((n, 2, 2)),
        stance=stance,
        act=np.zeros((n, 2, 7)),
        stim=np.zeros((n, 2, 7)),
        energy=300.0 * x,
        alive=alive,
    )
    td = np.arange(0.25, 20, 0.5)  # alternating legs, right leg every 1 s
    events = Events(
        t=td,
        leg=np.arange(td.size) % 2,
        x_td=np.interp(td, t, x) + 0.3,
        x_other=np.interp(td, t, x) - 0.3 + 0.01 * (np.arange(td.size) % 3),
        n=np.asarray(td.size),
    )
    return trace, events


def test_window_measures_on_a_synthetic_walk():
    trace, events = _synthetic()
    m = window_measures(trace, events, [(6.0, 10.0), (16.0, 20.0)])
    np.testing.assert_allclose(m["speed_mps"], [1.0, 1.5], rtol=1e-2)
    np.testing.assert_allclose(m["energy_J_per_m"], [300.0, 300.0], rtol=1e-6)
    np.testing.assert_allclose(m["cycle_length_s"], [1.0, 1.0], rtol=1e-9)
    frac = np.mean(np.abs(np.sin(2 * np.pi * np.linspace(0, 1, 10001))) < 0.3)  # both down
    np.testing.assert_allclose(m["double_stance_fraction"], [frac, frac], atol=0.02)
    assert np.all(m["step_length_var_m2"] > 0)
    fallen = window_measures(*_synthetic(fall_at=15.0), [(6.0, 10.0), (16.0, 20.0)], 15.0)
    assert np.isfinite(fallen["speed_mps"][0]) and np.isnan(fallen["speed_mps"][1])


def test_speed_law_recovers_known_coefficients():
    xv, yv = np.linspace(-0.1, 0.1, 7), np.linspace(0.7, 1.2, 6)
    X, Y = np.meshgrid(xv, yv)
    S = 4.40 * X + 0.57 * Y + 0.63  # thesis eq. 7.1
    S[0, :3] = np.nan  # fallen settings are left out
    law = fit_speed_law(xv, yv, S)
    assert (law["a1"], law["a2"], law["a3"]) == pytest.approx((4.40, 0.57, 0.63), abs=1e-9)
    assert law["n"] == 39 and law["rms"] < 1e-9
    with pytest.raises(SpinalError, match="at least 3"):
        fit_speed_law(xv[:1], yv[:2], np.array([[1.0], [np.nan]]))


@pytest.mark.slow
def test_search_command_runs_at_a_tiny_size(tmp_path, capsys):
    import json

    from jaxgait.spinal.cli import main

    args = ["search", "fblnet_walk", "--x", "A_INSEN=0.95,1.0", "--y", "O_INSEN=0.0"]
    args += ["--hold", "1.5", "--measure", "1", "--warmup", "0", "--out", str(tmp_path)]
    assert main(args) == 0
    res = json.loads((tmp_path / "search_A_INSEN_O_INSEN.json").read_text())
    speed = np.asarray(res["grid"]["speed_mps"], float)
    assert speed.shape == (1, 2) and np.all(np.isfinite(speed)) and np.all(speed > 0.5)
    assert (tmp_path / "search_A_INSEN_O_INSEN.png").is_file()


def test_map_commands_follow_the_model_and_refuse_what_it_lacks():
    from jaxgait.spinal.cli_control import map_commands

    three = {"A_INSEN", "O_INSEN", "A_INBAS", "O_INBAS", "A_INCPG", "O_INCPG", "omega"}
    assert map_commands(three) == ["O_INBAS", "O_INCPG", "A_INBAS", "A_INCPG"]
    minus = {"A_INSEN", "O_INSEN", "A_INBAS", "O_INBAS", "lean_offset"}
    assert map_commands(minus) == ["O_INBAS", "A_INBAS"]
    assert map_commands({"A_INSEN", "O_INSEN", "lean_offset"}) == ["O_INSEN", "A_INSEN"]
    assert map_commands(minus, "A_INSEN, O_INBAS") == ["A_INSEN", "O_INBAS"]
    with pytest.raises(SpinalError, match="has no A_INCPG"):
        map_commands(minus, "A_INBAS,A_INCPG")
    with pytest.raises(SpinalError, match="not mappable"):
        map_commands(minus, "A_INBAS,lean_offset")
    with pytest.raises(SpinalError, match="two different"):
        map_commands(minus, "A_INBAS,A_INBAS")


def test_maps_of_a_model_without_a_cpg_have_no_omega_rows(tmp_path):
    import json

    from jaxgait.spinal.cli import main

    args = ["maps", "fblminus_walk", "--n", "2", "--hold", "1.5", "--measure", "1"]
    args += ["--warmup", "0", "--out", str(tmp_path)]
    assert main(args) == 0
    res = json.loads((tmp_path / "maps.json").read_text())
    assert [(p["x"], p["y"]) for p in res["pairs"]] == [("O_INBAS", "A_INBAS")]
    assert "z" not in res["pairs"][0] and "omega" not in res["ranges"]
    pair = res["pairs"][0]
    speed = np.asarray(pair["grid"]["speed_mps"], float)
    assert speed.shape == (2, 2) and np.all(speed[np.isfinite(speed)] > 0.5)
    # a blank cell is a column that fell; a column that did not fall has every setting
    for row, fell in zip(speed, pair["fell"], strict=True):
        assert fell or np.all(np.isfinite(row))
    assert np.isfinite(speed).sum() >= 2
    assert (tmp_path / "maps_speed_mps.png").is_file()
