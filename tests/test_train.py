"""Training runs, experiment registry, checkpoints and the command line (tiny sizes).

Every run here uses 4 particles, 1 s rollouts and 4 rollouts per device call, so the whole
file compiles one rollout program (shared through :func:`jaxgait.train.evaluator._batched_rollout`).
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import shutil

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxgait import train as tr
from jaxgait.presets import load_preset
from jaxgait.train.checkpoint import (
    CheckpointError,
    CheckpointMismatchError,
    RunCheckpoints,
)
from jaxgait.train.experiments import (
    EXPERIMENTS,
    Experiment,
    ExperimentError,
    get_experiment,
    load_config,
)

TINY = dict(particles=4, iterations=2, duration=1.0, batch_size=4)


def tiny(name, **kw):
    return get_experiment(name, **{**TINY, **kw})


def walking_quickstart(**kw):
    """quickstart from fbl_walk with a tiny step size: every candidate walks its 1 s."""
    return tiny("quickstart", init="fbl_walk", optimiser_options={"sigma_init": 1e-4}, **kw)


def fblplus_available() -> bool:
    try:
        tr.get_model("fblplus")
        return True
    except tr.TrainError:
        return False


def quiet(lines):
    return lines.append


# ----------------------------------------------------------------------- registry runs


def _chained_start_missing(exp) -> bool:
    """The experiment starts from the best of another experiment, not shipped yet."""
    from jaxgait.presets import PresetError

    if exp.init in (None, "table") or exp.init not in EXPERIMENTS:
        return False
    try:
        load_preset(exp.init)
        return False
    except PresetError:
        return True


@pytest.mark.parametrize("name", list(EXPERIMENTS))
def test_every_registry_experiment_runs(name, tmp_path):
    exp = tiny(name)
    lines = []
    if _chained_start_missing(exp):  # e.g. wang_walk_1p0 before wang_walk_1p25 ships
        with pytest.raises(tr.TrainError, match=f"run `jaxgait train {exp.init}` first"):
            tr.train(exp, tmp_path / name, progress=quiet(lines))
        return
    if exp.model == "fblplus" and not fblplus_available():
        with pytest.raises(tr.TrainError, match="model fblplus not available yet"):
            tr.train(exp, tmp_path / name, progress=quiet(lines))
        assert not (tmp_path / name / "checkpoints").exists()
        return
    res = tr.train(exp, tmp_path / name, progress=quiet(lines), plots=(name == "exp3"))
    assert res.complete and res.iterations_done == 2 and len(res.history) == 2
    assert res.best_stage >= 0 and np.isfinite(res.best_value)
    out = res.out_dir
    for f in ("config.json", "best.json", "best_params.txt", "history.csv", "measures.json"):
        assert (out / f).is_file(), f
    model, vec, doc = load_preset(out / "best.json")  # usable by python -m jaxgait.evaluate
    np.testing.assert_allclose(vec, res.best_params)
    assert doc["experiment"] == name
    meas = json.loads((out / "measures.json").read_text())
    assert meas["distance_m"] > 0.5 and meas["worst_of"] == exp.worst_of_k
    assert 0.0 <= meas["perturbed_survival"] <= 1.0 and meas["perturbed_copies"] == 8
    warned = any("depends on rounding" in s for s in lines)
    assert warned == (meas["perturbed_survival"] < 1.0 and not meas["perturbed_reference_fell"])
    assert load_config(out / "config.json") == exp
    assert (out / "history.csv").read_text().count("\n") == 3
    progress = [s for s in lines if " it " in s]
    assert len(progress) == 2 and "rollouts/s" in progress[0] and "ETA" in progress[0]
    if exp.optimiser == "stage_pso":
        assert "stages 0:" in progress[0]
    if name == "exp3":
        for fig in ("joint_angles", "grf", "activations", "stick_figure", "stage_progress"):
            assert (out / "plots" / f"{fig}.png").is_file()


# ----------------------------------------------------------------------- resume


@pytest.mark.parametrize("name", ["exp3", "quickstart"])
def test_killed_and_resumed_equals_uninterrupted(name, tmp_path):
    exp = tiny(name, iterations=3)
    full = tr.train(exp, tmp_path / "full", progress=None, plots=False)
    part = tr.train(exp, tmp_path / "part", progress=None, plots=False, max_iterations=1)
    assert not part.complete and part.iterations_done == 1
    assert not (tmp_path / "part" / "measures.json").exists()
    lines = []
    rest = tr.train(exp, tmp_path / "part", resume=True, progress=quiet(lines), plots=False)
    assert any("resumed from iteration 1" in s for s in lines)
    assert rest.complete and rest.iterations_done == 3
    np.testing.assert_array_equal(rest.best_params, full.best_params)
    assert (rest.best_stage, rest.best_value) == (full.best_stage, full.best_value)
    drop = lambda rows: [
        {k: v for k, v in r.items() if k not in ("seconds", "rollouts_per_s", "env_steps_per_s")}
        for r in rows
    ]
    assert drop(rest.history) == drop(full.history)
    a, b = jax.tree.leaves(rest.state.opt_state), jax.tree.leaves(full.state.opt_state)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert rest.measures["distance_m"] == full.measures["distance_m"]


def _same_run(a, b):
    """Two results of the same iterations: best, history (timings aside), optimiser state."""
    np.testing.assert_array_equal(a.best_params, b.best_params)
    assert (a.best_stage, a.best_value) == (b.best_stage, b.best_value)
    drop = lambda rows: [
        {k: v for k, v in r.items() if k not in ("seconds", "rollouts_per_s", "env_steps_per_s")}
        for r in rows
    ]
    assert drop(a.history) == drop(b.history)
    for x, y in zip(
        jax.tree.leaves(a.state.opt_state), jax.tree.leaves(b.state.opt_state), strict=True
    ):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    for name in ("hist_best_value", "hist_iter_value", "hist_n_valid", "hist_stage_counts"):
        np.testing.assert_array_equal(getattr(a.state, name), getattr(b.state, name))


def test_resume_with_more_iterations_extends_a_finished_run(tmp_path):
    exp = tiny("quickstart", iterations=2)
    longer = exp.replace(iterations=4)
    full = tr.train(longer, tmp_path / "full", progress=None, plots=False)
    short = tr.train(exp, tmp_path / "ext", progress=None, plots=False)
    assert short.complete and short.iterations_done == 2
    lines = []
    ext = tr.train(longer, tmp_path / "ext", resume=True, progress=quiet(lines), plots=False)
    assert any("iterations 2 -> 4" in s for s in lines)
    assert any("resumed from iteration 2" in s for s in lines)
    assert ext.complete and ext.iterations_done == 4 and len(ext.history) == 4
    _same_run(ext, full)
    assert ext.measures["distance_m"] == full.measures["distance_m"]
    assert load_config(tmp_path / "ext" / "config.json") == longer
    # any other difference is still refused, naming it
    with pytest.raises(CheckpointMismatchError, match="seed: 0 -> 1"):
        tr.train(longer.replace(iterations=6, seed=1), tmp_path / "ext", resume=True, progress=None)
    # fewer iterations than done cannot be resumed
    with pytest.raises(tr.TrainError, match="4 iterations done.*use at least 4"):
        tr.train(exp.replace(iterations=3), tmp_path / "ext", resume=True, progress=None)


def test_early_stop_ends_the_run_once_its_best_walks_at_the_target_speed(tmp_path):
    exp = walking_quickstart(iterations=3, stop_speed_tol=0.3)
    lines = []
    res = tr.train(exp, tmp_path / "run", progress=quiet(lines), plots=False, video=False)
    assert res.iterations_done == 1 and res.complete and len(res.history) == 1
    d, t = res.best_walk
    assert t == pytest.approx(1.0, abs=1e-3) and abs(d / t - 1.3) <= 0.3
    assert any("target reached at iteration 1" in s for s in lines)
    assert res.measures is not None and (tmp_path / "run" / "measures.json").is_file()
    # resumed as it is, the finished run does not iterate again
    again = tr.train(exp, tmp_path / "run", resume=True, progress=None, plots=False, video=False)
    assert again.iterations_done == 1 and again.complete
    # with the early stop lifted it goes on to its iterations, as one run without it
    free = exp.replace(stop_speed_tol=None)
    cont = tr.train(free, tmp_path / "run", resume=True, progress=None, plots=False, video=False)
    whole = tr.train(free, tmp_path / "whole", progress=None, plots=False, video=False)
    assert cont.iterations_done == 3 and cont.complete
    _same_run(cont, whole)


def test_confirmed_best_is_the_one_the_final_evaluation_finds(tmp_path):
    """confirm_best on a gait that walks: the confirmation passes, so the run is the run
    without it, and the final evaluation (the same batch) finds the best and its copies up."""
    exp = walking_quickstart(iterations=2, confirm_best=False)
    plain = tr.train(exp, tmp_path / "plain", progress=None, plots=False, video=False)
    conf = exp.replace(confirm_best=True)
    assert conf.to_dict()["confirm_best"] is True and "confirm_best" not in exp.to_dict()
    res = tr.train(conf, tmp_path / "conf", progress=None, plots=False, video=False)
    _same_run(res, plain)
    assert res.measures["perturbed_survival"] == 1.0
    assert not res.measures["perturbed_reference_fell"]


def test_a_best_that_fails_its_confirmation_is_not_taken(tmp_path, monkeypatch):
    import jaxgait.train.loop as loop

    exp = walking_quickstart(iterations=2, confirm_best=True)
    answers = [False, True]  # the first walker is refused, the second taken
    monkeypatch.setattr(loop, "confirm_walk", lambda *a: answers.pop(0))
    lines = []
    res = tr.train(exp, tmp_path / "run", progress=quiet(lines), plots=False, video=False)
    assert not answers  # one confirmation per walking new best
    assert any("it 1: the candidate that walked 1.0 s falls" in s for s in lines)
    h = res.history
    assert h[0]["best_stage"] == -1 and not np.isfinite(h[0]["best_value"])  # nothing taken
    assert np.isfinite(h[1]["best_value"]) and res.best_walk is not None


def test_early_stop_rule():
    exp = tiny("quickstart", duration=20.0, stop_speed_tol=0.05)
    reach = lambda walk: tr.walk_reaches_target(exp, walk)
    assert reach((26.0, 20.0))  # 1.30 m/s for the whole 20 s
    assert reach((25.1, 20.0)) and reach((26.9, 20.0))  # 1.255 and 1.345 m/s
    assert not reach((24.9, 20.0)) and not reach((27.1, 20.0))  # 1.245 and 1.355 m/s
    assert not reach((25.35, 19.5))  # 1.30 m/s but fell at 19.5 s
    assert not reach(None)
    assert not tr.walk_reaches_target(exp.replace(stop_speed_tol=None), (26.0, 20.0))
    # unset, it is not written, so configs from before the field still match
    assert "stop_speed_tol" not in exp.replace(stop_speed_tol=None).to_dict()
    assert exp.to_dict()["stop_speed_tol"] == 0.05
    with pytest.raises(ExperimentError, match="stop_speed_tol"):
        exp.replace(stop_speed_tol=-0.1)
    with pytest.raises(ExperimentError, match="needs targets.v_desired"):
        Experiment(name="x", stop_speed_tol=0.1, targets=())


def test_start_pose_is_written_only_when_not_geyers_and_reaches_the_simulator():
    exp = tiny("quickstart", duration=1.0)
    assert "pose" not in exp.to_dict()  # configs from before the field still match
    run = exp.replace(pose="run")
    assert run.to_dict()["pose"] == "run"
    assert Experiment.from_dict(run.to_dict()) == run
    from jaxgait.train.evaluator import PopulationEvaluator

    assert PopulationEvaluator(run).sim_cfg.pose == "run"


def test_dynamics_reach_the_simulator_and_the_best_preset(tmp_path):
    """A new run's rollouts use the planar tree and its best preset says so (``evaluate``
    then runs it the same way); a run configured with MJX's passes writes neither key."""
    from jaxgait.train.evaluator import PopulationEvaluator

    for dyn in ("planar", "mjx"):
        exp = tiny("quickstart", duration=0.5, particles=2, iterations=1).replace(dynamics=dyn)
        assert PopulationEvaluator(exp).sim_cfg.dynamics == dyn
        res = tr.train(exp, tmp_path / dyn, progress=lambda *a: None, plots=False, video=False)
        best = json.loads((res.out_dir / "best.json").read_text())
        config = json.loads((res.out_dir / "config.json").read_text())["experiment"]
        assert best.get("dynamics", "mjx") == dyn and config.get("dynamics", "mjx") == dyn
        assert ("dynamics" in best) == (dyn == "planar")


