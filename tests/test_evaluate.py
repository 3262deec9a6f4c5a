"""Presets, trajectory CSV, plots and the evaluate command (one short simulation)."""

from __future__ import annotations

import contextlib
import io
import json
import math

import jax
import numpy as np
import pytest

from jaxgait import evaluate as ev
from jaxgait import presets
from jaxgait.analysis import plots, trajectory_io
from jaxgait.control.fbl import FBL
from jaxgait.core.params import save_preset
from jaxgait.muscles.mtu import MUSCLES
from jaxgait.sim.trace import Events, Summary, Trace
from jaxgait.world import envs, scene

MASS = 80.0


# ----------------------------------------------------------------------------- helpers


def write_json(path, doc):
    path.write_text(json.dumps(doc))
    return path


def fbl_doc(**params):
    d = {n: float(v) for n, v in zip(FBL.names, FBL.init, strict=True)}
    d.update(params)
    return {"model": "fbl", "table": "fbl", "params": d}


def hand_trace(T=120, dt=0.01, alive_rows=None, right_td=(0.1, 0.6, 1.1), left_td=(0.35, 0.85)):
    """A small synthetic rollout: sinusoidal joints, walking CoM, touchdowns as given."""
    t = dt * np.arange(1, T + 1)
    ph = 2 * np.pi * t / 0.5
    qpos = np.zeros((T, 9), np.float32)
    qpos[:, 0] = 1.2 * t
    qpos[:, 1] = 0.02 * np.sin(2 * ph)
    qpos[:, 2] = 0.05
    for leg, sh in ((0, 0.0), (1, np.pi)):
        qpos[:, 3 + 3 * leg] = np.deg2rad(15 + 20 * np.sin(ph + sh))
        qpos[:, 4 + 3 * leg] = np.deg2rad(30 + 30 * np.sin(ph + sh + 1))
        qpos[:, 5 + 3 * leg] = np.deg2rad(5 * np.sin(ph + sh + 2))
    grf = np.zeros((T, 2, 2), np.float32)
    grf[:, 0, 1] = MASS * 9.81 * np.clip(np.sin(ph), 0, None)
    grf[:, 1, 1] = MASS * 9.81 * np.clip(-np.sin(ph), 0, None)
    grf[:, :, 0] = 0.1 * grf[:, :, 1]
    act = np.stack([np.full((T, 7), 0.1), np.full((T, 7), 0.2)], 1).astype(np.float32)
    act[:, 0, :] += 0.05 * (1 + np.sin(ph))[:, None]
    alive = np.ones(T, bool)
    if alive_rows is not None:
        alive[alive_rows:] = False
    trace = Trace(
        t=t.astype(np.float32),
        qpos=qpos,
        com=np.stack([qpos[:, 0], qpos[:, 1] + 0.9], 1),
        com_vel=np.stack([np.full(T, 1.2), np.zeros(T)], 1).astype(np.float32),
        grf=grf,
        stance=np.stack([np.sin(ph) > -0.2, np.sin(ph) < 0.2], 1),
        act=act,
        stim=act,
        energy=(100.0 * t).astype(np.float32),
        alive=alive,
    )
    tds = sorted([(x, 0) for x in right_td] + [(x, 1) for x in left_td])
    E = 8
    ev_t = np.zeros(E, np.float32)
    ev_leg = np.zeros(E, np.int32)
    for i, (x, leg) in enumerate(tds):
        ev_t[i], ev_leg[i] = x, leg
    events = Events(
        t=ev_t,
        leg=ev_leg,
        x_td=1.2 * ev_t + 0.3,
        x_other=1.2 * ev_t - 0.3,
        n=np.int32(len(tds)),
    )
    t_end = float(t[alive][-1]) if alive.any() else 0.0
    summary = Summary(
        duration=np.float32(t_end),
        distance=np.float32(1.2 * t_end),
        fell=np.bool_(alive_rows is not None),
        energy=np.float32(100 * t_end),
        trunk_lean_sum=np.float32(0.05 * t_end),
        mass=np.float32(MASS),
    )
    return trace, events, summary


# ----------------------------------------------------------------------------- presets


