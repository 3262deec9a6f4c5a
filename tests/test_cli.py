"""The ``jaxgait`` command: every subcommand at a tiny size prints its documented keys; one
report schema for every model; the training progress output."""

from __future__ import annotations

import io
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jaxgait import cli
from jaxgait.render import KEYS as RENDER_KEYS
from jaxgait.train.progress import Progress, bar

DOCS = Path(__file__).resolve().parents[1] / "docs" / "measures.md"
#: Keys every model's evaluate report has (docs/measures.md, "every model").
COMMON = (
    "distance_m",
    "duration_s",
    "fell",
    "mean_speed_mps",
    "double_stance_fraction",
    "cycle_frequency_hz",
    "preset",
    "preset_file",
    "model",
    "env",
    "env_seed",
    "duration_requested_s",
    "units",
)


def run_json(capsys, argv):
    capsys.readouterr()
    assert cli.main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_help_lists_every_subcommand_and_the_console_script_runs():
    out = subprocess.run(
        [sys.executable, "-m", "jaxgait", "--help"], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0
    for name in ("train", "evaluate", "robustness", "render", "list"):
        assert re.search(rf"^\s+{name}\s", out.stdout, re.M), name
    script = Path(sys.executable).parent / "jaxgait"
    assert script.is_file(), "the jaxgait console command is not installed"
    out2 = subprocess.run([str(script), "--help"], capture_output=True, text=True, timeout=120)
    assert out2.returncode == 0 and out2.stdout == out.stdout


def test_unknown_command_and_bad_list_arguments(capsys):
    assert cli.main(["fly"]) == 2
    assert "unknown command 'fly'" in capsys.readouterr().err
    assert cli.main(["list", "--yaml"]) == 2


def test_list(capsys):
    doc = run_json(capsys, ["list", "--json"])
    assert set(doc) == {"experiments", "models", "presets"}
    q = doc["experiments"]["quickstart"]
    assert set(q) == {"model", "env", "optimiser", "particles", "iterations", "description"}
    assert doc["models"]["fbl"]["family"] == "planar" and doc["models"]["fbl"]["parameters"] == 28
    assert doc["models"]["taga"]["family"] == "taga"
    assert {"fbl_walk", "taga_walk"} <= set(doc["presets"])
    assert cli.main(["list"]) == 0
    text = capsys.readouterr().out
    assert "quickstart" in text and "fbl_walk" in text and "taga" in text


@pytest.fixture(scope="module")
def reports():
    """evaluate --json of a planar and of a Taga preset, through the jaxgait command."""
    import contextlib

    out = {}
    for name, seconds in (("fbl_walk", "0.3"), ("taga_walk", "4")):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert cli.main(["evaluate", name, "--duration", seconds, "--json"]) == 0
        out[name] = json.loads(buf.getvalue())
    return out


def test_evaluate_reports_share_the_keys_of_the_same_measures(reports):
    planar, taga = reports["fbl_walk"], reports["taga_walk"]
    for rep in (planar, taga):
        missing = [k for k in COMMON if k not in rep]
        assert not missing, (rep["model"], missing)
        assert rep["mean_speed_mps"] == pytest.approx(rep["distance_m"] / rep["duration_s"])
        assert rep["units"]["mean_speed_mps"] == "m/s"
    assert "speed_mps" not in taga and "double_support_fraction" not in taga
    assert taga["cycle_frequency_hz"] == pytest.approx(1.0 / taga["stride_duration_s"])
    assert planar["model"] == "fbl" and taga["model"] == "taga"


def test_every_report_key_is_documented(reports):
    text = DOCS.read_text()
    documented = set(re.findall(r"^\| `([A-Za-z0-9_]+)`", text, re.M))
    for rep in reports.values():
        missing = sorted(set(rep) - documented)
        assert not missing, f"{rep['model']} report keys missing from {DOCS}: {missing}"
    for k in RENDER_KEYS:
        assert f"`{k}`" in text, k


@pytest.mark.parametrize(
    "preset, seconds, suffix, fps, frames",
    [("fbl_walk", "0.3", "gif", "10", 3), ("taga_walk", "4", "mp4", "5", 20)],
)
def test_render(preset, seconds, suffix, fps, frames, tmp_path, capsys):
    path = tmp_path / f"walk.{suffix}"
    argv = ["render", preset, "--duration", seconds, "--fps", fps, "--size", "320x180"]
    rep = run_json(capsys, argv + ["-o", str(path), "--json"])
    assert set(rep) == set(RENDER_KEYS)
    assert rep["frames"] == frames and (rep["width"], rep["height"]) == (320, 180)
    assert path.is_file() and path.stat().st_size > 1000
    assert rep["duration_s"] == pytest.approx(float(seconds), abs=0.011)
    assert cli.main(argv + ["-o", str(tmp_path / "walk.avi")]) == 2
    assert ".mp4 or .gif" in capsys.readouterr().err


def test_evaluate_video(tmp_path, capsys):
    path = tmp_path / "walk.mp4"
    argv = ["evaluate", "fbl_walk", "--duration", "0.3", "--video", str(path), "--video-fps", "10"]
    rep = run_json(capsys, argv + ["--json"])
    assert rep["video_file"] == str(path) and rep["video_frames"] == 3 and path.is_file()
    assert rep["video_backend"] in ("mujoco", "matplotlib")


def test_robustness(capsys):
    argv = ["robustness", "fbl_walk", "--tests", "slope", "--seeds", "1", "--duration", "1"]
    rep = run_json(capsys, argv + ["--json"])
    for k in ("slope_distance_m", "slope_distance_m_sd", "slope_max_grade_pct", "model", "seeds"):
        assert k in rep, k
    assert 0.0 < rep["slope_distance_m"] < 3.0  # at most 1 s of walking


def test_train(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["train", "quickstart", "--particles", "4", "--iterations", "2", "--duration", "1"]
    argv += ["--set", "batch_size=4", "--no-plots", "--no-video", "--out", str(out)]
    capsys.readouterr()
    assert cli.main(argv) == 0
    text = capsys.readouterr().out
    lines = [s for s in text.splitlines() if " it " in s]
    assert len(lines) == 2 and lines[1].startswith("quickstart it 2/2")
    for key in ("best F", "walks", "rollouts/s", "ETA"):
        assert key in lines[1], key
    assert re.search(r"walks \d+\.\d s, \d+\.\d m, \d\.\d\d m/s", lines[1])
    assert "re-evaluated" in text and f"results in {out}" in text
    assert not (out / "best.mp4").exists()  # --no-video
    best = json.loads((out / "best.json").read_text())
    assert best["duration_s"] == pytest.approx(1.0, abs=0.011) and best["distance_m"] > 0.5


# ------------------------------------------------------------------------ progress output


class Tty(io.StringIO):
    def isatty(self):
        return True


def test_progress_plain_lines_when_not_a_terminal():
    s = io.StringIO()
    p = Progress(s)
    assert not p.live
    p("starting")
    p.iteration(1, 3, "it 1/3 | 5 rollouts/s | ETA 10s")
    p.iteration(3, 3, "it 3/3 | 6 rollouts/s | ETA 0s")
    assert s.getvalue().splitlines() == [
        "starting",
        "it 1/3 | 5 rollouts/s | ETA 10s",
        "it 3/3 | 6 rollouts/s | ETA 0s",
    ]


def test_progress_live_bar_on_a_terminal():
    s = Tty()
    p = Progress(s)
    assert p.live
    p.iteration(1, 4, "it 1/4 | ETA 30s")
    assert s.getvalue() == "\r\033[K" + bar(1, 4) + " it 1/4 | ETA 30s"  # no newline: redrawn
    p("a notice")  # clears the bar, prints on its own line
    p.iteration(4, 4, "it 4/4 | ETA 0s")
    text = s.getvalue()
    assert text.endswith(bar(4, 4) + " it 4/4 | ETA 0s\n") and "\r\033[Ka notice\n" in text
    assert bar(1, 4) == "[#####" + "-" * 15 + "]" and bar(0, 0) == "[" + "-" * 20 + "]"
    p2 = Progress(Tty())
    p2.iteration(1, 9, "x")
    p2.close()
    assert p2.stream.getvalue().endswith("x\n")


def test_progress_counts_are_the_train_loop_ones():
    """The loop hands Progress.iteration the iteration number and total."""
    seen = []

    class Spy(Progress):
        def iteration(self, done, total, line):
            seen.append((done, total, line.split(" | ")[0]))

    from jaxgait.train import get_experiment, train

    exp = get_experiment("quickstart", particles=4, iterations=2, duration=1.0, batch_size=4)
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        res = train(exp, d, progress=Spy(io.StringIO()), plots=False, video=False)
    assert seen == [(1, 2, "quickstart it 1/2"), (2, 2, "quickstart it 2/2")]
    assert res.best_walk is not None and np.isfinite(res.best_walk).all()