def test_reference_is_written_only_when_not_walking_and_scores_against_it():
    """``reference="running"``: the config says so (and only then), and the evaluator's
    grf_corr criterion is the rollout's vertical GRF against Fukuchi's running curve, the
    same figure ``compute_measures`` gives with that reference."""
    from jaxgait.analysis import refdata
    from jaxgait.analysis.measures import compute_measures
    from jaxgait.train.evaluator import PopulationEvaluator

    base = tiny("quickstart", duration=3.0, weights={"grf_corr": 1.0}, stages=(), lanes=0)
    assert "reference" not in base.to_dict()
    run = base.replace(reference="running")
    assert run.to_dict()["reference"] == "running"
    assert Experiment.from_dict(run.to_dict()) == run
    _, vec, _ = load_preset("fbl_walk")
    params = jnp.asarray(np.stack([vec, vec]), jnp.float32)
    keys = jax.random.split(jax.random.PRNGKey(0), 2)
    got = {}
    for name, exp in (("walking", base), ("running", run)):
        ev = PopulationEvaluator(exp)
        _, value, _, first = ev.scores(params, keys, keep_first=True)
        kin, grf = refdata.gait_reference(name)
        m = compute_measures(*first, reference=kin, grf_reference=grf)
        assert float(value[0]) == pytest.approx(float(m["grf_corr"]), abs=1e-6)
        got[name] = float(value[0])
    assert -1.0 <= got["running"] < got["walking"] - 0.05  # a walking GRF fits Winter's


