"""Speed regulation through the trunk-lean reference (a wrapper for reflex controllers).

The FBL+ runners found under body-weight support (``experiments/running``) run without it
for 10-20 s and then fall backwards: their forward speed decays steadily, about 0.1 m/s per
second, from 2.5 m/s to a stop.  Nothing in FBL or FBL+ regulates the speed; the trunk-lean
reference theta_ref sets it (a reference 0.005 rad further forward accelerates such a
runner, 0.005 rad further back decelerates it), as a runner leans into a faster pace.
:func:`speed_regulated` closes that loop with a PI law on the lean command every step:

    v' = (v_com - v) / tau_vr             (the speed filtered over about a stride)   [m/s]
    e = v_reg - v,  I' = e,  I clamped to [-i_max_vr, i_max_vr]                        [m]
    lean_offset <- lean_offset + clip(k_vp e + k_vi I, -lean_max, lean_max)          [rad]

(positive offsets lean forwards; ``lean_offset`` is the reflex laws' command added to
theta_ref, :func:`jaxgait.control.fbl.with_commands`).  The five gains v_reg, k_vp, k_vi,
tau_vr and i_max_vr are entries of the wrapped controller's table (:data:`REGULATOR_SPECS`), so
an optimiser searches them with the reflex gains; lean_max is fixed data.  With
k_vp = k_vi = 0 the offset is zero and the controller moves as the one it wraps.

The same law can offset another command of the wrapped controller (``command=``, e.g. FBL+'s
swing-end hip target ``hip_target_offset``), with its gains' names suffixed (``suffix=``) so
that two regulators can wrap one controller.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from jaxgait.control.interface import Controller, Sensors
from jaxgait.core.params import ParamSpec, ParamTable

_S = "speed regulation by trunk lean (jaxgait.control.speed_lean)"

#: The regulator's gains, appended to the wrapped controller's table.  Initial values leave
#: the lean alone (k_vp = k_vi = 0).
REGULATOR_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("v_reg", 2.5, 0.5, 5.0, "target forward speed; " + _S, "m/s"),
    ParamSpec("k_vp", 0.0, 0.0, 0.1, "lean per m/s of speed error; " + _S, "rad s/m"),
    ParamSpec("k_vi", 0.0, 0.0, 0.05, "lean per m of integrated speed error; " + _S, "rad/m"),
    ParamSpec("tau_vr", 1.0, 0.2, 3.0, "speed filter time constant; " + _S, "s"),
    ParamSpec("i_max_vr", 2.0, 0.1, 10.0, "anti-windup bound of the integral; " + _S, "m"),
)
REGULATOR_NAMES: tuple[str, ...] = tuple(s.name for s in REGULATOR_SPECS)


@dataclass(frozen=True, eq=False)
class SpeedLeanSettings:
    """Static data of the wrapper: the wrapped controller, the command the regulator offsets
    (``lean_offset`` by default), the suffix of its parameter names and the offset's bound
    lean_max [rad]."""

    base: Controller
    lean_max: float = 0.1
    command: str = "lean_offset"
    suffix: str = ""


@struct.dataclass
class SpeedLeanState:
    """The wrapped controller's state, the filtered speed v [m/s] and the integral I [m]."""

    base: Any
    v: jax.Array
    integral: jax.Array


def lean_command(p: dict, v, integral, lean_max: float):
    """clip(k_vp (v_reg - v) + k_vi I, -lean_max, lean_max) [rad] (module docstring)."""
    u = p["k_vp"] * (p["v_reg"] - v) + p["k_vi"] * integral
    return jnp.clip(u, -lean_max, lean_max)


def filter_and_integrate(v, integral, v_com, target, a, dt, i_max):
    """One step of a speed filter, v <- v + a (v_com - v) (``a`` the step's share of the
    filter, e.g. dt / tau), and of the error's integral, I <- clip(I + dt (target - v),
    -i_max, i_max) [m]: (v, I).  Shared with :mod:`jaxgait.control.autopilot`."""
    v = v + a * (v_com - v)
    return v, jnp.clip(integral + dt * (target - v), -i_max, i_max)


