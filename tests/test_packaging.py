"""An installed wheel (not only the source checkout) finds its models, presets and data."""

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(out),
            str(ROOT),
        ],
        check=True,
    )
    (whl,) = out.glob("jaxgait-*.whl")
    return whl


def test_wheel_contains_resources(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    assert "jaxgait/_resources/models/fbl_planar.xml" in names
    assert any(n.startswith("jaxgait/_resources/presets/") and n.endswith(".json") for n in names)
    assert "jaxgait/data/winter_normal_walking_kinematics.csv" in names


def test_installed_wheel_finds_models(wheel, tmp_path):
    target = tmp_path / "site"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--no-deps",
            "-q",
            "--target",
            str(target),
            str(wheel),
        ],
        check=True,
    )
    code = (
        "import jaxgait, jaxgait.core.resources as r, jaxgait.analysis.refdata as d;"
        "from jaxgait.body.planar import load_body;"
        "assert '_resources' in str(r.model_path('fbl_planar')), r.model_path('fbl_planar');"
        f"assert str(r.models_dir()).startswith({str(target)!r});"
        "b = load_body(); assert abs(b.total_mass - 80) < 1e-9;"
        "assert d.winter_walking_kinematics().n_samples == 51;"
        "print('ok')"
    )
    env = dict(os.environ, PYTHONPATH=str(target))
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().endswith("ok")
