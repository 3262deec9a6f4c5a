"""The notebooks are runnable by notebooks/run_all.py (CI executes them after the tests):
each has an install cell first and one parameters cell setting every size CI overrides."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import nbformat
import pytest

NB = Path(__file__).resolve().parents[1] / "notebooks"
spec = importlib.util.spec_from_file_location("run_all", NB / "run_all.py")
run_all = importlib.util.module_from_spec(spec)
spec.loader.exec_module(run_all)

NOTEBOOKS = sorted(NB.glob("*.ipynb"))


def test_the_notebooks_are_there():
    assert {p.stem for p in NOTEBOOKS} >= {"quickstart", "optimisation", "taga"}
    assert {p.stem for p in NOTEBOOKS} == set(run_all.SMALL)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_layout(path):
    nb = nbformat.read(path, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert "pip" in code[0].source and "google.colab" in code[0].source  # the install cell
    i = run_all.parameter_cell(nb)
    small = run_all.with_parameters(nb, run_all.SMALL[path.stem])
    injected = small.cells[i + 1]
    assert injected.metadata["tags"] == ["injected-parameters"]
    for k, v in run_all.SMALL[path.stem].items():
        assert f"{k} = {v!r}" in injected.source
    assert all(not c.get("outputs") for c in code), "notebooks are kept without outputs"


def test_overrides_must_exist_and_parameters_cell_is_required():
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("A = 1")])
    with pytest.raises(run_all.NotebookError, match="tagged 'parameters'"):
        run_all.parameter_cell(nb)
    nb.cells[0].metadata["tags"] = ["parameters"]
    with pytest.raises(run_all.NotebookError, match=r"\['B'\] are not set"):
        run_all.with_parameters(nb, {"B": 2})
    assert "A = 3" in run_all.with_parameters(nb, {"A": 3}).cells[1].source