def test_load_preset_round_trip(tmp_path):
    p = tmp_path / "ok.json"
    vec = FBL.init.copy()
    vec[0] = 1.3
    save_preset(p, "fbl", FBL, vec, description="test")
    model, got, doc = presets.load_preset(p)
    assert model == "fbl" and doc["description"] == "test"
    np.testing.assert_allclose(got, vec)
    # a results folder holding best.json
    (tmp_path / "res").mkdir()
    save_preset(tmp_path / "res" / "best.json", "fbl", FBL, vec)
    np.testing.assert_allclose(presets.load_preset(tmp_path / "res")[1], vec)
    assert isinstance(presets.list_presets(), list)


def test_preset_missing_file(tmp_path):
    with pytest.raises(presets.PresetError, match="not found.*available presets"):
        presets.load_preset(tmp_path / "nope.json")
    with pytest.raises(presets.PresetError, match="no_such_preset.*available presets"):
        presets.load_preset("no_such_preset")
    with pytest.raises(presets.PresetError, match="no best.json"):
        presets.load_preset(tmp_path)


def test_preset_bad_json(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{"model": "fbl",\n "params": {"k_bw": 1.2,,}}\n')
    with pytest.raises(presets.PresetError) as e:
        presets.load_preset(p)
    assert "bad.json" in str(e.value) and "line 2" in str(e.value)


def test_preset_no_params(tmp_path):
    p = write_json(tmp_path / "np.json", {"model": "fbl"})
    with pytest.raises(presets.PresetError, match=r"np\.json.*no 'params'"):
        presets.load_preset(p)


def test_preset_unknown_parameter(tmp_path):
    p = write_json(tmp_path / "unk.json", fbl_doc(G_SOLL=1.0))
    with pytest.raises(presets.PresetError) as e:
        presets.load_preset(p)
    msg = str(e.value)
    assert "unk.json" in msg and "G_SOLL" in msg and "did you mean G_SOL" in msg


def test_preset_missing_parameter_and_partial(tmp_path):
    doc = fbl_doc()
    del doc["params"]["G_VAS"], doc["params"]["k_d"]
    p = write_json(tmp_path / "miss.json", doc)
    with pytest.raises(presets.PresetError) as e:
        presets.load_preset(p)
    assert "miss.json" in str(e.value) and "G_VAS" in str(e.value) and "k_d" in str(e.value)
    doc["partial"] = True
    p = write_json(tmp_path / "partial.json", doc)
    _, vec, _ = presets.load_preset(p)
    assert vec[FBL.index("G_VAS")] == FBL.init[FBL.index("G_VAS")]


def test_preset_out_of_range_and_not_number(tmp_path):
    p = write_json(tmp_path / "range.json", fbl_doc(G_SOL=5.0))
    with pytest.raises(presets.PresetError) as e:
        presets.load_preset(p)
    assert "range.json" in str(e.value) and "G_SOL=5" in str(e.value)
    p = write_json(tmp_path / "str.json", fbl_doc(k_bw="big"))
    with pytest.raises(presets.PresetError, match=r"str\.json.*'k_bw'"):
        presets.load_preset(p)


def test_preset_taga_pass_through_and_unknown_model(tmp_path):
    p = write_json(tmp_path / "t.json", {"model": "taga", "params": {"anything": [1, 2]}})
    model, vec, doc = presets.load_preset(p)
    assert model == "taga" and vec.size == 0 and doc["params"]["anything"] == [1, 2]
    p = write_json(tmp_path / "x.json", {"model": "no_such_model", "params": {}})
    with pytest.raises(presets.PresetError, match="no_such_model.*not available"):
        presets.load_preset(p)


# ----------------------------------------------------------------------------- CSV


def test_trajectory_csv_round_trip(tmp_path, fbl_model):
    trace, events, summary = hand_trace(T=40, alive_rows=25)
    path = trajectory_io.write_trajectory_csv(tmp_path / "traj.csv", trace, summary, fbl_model)
    text = path.read_text()
    assert text.startswith("# jaxgait trajectory")
    cols = [c[0] for c in trajectory_io.trajectory_columns(MUSCLES)]
    for c in cols:  # every column is documented in the header block and the module doc
        assert f"#   {c} [" in text
        assert (c if not c.startswith("act_") else "act_<M>") in trajectory_io.__doc__
    d = trajectory_io.read_trajectory_csv(path)
    assert list(d) == cols
    assert all(v.shape == (25,) for v in d.values())
    np.testing.assert_allclose(d["time_s"], trace.t[:25], rtol=1e-6)
    np.testing.assert_allclose(d["knee_l_deg"], np.rad2deg(trace.qpos[:25, 7]), atol=1e-4)
    np.testing.assert_allclose(d["trunk_lean_deg"], np.rad2deg(0.05), atol=1e-4)
    np.testing.assert_allclose(d["grf_z_r_bw"], trace.grf[:25, 0, 1] / (MASS * 9.81), atol=1e-6)
    np.testing.assert_allclose(d["act_TA_l"], trace.act[:25, 1, 6], atol=1e-7)
    np.testing.assert_array_equal(d["stance_l"], trace.stance[:25, 1])
    assert d["stance_r"].dtype == bool
    np.testing.assert_allclose(d["energy_J"], trace.energy[:25], rtol=1e-6)
    assert not list(tmp_path.glob(".*tmp"))  # atomic write left no temporary file
    # the root and angle columns give back the MJCF qpos (replay in a scene)
    np.testing.assert_allclose(scene.trajectory_qpos(d), trace.qpos[:25], atol=1e-6)


# ----------------------------------------------------------------------------- plots


@pytest.mark.parametrize("case", ["cycles", "fell_early"])
def test_plots_hand_made(tmp_path, fbl_model, case):
    if case == "cycles":
        trace, events, summary = hand_trace()
    else:  # fell after 0.3 s with one right touchdown: no full cycle
        trace, events, summary = hand_trace(alive_rows=30, right_td=(0.1,), left_td=(0.25,))
    paths = plots.plot_all(tmp_path / case, trace, events, summary, fbl_model, n_cycles=3)
    assert set(paths) == {"joint_angles", "grf", "activations", "stick_figure"}
    for p in paths.values():
        assert p.is_file() and p.stat().st_size > 5000


def test_stick_figure_draws_env_terrain(tmp_path, fbl_model):
    trace, events, _ = hand_trace()
    slope = envs.make_env(
        envs.get_env_config("slope_up", start=0.0, grade=0.2), jax.random.PRNGKey(0)
    )
    flat = plots.plot_stick_figure(tmp_path / "flat.png", trace, events, fbl_model)
    up = plots.plot_stick_figure(tmp_path / "up.png", trace, events, fbl_model, terrain=slope)
    same = plots.plot_stick_figure(
        tmp_path / "up2.png", trace, events, fbl_model, terrain=slope.terrain
    )
    assert up.read_bytes() == same.read_bytes()  # an Env draws its terrain
    assert up.read_bytes() != flat.read_bytes()


def test_plots_no_alive_rows(tmp_path, fbl_model):
    trace, events, summary = hand_trace(T=20, alive_rows=0, right_td=(), left_td=())
    p = plots.plot_stick_figure(tmp_path / "s.png", trace, events, fbl_model)
    assert p.is_file()


# ----------------------------------------------------------------------------- CLI errors


def test_main_bad_inputs(tmp_path, capsys):
    good = tmp_path / "good.json"
    save_preset(good, "fbl", FBL, FBL.init)
    cases = [
        (["no_such_preset_xyz", "--json"], "no_such_preset_xyz"),
        ([str(good), "--env", "moon"], "moon"),
        ([str(good), "--duration", "-1"], "duration"),
        ([str(good), "--model", "fblplus"], "fblplus"),
        ([str(good), "--model", "taga"], "is for model 'fbl'"),
        ([str(good), "--save-trajectory", str(tmp_path / "nodir" / "t.csv")], "nodir"),
        ([str(good), "--save-scene", str(tmp_path / "nodir" / "s.xml")], "--save-scene"),
        ([str(good), "--save-scene", str(tmp_path)], "is a folder"),
        ([str(good), "--env", "weight_support", "--env-set", "fractio=0.2"], "valid fields"),
        ([str(good), "--env", "weight_support", "--env-set", "fraction=1.5"], "fraction"),
        ([str(good), "--env", "weight_support", "--env-set", "fraction"], "FIELD=VALUE"),
    ]
    for argv, needle in cases:
        assert ev.main(argv) == 2, argv
        out, errtxt = capsys.readouterr()
        assert out == "" and needle in errtxt and "Traceback" not in errtxt, (argv, errtxt)


def test_main_taga_dispatch(tmp_path, capsys, monkeypatch):
    import jaxgait.taga as taga

    capsys.readouterr()  # drop anything printed while importing
    seen = {}

    def fake(preset, duration, env, slope):
        seen.update(preset=preset, duration=duration, env=env, slope=slope)
        return {"distance_m": np.float32(2.5), "fell": np.bool_(False), "speed": float("nan")}

    monkeypatch.setattr(taga, "evaluate_preset", fake, raising=False)
    p = write_json(tmp_path / "taga.json", {"model": "taga", "params": {"u0": 5.0}})
    assert ev.main([str(p), "--json", "--duration", "2"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["distance_m"] == 2.5 and rep["fell"] is False and rep["speed"] is None
    assert rep["model"] == "taga" and seen["duration"] == 2.0 and seen["env"] == "flat"
    assert ev.main([str(p), "--json", "--env", "slope_down"]) == 0
    assert seen["env"] == "slope" and seen["slope"] == -0.05
    assert ev.main([str(p), "--env", "wavy"]) == 2
    assert ev.main([str(p), "--save-scene", str(tmp_path / "s.xml")]) == 2
    assert "FBL models only" in capsys.readouterr().err
    assert seen["preset"]["params"] == {"u0": 5.0}
    monkeypatch.delattr(taga, "evaluate_preset")
    assert ev.main([str(p)]) == 2
    assert "evaluate_preset is not available" in capsys.readouterr().err


def test_json_safe():
    assert ev.json_safe({"a": np.float32(np.nan), "b": np.bool_(True), "c": np.int32(3)}) == {
        "a": None,
        "b": True,
        "c": 3,
    }


# ----------------------------------------------------------------------------- end to end


@pytest.fixture(scope="module")
def e2e(tmp_path_factory):
    """One short simulation through the command line, reused by the checks below."""
    d = tmp_path_factory.mktemp("e2e")
    preset = d / "init.json"
    save_preset(preset, "fbl", FBL, FBL.init, description="table init values")
    out = io.StringIO()
    argv = [
        str(preset),
        "--json",
        "--duration",
        "0.3",
        "--save-trajectory",
        str(d / "traj.csv"),
        "--plots",
        str(d / "plots"),
        "--save-scene",
        str(d / "scene.xml"),
    ]
    with contextlib.redirect_stdout(out):
        code = ev.main(argv)
    return code, out.getvalue(), d


def test_env_set_reaches_the_environment(e2e, capsys):
    """``--env weight_support --env-set fraction=0.5``: the report names the overrides, and
    the harness carries weight: the supported body presses on the ground less over 0.3 s."""
    _, text, d = e2e
    preset = str(d / "init.json")
    argv = [preset, "--json", "--duration", "0.3", "--env", "weight_support"]
    assert ev.main([*argv, "--env-set", "fraction=0.5"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["env"] == "weight_support" and rep["env_overrides"] == {"fraction": 0.5}
    assert "env_overrides" not in json.loads(text)
    grf_z = {}
    for f in (0.0, 0.5):
        r = ev.run(preset, env="weight_support", duration=0.3, env_overrides={"fraction": f})
        grf_z[f] = float(np.asarray(r.trace.grf)[..., 1].sum(-1).mean())
    assert grf_z[0.5] < 0.8 * grf_z[0.0]


def test_end_to_end_json(e2e):
    code, text, _ = e2e
    assert code == 0
    rep = json.loads(text)  # exactly one JSON object
    keys = [
        "distance_m",
        "duration_s",
        "fell",
        "mean_speed_mps",
        "energy_J_per_m",
        "cost_of_transport",
        "c_angles",
        "corr_hip",
        "corr_knee",
        "corr_ankle",
        "step_length_snr",
        "step_length_mean_m",
        "n_steps",
        "double_stance_fraction",
        "mean_trunk_lean_deg",
        "preset",
        "model",
        "env",
        "units",
    ]
    for k in keys:
        assert k in rep, k
    assert rep["model"] == "fbl" and rep["env"] == "flat"
    assert isinstance(rep["fell"], bool)
    for k, v in rep.items():
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            assert math.isfinite(v), k
        assert not isinstance(v, (list,)), k
    assert 0 < rep["duration_s"] <= 0.3 + 1e-6
    assert rep["units"]["distance_m"] == "m" and rep["units"]["mean_trunk_lean_deg"] == "deg"


def test_end_to_end_outputs(e2e):
    code, text, d = e2e
    assert code == 0
    rep = json.loads(text)
    traj = trajectory_io.read_trajectory_csv(d / "traj.csv")
    assert 1 <= traj["time_s"].size <= 30
    assert np.all(np.isfinite(traj["com_x_m"]))
    for name in ("joint_angles", "grf", "activations", "stick_figure"):
        assert (d / "plots" / f"{name}.png").is_file()
        assert rep["plot_files"][name].endswith(f"{name}.png")


def test_end_to_end_scene(e2e):
    """The scene covers the walked range and replays the trajectory CSV."""
    import mujoco

    code, text, d = e2e
    assert code == 0
    assert json.loads(text)["scene_file"].endswith("scene.xml")
    m = mujoco.MjModel.from_xml_path(str(d / "scene.xml"))
    traj = trajectory_io.read_trajectory_csv(d / "traj.csv")
    q = scene.trajectory_qpos(traj)
    x0 = m.geom_pos[m.geom(scene.TERRAIN_NAME).id][0] - m.hfield_size[0][0]
    x1 = m.geom_pos[m.geom(scene.TERRAIN_NAME).id][0] + m.hfield_size[0][0]
    assert x0 == pytest.approx(q[:, 0].min() - 3.0, abs=1e-6)
    assert x1 == pytest.approx(q[:, 0].max() + 5.0, abs=1e-6)
    data = mujoco.MjData(m)
    for i in (0, len(q) // 2, len(q) - 1):  # replay: the scene's CoM is the logged CoM
        data.qpos[:] = q[i]
        mujoco.mj_forward(m, data)
        com = data.subtree_com[m.body("trunk").id][[0, 2]]
        np.testing.assert_allclose(com, [traj["com_x_m"][i], traj["com_z_m"][i]], atol=1e-4)


def test_save_scene_on_slope(tmp_path, capsys):
    """--save-scene for a sloped environment: the height field is the env's terrain."""
    import mujoco

    preset = tmp_path / "init.json"
    save_preset(preset, "fbl", FBL, FBL.init)
    path = tmp_path / "slope.xml"
    argv = [str(preset), "--env", "slope_up", "--duration", "0.3", "--save-scene", str(path)]
    assert ev.main(argv) == 0
    assert f"python -m mujoco.viewer --mjcf {path}" in capsys.readouterr().out
    m = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(m)
    mujoco.mj_forward(m, data)
    terrain = envs.make_env("slope_up", jax.random.PRNGKey(0)).terrain
    groups = np.zeros(mujoco.mjNGROUP, np.uint8)
    groups[scene.TERRAIN_GROUP] = 1
    hit = np.zeros(1, np.int32)
    for x in (-2.0, 1.0, 2.5, 4.0, 5.0):
        dist = mujoco.mj_ray(
            m, data, np.array([x, 0, 10.0]), np.array([0, 0, -1.0]), groups, 1, -1, hit
        )
        assert 10.0 - dist == pytest.approx(float(terrain.height(x)), abs=2e-3), x
    assert float(terrain.height(5.0)) > 0.1  # the slope (from x = 2 m) is in the scene


def test_a_preset_starts_in_its_own_pose_and_an_unknown_pose_is_refused():
    from jaxgait import evaluation
    from jaxgait.sim.model import POSES

    d = json.loads(presets.resolve_preset("fbl_walk").read_text())
    run = evaluation.run({**d, "pose": "run"}, duration=0.01)
    assert run.cfg.pose == "run"
    knee_sw = math.radians(POSES["run"][2][1])  # the swing knee of the running pose
    q0 = np.asarray(run.trace.qpos[0])
    assert np.isclose(q0, knee_sw, atol=0.02).any()  # Geyer's start has no joint near 100 deg
    with pytest.raises(evaluation.EvaluateError, match="unknown start pose 'crouch'"):
        evaluation.run({**d, "pose": "crouch"}, duration=0.01)


def test_a_preset_runs_the_dynamics_it_was_made_with():
    """A preset without ``dynamics`` (made before the option) runs MJX's passes; one that
    says ``planar`` runs the planar tree; anything else is refused, naming it."""
    from jaxgait import evaluation

    d = json.loads(presets.resolve_preset("fbl_walk").read_text())
    assert "dynamics" not in d
    assert evaluation.run(d, duration=0.01).cfg.dynamics == "mjx"
    assert evaluation.run({**d, "dynamics": "planar"}, duration=0.01).cfg.dynamics == "planar"
    with pytest.raises(evaluation.EvaluateError, match="unknown dynamics 'ode'"):
        evaluation.run({**d, "dynamics": "ode"}, duration=0.01)


def test_dynamics_can_be_chosen_over_the_presets_own(tmp_path, capsys):
    """``run(dynamics=...)`` and ``evaluate --dynamics`` simulate a preset with the other
    dynamics than it was made with (reported); the two agree to rounding over a short walk;
    a bad name is refused, and so is the option for the Taga biped."""
    from jaxgait import evaluation, sim

    assert set(sim.DYNAMICS) == {"mjx", "planar"}  # the CLI's choices
    d = json.loads(presets.resolve_preset("fbl_walk").read_text())
    runs = {k: evaluation.run(d, duration=0.5, dynamics=k) for k in ("mjx", "planar")}
    assert {k: r.cfg.dynamics for k, r in runs.items()} == {"mjx": "mjx", "planar": "planar"}
    assert runs["planar"].report["dynamics"] == "planar"
    np.testing.assert_allclose(
        np.asarray(runs["planar"].trace.qpos), np.asarray(runs["mjx"].trace.qpos), atol=1e-3
    )
    planar_doc = {**d, "dynamics": "planar"}
    assert evaluation.run(planar_doc, duration=0.01, dynamics="mjx").cfg.dynamics == "mjx"
    with pytest.raises(evaluation.EvaluateError, match="dynamics: unknown dynamics 'ode'"):
        evaluation.run(d, duration=0.01, dynamics="ode")
    capsys.readouterr()
    assert ev.main(["fbl_walk", "--duration", "0.05", "--json", "--dynamics", "planar"]) == 0
    assert json.loads(capsys.readouterr().out)["dynamics"] == "planar"
    assert ev.main(["fbl_walk", "--dynamics", "ode"]) == 2
    assert "invalid choice" in capsys.readouterr().err
    taga = write_json(tmp_path / "taga.json", {"model": "taga", "params": {"u0": 5.0}})
    assert ev.main([str(taga), "--dynamics", "planar"]) == 2
    assert "Taga biped has its own equations" in capsys.readouterr().err


def test_plots_draw_the_reference_the_correlations_use(e2e, tmp_path, monkeypatch, capsys):
    """``--reference running --plots``: the joint-angle and GRF figures draw Fukuchi's running
    curves, the ones the correlations (and grf_corr) were computed against."""
    from jaxgait.analysis import plots, refdata

    seen = {}
    real, real_grf = plots.plot_joint_angles, plots.plot_grf

    def spy(*args, **kw):
        seen["reference"] = kw.get("reference")
        return real(*args, **kw)

    def spy_grf(*args, **kw):
        seen["grf"] = kw.get("reference")
        return real_grf(*args, **kw)

    monkeypatch.setattr(plots, "plot_joint_angles", spy)
    monkeypatch.setattr(plots, "plot_grf", spy_grf)
    _, _, d = e2e
    argv = [str(d / "init.json"), "--json", "--duration", "0.3", "--plots", str(tmp_path)]
    assert ev.main([*argv, "--reference", "running"]) == 0
    capsys.readouterr()
    running = refdata.running_kinematics()
    np.testing.assert_array_equal(seen["reference"].mean_deg, running.mean_deg)
    np.testing.assert_array_equal(seen["grf"].mean_bw, refdata.running_grf().mean_bw)
    assert (tmp_path / "joint_angles.png").is_file()
