"""The model registry: every named model, its family, parameter table and commands.

One place that ``evaluate``, ``train``, ``robustness``, the presets and the experiment
registry read.  A :class:`ModelSpec` is small frozen data:

* ``family``: ``"planar"`` (a :class:`~jaxgait.control.interface.Controller` on the planar
  Geyer body, simulated by :mod:`jaxgait.sim`) or ``"taga"`` (Taga's oscillator biped,
  simulated by :mod:`jaxgait.taga`);
* ``table``: the parameter table presets and optimisers use (``None`` for Taga, whose
  presets are :class:`~jaxgait.taga.model.TagaParams` documents);
* ``build(timestep)``: the model object.

:func:`get_model` is the one cached factory (one instance per name and time step in a
process, so compiled rollouts are reused).  A new planar model is one :func:`register` call
with a controller::

    register(planar_spec(my_controller))
    model = get_model(my_controller.name)
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from jaxgait.control.commands import Command
from jaxgait.control.fbl import FBL_CONTROLLER
from jaxgait.control.fblankle import FBL_ANKLE_CONTROLLER
from jaxgait.control.fblplus import FBLPLUS_CONTROLLER
from jaxgait.control.fblplus_bal import (
    FBLPLUS_BAL_CONTROLLER,
    FBLPLUS_BAL_RUN_CONTROLLER,
    FBLPLUS_BAL_RUN_WIDE,
)
from jaxgait.control.gait import GaitConfig
from jaxgait.control.gh2010 import GH2010_CONTROLLER
from jaxgait.control.interface import Controller
from jaxgait.control.speed_lean import speed_regulated
from jaxgait.control.spinal import FBL_NET, FBLPLUS_NET, spinal_controller
from jaxgait.control.wang import WANG_CONTROLLER, WANG_RUN_CONTROLLER, WANG_RUN_LD_CONTROLLER
from jaxgait.core.params import ParamTable, widened
from jaxgait.muscles.tables import GEYER7, MuscleTable, with_headroom
from jaxgait.sim.model import planar_model
from jaxgait.taga.sim import COMMANDS as TAGA_COMMANDS
from jaxgait.taga.sim import default_sim

FAMILIES = ("planar", "taga")


@dataclass(frozen=True)
class ModelSpec:
    """One registered model (static data)."""

    name: str
    family: str
    description: str
    table: ParamTable | None
    commands: tuple[Command, ...]
    build: Callable[[float | None], Any]

    def __post_init__(self):
        if self.family not in FAMILIES:
            raise ValueError(f"model {self.name!r}: family {self.family!r} not in {FAMILIES}")


def planar_spec(
    controller: Controller,
    description: str | None = None,
    *,
    name: str | None = None,
    muscles: MuscleTable | None = None,
) -> ModelSpec:
    """The spec of ``controller`` on the planar Geyer body (:func:`jaxgait.sim.planar_model`,
    with the muscle table of the controller's muscle count unless ``muscles`` is given), under
    the controller's name unless ``name`` is given."""

    def build(timestep=None):
        return planar_model(controller, timestep, name=name, muscles=muscles)

    return ModelSpec(
        name=name or controller.name,
        family="planar",
        description=description or controller.description,
        table=controller.table,
        commands=controller.commands,
        build=build,
    )


def _taga_build(timestep=None):
    return default_sim(timestep)


_REGISTRY: dict[str, ModelSpec] = {}
#: Functions ``name -> bool`` tried, in order, for a name that is not registered: each may
#: register it (e.g. a spinal-network model defined by a shipped preset, registered by
#: :mod:`jaxgait.presets`) and returns whether it did.
_RESOLVERS: list[Callable[[str], bool]] = []


def add_resolver(fn: Callable[[str], bool]) -> None:
    """Add a resolver of unregistered model names (see :data:`_RESOLVERS`)."""
    if fn not in _RESOLVERS:
        _RESOLVERS.append(fn)


@functools.lru_cache(maxsize=16)
def get_model(name: str = "fbl", timestep: float | None = None):
    """The model object of ``name`` (cached per name and time step [s])."""
    return get_spec(name).build(timestep)


def register(spec: ModelSpec, replace: bool = False) -> ModelSpec:
    """Add ``spec`` to the registry (``replace`` to redefine a name); returns it."""
    if spec.name in _REGISTRY and not replace:
        raise ValueError(f"model {spec.name!r} is already registered")
    _REGISTRY[spec.name] = spec
    get_model.cache_clear()
    return spec


def unregister(name: str) -> None:
    """Remove a model (e.g. one a test registered)."""
    _REGISTRY.pop(name, None)
    get_model.cache_clear()


register(planar_spec(FBL_CONTROLLER))
register(planar_spec(FBLPLUS_CONTROLLER))
register(planar_spec(spinal_controller(FBL_NET)))
register(planar_spec(spinal_controller(FBLPLUS_NET)))
register(
    ModelSpec(
        name="taga",
        family="taga",
        description="Taga 1991 neural-oscillator biped (5 links, 12 Matsuoka neurons)",
        table=None,
        commands=TAGA_COMMANDS,
        build=_taga_build,
    )
)
register(planar_spec(WANG_CONTROLLER))
register(planar_spec(WANG_RUN_CONTROLLER))
register(planar_spec(WANG_RUN_LD_CONTROLLER))
register(planar_spec(FBL_ANKLE_CONTROLLER))
register(planar_spec(FBLPLUS_BAL_CONTROLLER))
register(planar_spec(FBLPLUS_BAL_RUN_CONTROLLER))
#: fblplus_bal_run with a wider swing drive, its speed regulated by the trunk lean.
FBLPLUS_RUN_SR = speed_regulated(
    dataclasses.replace(FBLPLUS_BAL_RUN_CONTROLLER, table=FBLPLUS_BAL_RUN_WIDE),
    "fblplus_bal_run_sr",
    "fblplus_bal_run, a wider swing drive, its speed regulated by the trunk lean",
)
register(planar_spec(FBLPLUS_RUN_SR))
#: fblplus_bal_run_sr with swing end reachable before the swing foot passes the CoM:
#: d_sw_end's range [-2.5, 0] (Table 2.6) widened to [-2.5, 1] foot lengths, where the
#: regulated runners sat at the bound (``fblplus_run_2p0``: -0.039, ``fblplus_push_run_1p8``:
#: -0.049); a positive threshold starts the swing-end PD rules (the knee's extension towards
#: delta_knee_ref, the hip's towards its target) while the foot is still behind the CoM.
FBLPLUS_RUN_SR_SE = dataclasses.replace(
    FBLPLUS_RUN_SR,
    name="fblplus_bal_run_sr_se",
    table=widened(
        FBLPLUS_RUN_SR.table,
        "fblplus_bal_run_sr_se",
        {"d_sw_end": (-2.5, 1.0)},
        "; range widened: swing end may start behind the CoM (fblplus_bal_run_sr_se)",
    ),
    description="fblplus_bal_run_sr with swing end allowed to start before the foot passes the CoM",
)
register(planar_spec(FBLPLUS_RUN_SR_SE))
#: fblplus_bal_run_sr with a second regulator on FBL+'s swing-end hip target (gains suffixed
#: ``_h``; either sign: a negative gain lengthens the stride when the run is slow).
FBLPLUS_RUN_SR2 = speed_regulated(
    FBLPLUS_RUN_SR,
    "fblplus_bal_run_sr2",
    "fblplus_bal_run_sr with its speed regulated through the swing-end hip target as well",
    command="hip_target_offset",
    suffix="_h",
    ranges={"k_vp": (-0.3, 0.1), "k_vi": (-0.1, 0.05)},
)
register(planar_spec(FBLPLUS_RUN_SR2))
#: fblplus_bal_run_sr with 25 % headroom in the hip flexor: HFL's stimulation may reach 1.25
#: instead of 1, so the leg pulls exactly as before until HFL saturates and up to 1.25 x its
#: active maximum above (a capacity study, not the thesis's model;
#: :func:`jaxgait.muscles.tables.with_headroom`).  The regulated FBL+ runners hold HFL's
#: activation above 0.95 for 36 % of each swing at 1.8-2.0 m/s and 51-69 % in the faster
#: settings that fall (experiments/running/capacity/saturation.json).
HFL_HEADROOM = 1.25
register(
    planar_spec(
        FBLPLUS_RUN_SR,
        "fblplus_bal_run_sr with 25 % headroom in the hip flexor's stimulation (capacity study)",
        name="fblplus_bal_run_sr_hfl125",
        muscles=with_headroom(GEYER7, {"HFL": HFL_HEADROOM}, "HFL stimulation up to 1.25"),
    )
)
#: The same study with every muscle's stimulation allowed up to 1.25 (the runners' stance
#: muscles VAS, SOL, GLU, HAM, GAS are above 0.95 for 13-39 % of each stance).
register(
    planar_spec(
        FBLPLUS_RUN_SR,
        "fblplus_bal_run_sr with 25 % headroom in every muscle's stimulation (capacity study)",
        name="fblplus_bal_run_sr_hr125",
        muscles=with_headroom(
            GEYER7, dict.fromkeys(GEYER7.names, HFL_HEADROOM), "every stimulation up to 1.25"
        ),
    )
)
register(
    planar_spec(
        speed_regulated(
            WANG_RUN_CONTROLLER,
            "wang8_run_sr",
            "wang8_run with its speed regulated through the stance trunk targets",
        )
    )
)


def _gh2010_build(timestep=None):
    return planar_model(GH2010_CONTROLLER, timestep, gait=GaitConfig(load_signal="thigh_sheet"))


register(
    ModelSpec(
        name="fbl_gh2010",
        family="planar",
        description=GH2010_CONTROLLER.description,
        table=GH2010_CONTROLLER.table,
        commands=GH2010_CONTROLLER.commands,
        build=_gh2010_build,
    )
)


def model_names(family: str | None = None) -> tuple[str, ...]:
    """Registered names, in registration order (only ``family``'s if given)."""
    return tuple(n for n, s in _REGISTRY.items() if family is None or s.family == family)


def get_spec(name: str) -> ModelSpec:
    """The :class:`ModelSpec` of ``name``; ``KeyError`` listing the registered names."""
    if name not in _REGISTRY:
        for fn in _RESOLVERS:
            if fn(name) and name in _REGISTRY:
                break
    try:
        return _REGISTRY[name]
    except KeyError:
        raise KeyError(f"unknown model {name!r}; registered: {', '.join(model_names())}") from None


def param_tables() -> dict[str, ParamTable]:
    """Parameter table name -> table, of every registered model that has one."""
    return {s.table.name: s.table for s in _REGISTRY.values() if s.table is not None}


def describe_models() -> str:
    """One line per registered model: name, family, parameters, commands, description."""
    lines = []
    for s in _REGISTRY.values():
        n = f"{s.table.size} parameters" if s.table is not None else "preset parameters"
        cmds = ", ".join(c.name for c in s.commands) or "none"
        lines.append(f"{s.name:<10} {s.family:<7} {n:<18} commands: {cmds:<32} {s.description}")
    return "\n".join(lines)
