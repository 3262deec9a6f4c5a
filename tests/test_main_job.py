"""The main job (``./jg train`` = ``jaxgait train quickstart``) at a reduced size: from the
Geyer-Herr gains, which fall, the best's walked distance improves over the first iterations,
and the progress lines show it."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from jaxgait import models
from jaxgait import train as tr
from jaxgait.train.experiments import EXPERIMENTS

WALK = re.compile(r"walks (\d+\.\d) s, (\d+\.\d) m, (\d\.\d\d) m/s")


def test_quickstart_starts_from_the_geyer_herr_gains():
    exp = EXPERIMENTS["quickstart"]
    assert exp.init == "table" and exp.model == "fbl" and exp.optimiser == "cmaes"
    table = models.get_model("fbl").table
    np.testing.assert_array_equal(tr.resolve_init(exp.init, table), table.init)
    assert exp.duration >= 20.0 and exp.d_lim == float("inf")
    assert dict(exp.targets)["v_desired"] == 1.3


@pytest.mark.slow
def test_main_job_improves_the_distance_from_the_geyer_herr_start(tmp_path, capsys):
    out = tmp_path / "qs"
    argv = ["quickstart", "--iterations", "5", "--duration", "3", "--no-plots", "--no-video"]
    assert tr.main(argv + ["--out", str(out)]) == 0
    text = capsys.readouterr().out
    # the progress lines (a confirm_best rejection also starts "quickstart it N:")
    lines = [s for s in text.splitlines() if re.match(r"quickstart it \d+/5 \|", s)]
    assert len(lines) == 5, text
    walks = [tuple(float(x) for x in WALK.search(s).groups()) for s in lines]
    (t0, d0, _), (t1, d1, v1) = walks[0], walks[-1]
    assert t0 < 3.0 and d0 < 3.0, walks  # the first iteration's best still falls
    assert d1 > d0 and t1 > t0, walks  # and the best walks further and longer later
    best = json.loads((out / "best.json").read_text())
    assert abs(best["distance_m"] - d1) <= 0.05  # best.json keeps the best's walk
    assert abs(v1 - best["distance_m"] / best["duration_s"]) < 0.01
