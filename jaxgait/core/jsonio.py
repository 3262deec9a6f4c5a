"""JSON-able values from NumPy / JAX results (for reports, measures and run files)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np


def json_safe(x):
    """Python scalars / lists / dicts for JSON: NumPy and JAX numbers converted, NaN -> None."""
    if isinstance(x, dict):
        return {str(k): json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, (str, type(None))):
        return x
    if isinstance(x, Path):
        return str(x)
    a = np.asarray(x)
    if a.ndim > 0:
        return [json_safe(v) for v in a.tolist()]
    if a.dtype == bool:
        return bool(a)
    if np.issubdtype(a.dtype, np.integer):
        return int(a)
    if np.issubdtype(a.dtype, np.number):
        v = float(a)
        return v if math.isfinite(v) else None
    return str(x)


def parse_assignment(item: str) -> tuple[str, Any] | None:
    """``"key=value"`` of a command-line option -> ``(key, value)``, None if malformed.

    The value is JSON (``null``, ``true``, numbers, lists, strings in quotes); anything that
    is not JSON is taken as a string; ``inf`` is infinity.  The key is stripped and non-empty.
    """
    key, sep, raw = item.partition("=")
    key = key.strip()
    if not sep or not key:
        return None
    if raw.strip() in ("inf", "+inf", "Infinity"):
        return key, math.inf
    try:
        return key, json.loads(raw)
    except json.JSONDecodeError:
        return key, raw
