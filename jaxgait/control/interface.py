"""The controller interface: static data plus pure ``init`` / ``step`` functions.

A :class:`Controller` is what the simulator needs to know of a neural controller:

* its parameter table (:class:`~jaxgait.core.params.ParamTable`: what the optimisers search),
* the number of muscles per leg it stimulates (the model's muscle table must match),
* its command inputs (:class:`~jaxgait.control.commands.Command`: the control vector, with
  defaults, that a schedule or a feedback law may change during a rollout),
* ``init(ctrl, sensors, dt) -> state``: its own state (any pytree, kept in ``SimState.ctrl``),
* ``step(ctrl, p, sensors, state, command, dt) -> (stim (2, n_muscles), state)``: this step's
  stimulation of every muscle from the parameters ``p`` (name -> value, from
  ``table.unpack``), this step's :class:`Sensors`, its state and the command
  (name -> value).

``settings`` holds whatever static data the functions read (delays, the law, a network of
interneurons...), so a new model is a new instance, not a new step.  The simulator builds
the :class:`Sensors` once per step, shared by the controller and any command law; fields a
controller does not read cost nothing after XLA's dead-code elimination.

Gait-phase detection (:mod:`jaxgait.control.gait`) is shared by every controller and by the
logs: ``Sensors.load``, ``stance``, ``touchdown``, ``double_support`` and ``theta_to`` come
from it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax
from flax import struct

from jaxgait.control.commands import Command, names
from jaxgait.core.params import ParamTable


@struct.dataclass
class Sensors:
    """What a controller can read at one physics step (legs 0 = right, 1 = left).

    Attributes:
      t: () time [s].
      f_mtu: (2, M) muscle-tendon force [N].
      f_norm: (2, M) force feedback F_mtu / F_max [-] (thesis eq. 2.31).
      l_ce: (2, M) contractile-element length [m].
      l_norm: (2, M) length feedback l_ce / l_opt [-] (thesis eq. 2.32, before the offset).
      phi: (2, 3) hip, knee, ankle angles in the Geyer-Herr convention [rad].
      dphi: (2, 3) their rates [rad/s].
      trunk: () trunk pitch, forward lean + [rad]; dtrunk: () its rate [rad/s].
      load: (2,) filtered ground load per leg / (M g) (thesis eq. 2.34).
      stance: (2,) bool, leg in stance.
      touchdown: (2,) bool, the leg touched down at this step.
      double_support: (2,) bool, trailing leg in double support (stance end).
      theta_to: (2,) trunk pitch at each leg's last take-off [rad].
      com: (2,) centre of mass (x, z) [m]; com_vel: (2,) its velocity [m/s].
      feet: (4, 2) heel_r, ball_r, heel_l, ball_l positions (x, z) [m].
      dcom: (2,) (x_CoM - x_ball) / foot length per leg [-]: CoM ahead of the ball +.
      ankle: (2, 2) ankle positions (x, z) per leg [m]; ankle_vel: (2, 2) their velocities
        [m/s].
      dleg: (2,) (x_CoM - x_ankle) / leg length per leg [-]: CoM ahead of the ankle +.
    """

    t: jax.Array
    f_mtu: jax.Array
    f_norm: jax.Array
    l_ce: jax.Array
    l_norm: jax.Array
    phi: jax.Array
    dphi: jax.Array
    trunk: jax.Array
    dtrunk: jax.Array
    load: jax.Array
    stance: jax.Array
    touchdown: jax.Array
    double_support: jax.Array
    theta_to: jax.Array
    com: jax.Array
    com_vel: jax.Array
    feet: jax.Array
    dcom: jax.Array
    ankle: jax.Array
    ankle_vel: jax.Array
    dleg: jax.Array


def com_over_other_ankle(sens: Sensors) -> tuple[jax.Array, jax.Array]:
    """SIMBICON's balance inputs per leg (Yin et al. 2007; Wang et al. 2012 section 4.3):
    ``(d, v)`` (2,), the CoM's horizontal offset [m] and velocity [m/s] relative to the other
    (stance) leg's ankle."""
    d = sens.com[0] - sens.ankle[::-1][:, 0]
    v = sens.com_vel[0] - sens.ankle_vel[::-1, 0]
    return d, v


@dataclass(frozen=True, eq=False)
class Controller:
    """A controller as static data plus pure functions (see the module docstring).

    Attributes:
      name: registry name (also the default model name).
      table: its parameter table.
      n_muscles: muscles per leg it stimulates.
      init: ``(ctrl, sensors, dt) -> state``.
      step: ``(ctrl, p, sensors, state, command, dt) -> (stim (2, n_muscles), state)``.
      commands: its command inputs, in control-vector order.
      settings: static data the functions read.
      description: one line for listings.
      initial_offsets: ``None`` or ``(ctrl, p) -> (dq (7,), dv)``: parameter-dependent
        offsets of the initial posture (trunk pitch, then hip, knee, ankle of the stance leg
        and of the swing leg, Winter convention [rad]) and of the initial forward speed
        [m/s], added to the simulator's pose and ``v0`` (:func:`jaxgait.sim.initial_state`).
    """

    name: str
    table: ParamTable
    n_muscles: int
    init: Callable[..., Any]
    step: Callable[..., tuple[jax.Array, Any]]
    commands: tuple[Command, ...] = ()
    settings: Any = None
    description: str = ""
    initial_offsets: Callable[..., tuple[jax.Array, jax.Array]] | None = None

    @property
    def command_names(self) -> tuple[str, ...]:
        return names(self.commands)
