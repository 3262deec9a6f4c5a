"""Declared parameter tables: every free parameter once, with start value, range and source.

A :class:`ParamTable` is static data (like a SCONE ``.par`` declaration).  Parameter sets
are flat float vectors (D,) in table order, which is what the optimisers see;
``table.unpack(vec)`` gives a name -> scalar mapping inside jitted code (static indices).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import jax.numpy as jnp
import numpy as np


@dataclass(frozen=True)
class ParamSpec:
    name: str
    init: float
    lower: float
    upper: float
    source: str
    unit: str = ""


@dataclass(frozen=True)
class ParamTable:
    name: str
    specs: tuple[ParamSpec, ...]

    def __post_init__(self):
        names = [s.name for s in self.specs]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate parameter names in table {self.name!r}")
        for s in self.specs:
            if not (s.lower <= s.init <= s.upper):
                raise ValueError(
                    f"table {self.name!r}: {s.name} init {s.init} outside [{s.lower}, {s.upper}]"
                )

    # ------------------------------------------------------------------ access
    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.specs)

    @property
    def size(self) -> int:
        return len(self.specs)

    @property
    def lower(self) -> np.ndarray:
        return np.array([s.lower for s in self.specs])

    @property
    def upper(self) -> np.ndarray:
        return np.array([s.upper for s in self.specs])

    @property
    def init(self) -> np.ndarray:
        return np.array([s.init for s in self.specs])

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(
                f"unknown parameter {name!r} for table {self.name!r}; "
                f"known: {', '.join(self.names)}"
            ) from None

    def unpack(self, vec) -> dict:
        """name -> scalar (static slicing, fine inside jit/vmap)."""
        if vec.shape[-1] != self.size:
            raise ValueError(
                f"parameter vector has {vec.shape[-1]} entries, table {self.name!r} has {self.size}"
            )
        return {n: vec[..., i] for i, n in enumerate(self.names)}

    def pack(self, values: dict, base=None) -> np.ndarray:
        """Vector from a name -> value mapping; missing names take ``base`` (or init)."""
        out = np.array(self.init if base is None else base, dtype=float).copy()
        for k, v in values.items():
            out[self.index(k)] = float(v)
        return out

    def check(self, vec, where: str = "parameters") -> None:
        """Raise a ValueError naming every entry outside its range (or not finite)."""
        vec = np.asarray(vec, dtype=float)
        if vec.shape != (self.size,):
            raise ValueError(f"{where}: expected {self.size} values, got shape {vec.shape}")
        bad = [
            f"{s.name}={v:g} not in [{s.lower:g}, {s.upper:g}]"
            for s, v in zip(self.specs, vec, strict=True)
            if not (np.isfinite(v) and s.lower <= v <= s.upper)
        ]
        if bad:
            raise ValueError(f"{where}: out of range: " + "; ".join(bad))

    def to_table(self, vec) -> str:
        """Readable table (name, value, range, source)."""
        vec = np.asarray(vec, dtype=float)
        w = max(len(n) for n in self.names)
        lines = [f"# {self.name}: {self.size} parameters", f"{'name':<{w}}  value        range"]
        for s, v in zip(self.specs, vec, strict=True):
            lines.append(
                f"{s.name:<{w}}  {v:<11.6g}  [{s.lower:g}, {s.upper:g}] {s.unit}  # {s.source}"
            )
        return "\n".join(lines) + "\n"

    def as_jnp(self, vec, dtype=jnp.float32):
        return jnp.asarray(vec, dtype)


def save_preset(path: Path, model: str, table: ParamTable, vec, **meta) -> None:
    """Write a preset JSON that ``python -m jaxgait.evaluate`` accepts."""
    vec = np.asarray(vec, dtype=float)
    doc = {"model": model, "table": table.name, **meta}
    doc["params"] = {n: float(v) for n, v in zip(table.names, vec, strict=True)}
    path = Path(path)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(doc, indent=2) + "\n")
    tmp.replace(path)


def widened(table: ParamTable, name: str, ranges: dict[str, tuple[float, float]], why: str):
    """``table`` renamed ``name``, with the ``ranges`` (name -> (lower, upper)) replacing the
    listed entries' ranges (each must contain the old range, so every vector valid in
    ``table`` is valid in the new one) and ``why`` appended to their sources."""
    unknown = sorted(set(ranges) - set(table.names))
    if unknown:
        raise ValueError(f"table {table.name!r} has no parameters {unknown}")
    specs = []
    for s in table.specs:
        if s.name in ranges:
            lo, hi = ranges[s.name]
            if lo > s.lower or hi < s.upper:
                raise ValueError(
                    f"{s.name}: [{lo:g}, {hi:g}] does not contain [{s.lower:g}, {s.upper:g}]"
                )
            s = dataclasses.replace(s, lower=float(lo), upper=float(hi), source=s.source + why)
        specs.append(s)
    return ParamTable(name, tuple(specs))
