"""Clean edges: no MJX backend notices on import, clear errors for lengths too large to simulate."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

from jaxgait.core import limits
from jaxgait.core.quiet_import import DROPPED, filter_lines


def test_import_prints_no_warp_notices():
    """A fresh interpreter importing the model registry (which imports mujoco.mjx) prints
    nothing on stdout; MJX prints its two notices without the hook (warp is not installed)."""
    code = "import jaxgait.models"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "Failed to import" not in out.stdout + out.stderr
    raw = subprocess.run(
        [sys.executable, "-c", "import mujoco.mjx"], capture_output=True, text=True, timeout=300
    )
    try:
        import warp  # noqa: F401

        have_warp = True
    except ImportError:
        have_warp = False
    if not have_warp:  # the notices exist, so the check above can fail
        assert "Failed to import warp" in raw.stdout


def test_filter_keeps_other_lines():
    text = f"{DROPPED[0]} x\nhello\n{DROPPED[1]} y\nworld"
    assert filter_lines(text) == "hello\nworld"
    assert filter_lines("warp is fine\n") == "warp is fine\n"


def test_duration_limit():
    top = limits.max_duration(5e-4)
    assert 8388 < top < 8389
    assert limits.check_duration(60) == 60.0
    assert limits.check_duration(top) == top
    with pytest.raises(limits.LimitError, match="too long to simulate.*2\\*\\*24 steps"):
        limits.check_duration(1e12)
    with pytest.raises(limits.LimitError, match="too long"):
        limits.check_duration(top * 1.001)
    for bad in (0, -1.0, math.inf, math.nan, "5", True):
        with pytest.raises(limits.LimitError, match="duration"):
            limits.check_duration(bad)
    # a finer step reaches less far
    with pytest.raises(limits.LimitError, match="0.25 ms"):
        limits.check_duration(5000.0, dt=2.5e-4)


def test_distance_limit():
    assert limits.check_distance(35.0) == 35.0
    assert limits.check_distance(math.inf) == math.inf
    with pytest.raises(limits.LimitError, match="too far to simulate.*inf for no distance"):
        limits.check_distance(1e12)
    for bad in (0.0, -3.0, math.nan, None):
        with pytest.raises(limits.LimitError, match="d_lim"):
            limits.check_distance(bad)


def test_evaluate_cli_refuses_a_huge_duration(capsys):
    from jaxgait.evaluate import main

    assert main(["fbl_walk", "--duration", "1e12"]) == 2
    err = capsys.readouterr().err
    assert "duration 1e+12 s is too long to simulate" in err and "Traceback" not in err


@pytest.mark.parametrize(
    "flag, value, msg",
    [("--duration", "1e12", "too long to simulate"), ("--d-lim", "1e12", "too far to simulate")],
)
def test_train_cli_refuses_huge_lengths(flag, value, msg, tmp_path, capsys):
    from jaxgait.train import main

    assert main(["quickstart", flag, value, "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert msg in err and "Traceback" not in err
    assert not (tmp_path / "run").exists()


def test_robustness_refuses_a_huge_duration(capsys):
    from jaxgait.robustness import main

    assert main(["fbl_walk", "--duration", "1e12", "--tests", "slope"]) == 2
    assert "too long to simulate" in capsys.readouterr().err
