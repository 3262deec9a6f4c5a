"""Population optimisers with one ask/tell interface (thesis 2.2.1, SPEC §4).

* ``"pso"``: particle swarm optimisation, thesis eq. 2.45-2.46 (:class:`PSO`).
* ``"stage_pso"``: stage PSO, thesis 2.2.1.2 / Table 2.8 (:class:`StagePSO`), fitness is a
  ``(stage, value)`` pair with value maximised.
* ``"cmaes"``: CMA-ES through evosax in normalised box coordinates (:class:`CMAES`).

All take parameters in a box (``bounds = (lower, upper)``), return candidates inside it, and keep
their state in an array-only pytree that goes through ``jax.lax.scan``. See
:mod:`jaxgait.optim.base` for the protocol and the fitness convention (lower is better, NaN is the
worst).
"""

from __future__ import annotations

from typing import Any

from .base import (
    Bounds,
    Strategy,
    as_bounds,
    denormalize,
    normalize,
    reflect_unit,
    sanitize_fitness,
)
from .cmaes import CMAES, CMAESState
from .pso import PSO, PSOState, SwarmState, move_swarm
from .stage_pso import (
    INVALID_STAGE,
    StagePSO,
    StagePSOState,
    canonical_stage,
    evaluate_stages,
    stage_argbest,
    stage_better,
    stage_rank_key,
    threshold_entrance,
)

#: Registry of optimisers by name; every entry follows :class:`Strategy`.
STRATEGIES: dict[str, type] = {"pso": PSO, "stage_pso": StagePSO, "cmaes": CMAES}


def make_strategy(name: str, popsize: int, **kwargs: Any) -> Strategy:
    """Build the optimiser ``name`` from :data:`STRATEGIES` with ``popsize`` candidates.

    Args:
        name: ``"pso"``, ``"stage_pso"`` or ``"cmaes"``.
        popsize: population size P.
        **kwargs: hyper-parameters of that strategy (e.g. ``omega`` for PSO, ``sigma_init`` for
            CMA-ES).

    Raises:
        ValueError: unknown ``name``.
        TypeError: a keyword the strategy does not have.
    """
    try:
        cls = STRATEGIES[name]
    except KeyError:
        raise ValueError(
            f"unknown optimiser {name!r}; choose one of {sorted(STRATEGIES)}"
        ) from None
    return cls(popsize=popsize, **kwargs)


__all__ = [
    "Bounds",
    "CMAES",
    "CMAESState",
    "INVALID_STAGE",
    "PSO",
    "PSOState",
    "STRATEGIES",
    "StagePSO",
    "StagePSOState",
    "Strategy",
    "SwarmState",
    "as_bounds",
    "canonical_stage",
    "denormalize",
    "evaluate_stages",
    "make_strategy",
    "move_swarm",
    "normalize",
    "reflect_unit",
    "sanitize_fitness",
    "stage_argbest",
    "stage_better",
    "stage_rank_key",
    "threshold_entrance",
]