def test_cli_resume_iterations_extends(tmp_path, capsys):
    out = str(tmp_path / "run")
    base = ["quickstart", "--particles", "4", "--duration", "1", "--set", "batch_size=4"]
    assert tr.main(base + ["--iterations", "1", "--no-plots", "--out", out]) == 0
    assert tr.main(["quickstart", "--resume", "--iterations", "2", "--no-plots", "--out", out]) == 0
    text = capsys.readouterr().out
    assert "iterations 1 -> 2" in text and "quickstart it 2/2" in text
    assert load_config(tmp_path / "run" / "config.json").iterations == 2
    assert tr.main(["quickstart", "--resume", "--seed", "3", "--no-plots", "--out", out]) == 2
    assert "seed: 0 -> 3" in capsys.readouterr().err


def test_resume_without_checkpoint_starts_fresh_and_fresh_run_refuses_old_dir(tmp_path):
    exp = tiny("exp1", iterations=1)
    lines = []
    tr.train(exp, tmp_path, resume=True, progress=quiet(lines), plots=False)
    assert any("starting from iteration 0" in s for s in lines)
    before = sorted(p.name for p in (tmp_path / "checkpoints").iterdir())
    with pytest.raises(tr.TrainError, match="already holds checkpoints"):
        tr.train(exp, tmp_path, progress=None)
    assert sorted(p.name for p in (tmp_path / "checkpoints").iterdir()) == before


