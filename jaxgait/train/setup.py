"""Run set-up: the config document, the model and the starting point of a search."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jaxgait import models
from jaxgait.presets import PresetError, ensure_model, load_preset
from jaxgait.train.experiments import (
    CONFIG_FORMAT,
    EXPERIMENTS,
    Experiment,
)

#: Default parent of results folders.
DEFAULT_RUNS = Path("runs")
#: Name of the mesh axis the population is sharded over.
POP_AXIS = "pop"
#: fold_in tags of the keys that are not per-iteration.
_INIT_TAG, _EVAL_TAG = 0x1D17, 0xE7A1
#: Fallback location (source checkout) of the walking gait used before ``fbl_walk`` ships.
_FBL_WALK_RUN = Path(__file__).resolve().parents[2] / "experiments/fbl_walk/run1/best.json"


class TrainError(ValueError):
    """Bad input to :func:`train` (model not available, results folder in use, bad start)."""


def jaxgait_version() -> str:
    """Installed jaxgait version (``"unknown"`` outside an installed package)."""
    try:
        from importlib.metadata import version

        return version("jaxgait")
    except Exception:  # noqa: BLE001 - metadata missing in odd setups
        return "unknown"


def config_document(exp: Experiment) -> dict:
    """The config JSON of a run: experiment fields, jaxgait version and format number."""
    return {
        "format": CONFIG_FORMAT,
        "jaxgait_version": jaxgait_version(),
        "experiment": exp.to_dict(),
    }


# ------------------------------------------------------------------------------- model / init


def get_model(name: str, init: str | None = None):
    """The planar simulation model ``name`` from the registry (cached there, so compiled
    rollouts are shared).  A spinal-network model is found by its name when a shipped
    preset defines it, or registered by loading ``init`` (a network preset file)."""
    if not ensure_model(name, init):
        raise TrainError(
            f"model {name!r} cannot be trained here: training runs the planar models "
            f"({', '.join(models.model_names('planar'))})"
        )
    return models.get_model(name)


def resolve_init(init: str | None, table) -> np.ndarray | None:
    """Starting point (D,) of the search: a preset, the table's init (``"table"``) or None.

    A preset is matched to ``table`` by parameter name: names the table lacks are an error,
    names the preset lacks take the table's initial values (so an FBL preset can start a model
    whose table extends FBL's). ``"fbl_walk"`` falls back to
    ``experiments/fbl_walk/run1/best.json`` of a source checkout while the shipped preset is
    missing.
    """
    if init is None:
        return None
    if init == "table":
        return np.asarray(table.init, float)
    try:
        _, _, doc = load_preset(init)
    except PresetError as e:
        if init in EXPERIMENTS:  # a start that an experiment of the registry produces
            raise TrainError(
                f"init preset {init!r} is not shipped yet: it is the best of the experiment "
                f"{init!r}; run `jaxgait train {init}` first and copy its best.json to "
                f"experiments/presets/{init}.json, or start from another preset with "
                f"--set init=NAME"
            ) from e
        if init != "fbl_walk" or not _FBL_WALK_RUN.is_file():
            raise
        _, _, doc = load_preset(_FBL_WALK_RUN)
    values = {str(k): float(v) for k, v in doc.get("params", {}).items()}
    unknown = sorted(set(values) - set(table.names))
    if unknown:
        raise TrainError(
            f"init preset {init!r} has parameters the model's table {table.name!r} lacks: "
            + ", ".join(unknown)
        )
    vec = table.pack(values)
    try:
        table.check(vec, where=f"init preset {init!r}")
    except ValueError as e:
        raise TrainError(str(e)) from None
    return vec