def regulator_update(p: dict, state_v, state_i, v_com, dt):
    """One step of the speed filter (a = dt / tau_vr) and of the integral clamped to
    [-i_max_vr, i_max_vr]: (v, I)."""
    a = dt / p["tau_vr"]
    return filter_and_integrate(state_v, state_i, v_com, p["v_reg"], a, dt, p["i_max_vr"])


def _init(ctrl: Controller, sens: Sensors, dt) -> SpeedLeanState:
    s = ctrl.settings
    v0 = sens.com_vel[0]
    return SpeedLeanState(base=s.base.init(s.base, sens, dt), v=v0, integral=jnp.zeros_like(v0))


def _step(ctrl: Controller, p: dict, sens: Sensors, state: SpeedLeanState, command: dict, dt):
    s = ctrl.settings
    g = {n: p[n + s.suffix] for n in REGULATOR_NAMES}
    v, integral = regulator_update(g, state.v, state.integral, sens.com_vel[0], dt)
    u = lean_command(g, v, integral, s.lean_max)
    command = {**command, s.command: command[s.command] + u}
    stim, base_state = s.base.step(s.base, p, sens, state.base, command, dt)
    return stim, SpeedLeanState(base=base_state, v=v, integral=integral)


def speed_regulated(
    base: Controller,
    name: str,
    description: str | None = None,
    command: str = "lean_offset",
    suffix: str = "",
    ranges: dict[str, tuple[float, float]] | None = None,
) -> Controller:
    """``base`` with the speed regulator (module docstring), named ``name``: its table is
    ``base``'s followed by :data:`REGULATOR_SPECS` (each name with ``suffix`` appended), so a
    ``base`` vector followed by the five gains is a vector of the new model.  ``command``
    names the command the regulator offsets: ``lean_offset`` (the trunk lean) by default;
    another, such as FBL+'s ``hip_target_offset`` (the swing-end hip target, where a
    positive offset places the foot less far forwards), is offset the same way, forwards when
    slower than v_reg.  ``ranges`` replaces the (lower, upper) bounds of gains named as in
    :data:`REGULATOR_NAMES` (unsuffixed), e.g. negative k_vp and k_vi for a regulator whose
    useful sign is not known beforehand; each initial value must lie in its new range.

    Raises:
      ValueError: ``base`` has no such command, or already has a regulator entry; ``ranges``
        names an unknown gain or a range that excludes its initial value.
    """
    if command not in base.command_names:
        raise ValueError(f"controller {base.name!r} has no {command} command to regulate")
    ranges = dict(ranges or {})
    unknown = sorted(set(ranges) - set(REGULATOR_NAMES))
    if unknown:
        raise ValueError(f"ranges name no regulator gain: {unknown} (gains: {REGULATOR_NAMES})")
    specs = []
    for sp in REGULATOR_SPECS:
        lo, hi = ranges.get(sp.name, (sp.lower, sp.upper))
        if not lo <= sp.init <= hi:
            raise ValueError(f"range ({lo}, {hi}) of {sp.name} excludes its initial {sp.init}")
        specs.append(dataclasses.replace(sp, name=sp.name + suffix, lower=lo, upper=hi))
    specs = tuple(specs)
    clash = sorted({sp.name for sp in specs} & set(base.table.names))
    if clash:
        raise ValueError(f"controller {base.name!r} already has parameters {clash}")
    return dataclasses.replace(
        base,
        name=name,
        table=ParamTable(name, base.table.specs + specs),
        init=_init,
        step=_step,
        settings=SpeedLeanSettings(base=base, command=command, suffix=suffix),
        initial_offsets=None
        if base.initial_offsets is None
        else (lambda ctrl, p: base.initial_offsets(base, p)),
        description=description or base.description + f", speed regulated through {command}",
    )