def test_checkpoint_of_another_experiment_is_refused(tmp_path):
    tr.train(tiny("exp1", iterations=1), tmp_path, progress=None, plots=False)
    with pytest.raises(CheckpointMismatchError, match=r"'exp1'.*this run is experiment 'exp2'"):
        tr.train(tiny("exp2", iterations=1), tmp_path, resume=True, progress=None)
    with pytest.raises(CheckpointMismatchError, match="seed: 0 -> 5"):
        tr.train(tiny("exp1", iterations=1, seed=5), tmp_path, resume=True, progress=None)


def test_full_disk_while_saving_keeps_the_last_good_checkpoint(tmp_path, monkeypatch):
    exp = tiny("exp1", iterations=2)
    real_save = RunCheckpoints.save
    calls = []

    def flaky_save(self, step, state):
        calls.append(step)
        if step == 2:  # the disk fills up during the second save

            def boom(*a, **k):
                raise OSError(errno.ENOSPC, "No space left on device")

            monkeypatch.setattr(self._manager, "save", boom)
        return real_save(self, step, state)

    monkeypatch.setattr(RunCheckpoints, "save", flaky_save)
    lines = []
    res = tr.train(exp, tmp_path, progress=quiet(lines), plots=False)
    assert res.complete and calls == [1, 2]
    assert any("disk full" in s and "last good checkpoint is step 1" in s for s in lines)
    monkeypatch.undo()
    ck = RunCheckpoints(tmp_path / "checkpoints", tr.config_document(exp))
    assert ck.steps() == [1]
    assert not list((tmp_path / "checkpoints").glob("*tmp*"))


