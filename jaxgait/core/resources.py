"""Locate the files jaxgait ships: MJCF models, presets and human reference data.

In a source checkout the models live in the top-level ``models/`` folder and presets in
``experiments/presets/``; an installed wheel carries both inside ``jaxgait/_resources``.
"""

from __future__ import annotations

from pathlib import Path

_PKG = Path(__file__).resolve().parent.parent  # the jaxgait package
_REPO = _PKG.parent


def _first_existing(*candidates: Path) -> Path:
    for c in candidates:
        if c.exists():
            return c
    raise FileNotFoundError(
        "jaxgait resource not found; looked in: " + ", ".join(str(c) for c in candidates)
    )


def models_dir() -> Path:
    """Folder holding the MJCF files."""
    return _first_existing(_PKG / "_resources" / "models", _REPO / "models")


def presets_dir() -> Path:
    """Folder holding the shipped parameter presets (``*.json``)."""
    return _first_existing(_PKG / "_resources" / "presets", _REPO / "experiments" / "presets")


def data_dir() -> Path:
    """Folder holding the human reference gait data (CSV, with SOURCES.md)."""
    return _PKG / "data"


def model_path(name: str) -> Path:
    """Path of the MJCF model ``name`` (with or without ``.xml``)."""
    fname = name if name.endswith(".xml") else name + ".xml"
    p = models_dir() / fname
    if not p.exists():
        avail = sorted(x.stem for x in models_dir().glob("*.xml"))
        raise FileNotFoundError(f"no MJCF model {name!r} in {models_dir()}; available: {avail}")
    return p
