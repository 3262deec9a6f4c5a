"""Layer 5: one pure step of body + muscles + controller + contact, and rollouts.

The public API in one place: :class:`Model`, :class:`SimConfig`, :class:`SimState`,
:func:`planar_model` (:mod:`jaxgait.sim.model`); :func:`initial_state`, :func:`step`
(:mod:`jaxgait.sim.step`); :func:`rollout`, :func:`make_rollout`, :func:`rollout_steps`
(:mod:`jaxgait.sim.rollout`).  Named models come from :func:`jaxgait.models.get_model`.
"""

from jaxgait.sim.model import (
    CONTACT_SITES,
    DYNAMICS,
    LEG_JOINTS,
    POSES,
    Model,
    SimConfig,
    SimState,
    planar_model,
)
from jaxgait.sim.rollout import make_rollout, rollout, rollout_steps
from jaxgait.sim.step import initial_state, scheduled_command, step

__all__ = [
    "CONTACT_SITES",
    "DYNAMICS",
    "LEG_JOINTS",
    "POSES",
    "Model",
    "SimConfig",
    "SimState",
    "initial_state",
    "make_rollout",
    "planar_model",
    "rollout",
    "rollout_steps",
    "scheduled_command",
    "step",
]