# ----------------------------------------------------------------------- checkpoints (no sim)


def _toy_state(i):
    return {"x": jnp.arange(3.0) + i, "it": jnp.asarray(i, jnp.int32)}


def _abstract():
    from orbax.checkpoint.utils import to_shape_dtype_struct

    return jax.tree.map(to_shape_dtype_struct, _toy_state(0))


CFG = {"format": 1, "jaxgait_version": "t", "experiment": {"name": "toy", "seed": 0}}


def test_checkpoints_keep_last_three_and_ignore_partial_saves(tmp_path):
    ck = RunCheckpoints(tmp_path, CFG, warn=lambda s: None)
    for i in range(1, 6):
        assert ck.save(i, _toy_state(i))
    assert ck.steps() == [3, 4, 5]
    # a save killed mid-way leaves only orbax's temporary folder: it is not a step
    (tmp_path / "6.orbax-checkpoint-tmp-1234" / "state").mkdir(parents=True)
    step, state = RunCheckpoints(tmp_path, CFG, warn=lambda s: None).restore(_abstract())
    assert step == 5 and int(state["it"]) == 5


def test_save_failing_before_the_atomic_rename_leaves_no_step(tmp_path, monkeypatch):
    """orbax writes into a temporary folder and renames it last: fail right there."""
    from orbax.checkpoint._src.path import atomicity

    ck = RunCheckpoints(tmp_path, CFG, warn=lambda s: None)
    assert ck.save(1, _toy_state(1))

    async def no_space(self, *a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomicity.AtomicRenameTemporaryPath, "finalize", no_space)
    warnings = []
    ck.warn = warnings.append
    assert not ck.save(2, _toy_state(2))
    assert "disk full" in warnings[0] and "last good checkpoint is step 1" in warnings[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["1"]
    monkeypatch.undo()
    assert ck.save(3, _toy_state(3)) and ck.steps() == [1, 3]


def test_corrupt_checkpoint_falls_back_to_the_previous_one(tmp_path):
    ck = RunCheckpoints(tmp_path, CFG, warn=lambda s: None)
    for i in (1, 2):
        ck.save(i, _toy_state(i))
    for f in (tmp_path / "2" / "state").rglob("*"):
        if f.is_file():
            f.write_bytes(b"garbage")
    warnings = []
    step, state = RunCheckpoints(tmp_path, CFG, warn=warnings.append).restore(_abstract())
    assert step == 1 and int(state["it"]) == 1
    assert any("step 2" in w and "corrupt" in w for w in warnings)
    shutil.rmtree(tmp_path / "1" / "state")
    with pytest.raises(CheckpointError, match="no readable checkpoint"):
        RunCheckpoints(tmp_path, CFG, warn=lambda s: None).restore(_abstract())


def test_checkpoint_version_mismatch_names_both(tmp_path):
    RunCheckpoints(tmp_path, CFG).save(1, _toy_state(1))
    other = {**CFG, "jaxgait_version": "9.9"}
    with pytest.raises(CheckpointMismatchError, match=r"jaxgait t.*jaxgait 9\.9"):
        RunCheckpoints(tmp_path, other).restore(_abstract())


def test_checkpoint_folder_that_is_a_file(tmp_path):
    f = tmp_path / "ck"
    f.write_text("x")
    with pytest.raises(CheckpointError, match="not a folder"):
        RunCheckpoints(f, CFG)


# ----------------------------------------------------------------------- bad input


def test_unknown_experiment_and_fields_list_the_valid_ones():
    with pytest.raises(ExperimentError, match="valid experiments: exp1, exp2"):
        get_experiment("exp99")
    with pytest.raises(ExperimentError, match="valid fields: name, description"):
        get_experiment("exp1", partciles=3)


@pytest.mark.parametrize(
    "override, msg",
    [
        ({"particles": 0}, "particles"),
        ({"iterations": 1.5}, "iterations"),
        ({"worst_of_k": 0}, "worst_of_k"),
        ({"d_lim": -1.0}, "d_lim"),
        ({"duration": float("inf")}, "duration"),
        ({"seed": -1}, "seed"),
        ({"env": "moon"}, "valid environments"),
        ({"env_overrides": {"alpha": 1}}, "valid fields"),
        ({"optimiser": "adam"}, "valid optimisers"),
        ({"model": "fbl2"}, "valid models"),
        ({"stages": (("distance", None), ("speed", "x"))}, "stage threshold"),
        ({"stages": (("distance", None), ("nope", None))}, "unknown criterion"),
        ({"targets": {"v_wanted": 1.0}}, "unknown target"),
        ({"optimiser_options": {"c3": 1.0}}, "optimiser_options"),
        ({"pose": "crouch"}, "invalid pose='crouch': must be one of geyer, run, thatte"),
        ({"reference": "jog"}, "invalid reference='jog': must be one of walking, running"),
    ],
)
def test_out_of_range_overrides(override, msg):
    with pytest.raises(ExperimentError, match=msg):
        get_experiment("exp3", **override)


def test_malformed_config_files(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"name": "x",\n "particles": }')
    with pytest.raises(ExperimentError, match=r"bad\.json: invalid JSON at line 2"):
        tr.train(bad, tmp_path / "out")
    unknown = tmp_path / "unknown.json"
    unknown.write_text(json.dumps({**EXPERIMENTS["exp1"].to_dict(), "colour": "red"}))
    with pytest.raises(ExperimentError, match=r"unknown\.json: unknown field\(s\) colour"):
        load_config(unknown)
    ranged = tmp_path / "ranged.json"
    ranged.write_text(json.dumps({**EXPERIMENTS["exp1"].to_dict(), "particles": -4}))
    with pytest.raises(ExperimentError, match=r"ranged\.json: invalid particles=-4"):
        load_config(ranged)
    assert not (tmp_path / "out").exists()


def test_config_round_trip_and_inf(tmp_path):
    for exp in EXPERIMENTS.values():
        assert Experiment.from_dict(json.loads(json.dumps(exp.to_dict()))) == exp
    assert EXPERIMENTS["quickstart"].to_dict()["d_lim"] == "inf"


def test_bad_init_preset(tmp_path):
    with pytest.raises(ValueError, match="no preset of that name"):
        tr.train(tiny("exp1", init="no_such_preset"), tmp_path / "out", progress=None)
    assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------- command line


def _cli(args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = tr.main(args)
    return code, out.getvalue(), err.getvalue()


def test_cli_lists_experiments_by_default():
    for args in ([], ["--list"]):
        code, out, _ = _cli(args)
        assert code == 0 and "exp7a" in out and "quickstart" in out


def test_cli_errors():
    code, _, err = _cli(["exp99"])
    assert code == 2 and "unknown experiment 'exp99'" in err
    code, _, err = _cli(["exp1", "--set", "particles"])
    assert code == 2 and "key=value" in err
    if not fblplus_available():
        code, _, err = _cli(["exp5", "--iterations", "1"])
        assert code == 2 and "model fblplus not available yet" in err


def test_cli_overrides_only_given_flags(tmp_path):
    args = [
        "exp3",
        "--particles",
        "4",
        "--iterations",
        "1",
        "--duration",
        "1",
        "--out",
        str(tmp_path),
        "--no-plots",
        "--set",
        "targets.v_desired=1.2",
        "--set",
        "batch_size=4",
    ]
    code, out, err = _cli(args)
    assert code == 0, err
    assert "exp3 it 1/1" in out and "best:" in out
    saved = load_config(tmp_path / "config.json")
    assert saved == get_experiment(
        "exp3", particles=4, iterations=1, duration=1.0, targets={"v_desired": 1.2}, batch_size=4
    )
    # resume picks the saved config up; a different experiment name is refused
    code, _, err = _cli(["exp1", "--resume", "--out", str(tmp_path)])
    assert code == 2 and "'exp3', not 'exp1'" in err
    code, out, err = _cli(["exp3", "--resume", "--out", str(tmp_path), "--no-plots"])
    assert code == 0 and "resumed from iteration 1" in out


def test_unavailable_model_is_refused_clearly():
    with pytest.raises(tr.TrainError, match="'fblminus' cannot be trained here.*fbl, fblplus"):
        tr.get_model("fblminus")
    with pytest.raises(tr.TrainError, match="'taga' cannot be trained here"):
        tr.get_model("taga")


def test_parse_set():
    assert tr.parse_set(["a=1", "b=null", "c=inf", "d=text", "t.v=1.5", "t.w=[1, 2]"]) == {
        "a": 1,
        "b": None,
        "c": float("inf"),
        "d": "text",
        "t": {"v": 1.5, "w": [1, 2]},
    }


def test_padding_to_devices():
    assert tr.padded_size(10, 4, None) == (12, 1)
    assert tr.padded_size(10, 4, 4) == (4, 3)
    assert tr.padded_size(20, 1, 4) == (4, 5)


# ----------------------------------------------------------------------- seeds


def test_seeds_share_one_program_and_equal_separate_runs(tmp_path):
    """``train_seeds`` runs each seed as ``train`` does alone (here bitwise: a call holds one
    run's rollouts), in its own folder, and a killed multi-seed run resumes to the same end."""
    exp = tiny("quickstart", seed=3)
    lines = []
    many = tr.train_seeds(exp, 2, tmp_path / "many", progress=quiet(lines), plots=False)
    assert [r.config.seed for r in many] == [3, 4]
    assert any(s.startswith("quickstart: 2 runs x 4 x 1 rollouts") for s in lines)
    assert sum(" seed 4 it " in s for s in lines) == 2
    for r in many:
        seed = r.config.seed
        assert r.out_dir == tmp_path / "many" / f"seed{seed}" and r.complete
        assert load_config(r.out_dir / "config.json") == exp.replace(seed=seed)
        assert (r.out_dir / "measures.json").is_file()
        alone = tr.train(
            exp.replace(seed=seed), tmp_path / f"alone{seed}", progress=None, plots=False
        )
        np.testing.assert_array_equal(r.best_params, alone.best_params)
        assert (r.best_stage, r.best_value) == (alone.best_stage, alone.best_value)
        assert r.measures["distance_m"] == alone.measures["distance_m"]
    assert not np.array_equal(many[0].best_params, many[1].best_params)

    part = tr.train_seeds(
        exp, [3, 4], tmp_path / "part", progress=None, plots=False, max_iterations=1
    )
    assert [r.iterations_done for r in part] == [1, 1]
    rest = tr.train_seeds(exp, 2, tmp_path / "part", resume=True, progress=None, plots=False)
    for a, b in zip(rest, many, strict=True):
        np.testing.assert_array_equal(a.best_params, b.best_params)
        assert a.complete and a.iterations_done == 2


@pytest.mark.parametrize("bad", [0, [], [1, 1], True, "2"])
def test_bad_seeds_are_refused(bad, tmp_path):
    with pytest.raises(tr.TrainError, match="seeds"):
        tr.train_seeds(tiny("quickstart"), bad, tmp_path, progress=None)
    assert not any(tmp_path.iterdir())


def test_cli_seeds_writes_one_folder_per_seed(tmp_path, capsys):
    argv = ["quickstart", "--particles", "4", "--iterations", "1", "--duration", "1"]
    argv += ["--set", "batch_size=4", "--seeds", "2", "--out", str(tmp_path), "--no-plots"]
    assert tr.main(argv) == 0
    out = capsys.readouterr().out
    for s in (0, 1):
        assert f"seed {s}: best" in out and (tmp_path / f"seed{s}" / "best.json").is_file()
