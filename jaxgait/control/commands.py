"""Commands during a rollout: schedules of a controller's control vector and feedback laws.

A controller declares named command inputs with defaults (:class:`Command`), e.g. the lean
offset of the reflex walkers or the tonic drive u0 of Taga's oscillators.  What they are at
time t comes from

* a :class:`Schedule`: the control vector as a function of time (knot times and values,
  held or linearly interpolated).  It is a pytree of arrays, so a batch of schedules
  ``vmap``s like a batch of environments;
* optionally a :class:`CommandLaw`: static data plus pure ``init``/``step`` with its own
  state, run inside the jitted step after the sensors (an automatic speed or slope
  controller): it receives the scheduled vector and this step's sensors and returns the
  vector the controller uses.

With neither, a controller runs on its defaults (:func:`defaults`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

INTERPOLATIONS = ("hold", "linear")


class CommandError(ValueError):
    """A schedule names an unknown command, or its times or values are malformed."""


@dataclass(frozen=True)
class Command:
    """One command input of a controller: name, default value, unit, meaning and the range a
    feedback law keeps it in (``lower``, ``upper``; unbounded by default)."""

    name: str
    default: float
    unit: str = ""
    doc: str = ""
    lower: float = -np.inf
    upper: float = np.inf


def bounds(commands: Sequence[Command], dtype=jnp.float32) -> tuple[jax.Array, jax.Array]:
    """((C,), (C,)) the declared lower and upper bounds of a control vector."""
    lo = jnp.asarray([c.lower for c in commands], dtype).reshape(len(commands))
    hi = jnp.asarray([c.upper for c in commands], dtype).reshape(len(commands))
    return lo, hi


def names(commands: Sequence[Command]) -> tuple[str, ...]:
    return tuple(c.name for c in commands)


def defaults(commands: Sequence[Command], dtype=jnp.float32) -> jax.Array:
    """(C,) the default control vector in declaration order."""
    return jnp.asarray([c.default for c in commands], dtype).reshape(len(commands))


def as_dict(commands: Sequence[Command], vec: jax.Array) -> dict[str, jax.Array]:
    """name -> () value of a (C,) control vector (static indices, traceable)."""
    return {c.name: vec[i] for i, c in enumerate(commands)}


@struct.dataclass
class Schedule:
    """The control vector as a function of time.

    Attributes:
      t: (K,) knot times [s], non-decreasing.
      values: (K, C) control vector at each knot, columns in the controller's command order.
      interp: "hold" (the value of the last knot at or before t; before the first knot, the
        first value) or "linear" (piecewise linear, constant outside the knots); static.
    """

    t: jax.Array
    values: jax.Array
    interp: str = struct.field(pytree_node=False, default="hold")

    def at(self, t) -> jax.Array:
        """(C,) control vector at time ``t`` [s] (traceable)."""
        if self.interp == "linear":
            return jax.vmap(lambda col: jnp.interp(t, self.t, col), in_axes=1)(self.values)
        i = jnp.clip(jnp.sum(self.t <= t) - 1, 0, self.t.shape[0] - 1)
        return self.values[i]


def _checked_values(commands: Sequence[Command], row: Mapping[str, float], where: str) -> list:
    known = names(commands)
    unknown = sorted(set(row) - set(known))
    if unknown:
        raise CommandError(
            f"{where}: unknown command(s) {', '.join(unknown)}; "
            f"this controller takes: {', '.join(known) or '(none)'}"
        )
    out = []
    for c in commands:
        v = row.get(c.name, c.default)
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
            raise CommandError(f"{where}: command {c.name!r} = {v!r} is not a number")
        if not np.isfinite(v):
            raise CommandError(f"{where}: command {c.name!r} = {v!r} is not finite")
        out.append(float(v))
    return out


def schedule(
    commands: Sequence[Command],
    knots: Sequence[tuple[float, Mapping[str, float]]] | Mapping[str, float] = (),
    interp: str = "hold",
    dtype=jnp.float32,
) -> Schedule:
    """A :class:`Schedule` from knots ``[(t, {name: value}), ...]`` or one ``{name: value}``.

    Commands a knot does not name take their defaults; times must not decrease.  Raises
    :class:`CommandError` for unknown names, non-numbers, bad times or an unknown ``interp``.
    """
    if interp not in INTERPOLATIONS:
        raise CommandError(f"interp must be one of {INTERPOLATIONS}, got {interp!r}")
    if isinstance(knots, Mapping):
        knots = [(0.0, knots)]
    knots = list(knots) or [(0.0, {})]
    times, rows = [], []
    for k, item in enumerate(knots):
        try:
            t, row = item
        except (TypeError, ValueError):
            raise CommandError(
                f"knot {k}: expected (time, {{name: value}}), got {item!r}"
            ) from None
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not np.isfinite(t):
            raise CommandError(f"knot {k}: time {t!r} is not a finite number")
        if times and t < times[-1]:
            raise CommandError(f"knot {k}: time {t} is before the previous knot ({times[-1]})")
        if not isinstance(row, Mapping):
            raise CommandError(f"knot {k}: values must be a mapping name -> value, got {row!r}")
        times.append(float(t))
        rows.append(_checked_values(commands, row, f"knot {k} (t = {t} s)"))
    values = np.asarray(rows, np.float64).reshape(len(rows), len(commands))
    return Schedule(t=jnp.asarray(times, dtype), values=jnp.asarray(values, dtype), interp=interp)


def constant(commands: Sequence[Command], dtype=jnp.float32, **values) -> Schedule:
    """A schedule holding one control vector (defaults where not given) for the whole run."""
    return schedule(commands, values, dtype=dtype)


@dataclass(frozen=True, eq=False)
class CommandLaw:
    """A feedback law on the control vector, run inside the jitted step (static data + pure
    functions).

    Attributes:
      name: label.
      init: ``(law, sensors, command (C,)) -> state`` (any pytree, may be ``None``).
      step: ``(law, state, sensors, command (C,), dt) -> (command (C,), state)``: the
        scheduled vector in, the vector the controller uses out.
      settings: static data of the law (gains, targets, command indices...).
    """

    name: str
    init: Callable[..., Any]
    step: Callable[..., tuple[jax.Array, Any]]
    settings: Any = None
