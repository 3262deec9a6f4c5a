"""Shared pieces of the population optimisers: box bounds, the ask/tell protocol, fitness hygiene.

Every optimiser in :mod:`jaxgait.optim` has the same evosax-style shape::

    state = strategy.init(key, bounds, init_mean)      # pytree of arrays only
    population, state = strategy.ask(key, state)       # (P, D), inside the bounds
    fitness = evaluate(population)                     # (P,), lower is better
    state = strategy.tell(state, population, fitness)
    params, fitness = strategy.best(state)

The state is a frozen ``flax.struct`` pytree holding arrays only, so it goes through
``jax.lax.scan``, ``jax.vmap`` and orbax checkpoints unchanged. Strategies are frozen (hashable)
dataclasses holding only Python hyper-parameters; they can be closed over or passed as a static
argument to ``jax.jit``. Nothing here is jitted: ``jit`` belongs at the top (one generation step).

Parameters are real vectors (D,) living in a box ``[lower, upper]`` (thesis 2.2.1: each parameter
has a range, Tables 2.5-2.6). Optimisers return candidates inside the box.

Fitness convention (as evosax): LOWER IS BETTER, and a NaN fitness (a failed rollout) is treated
as ``+inf``, the worst possible value; it never becomes a best and never enters the state.
The stage PSO is the one exception: its fitness is a ``(stage, value)`` pair, see
:mod:`jaxgait.optim.stage_pso`.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

Array = jax.Array


@struct.dataclass
class Bounds:
    """Box of admissible parameters.

    Attributes:
        lower: (D,) lower bound of each parameter.
        upper: (D,) upper bound of each parameter, ``upper > lower``.
    """

    lower: Array
    upper: Array

    @property
    def range(self) -> Array:
        """(D,) width ``upper - lower`` of each parameter range."""
        return self.upper - self.lower

    @property
    def num_dims(self) -> int:
        """Number of parameters D."""
        return self.lower.shape[-1]


def _is_concrete(x: Any) -> bool:
    return not isinstance(x, jax.core.Tracer)


def as_bounds(bounds: Any) -> Bounds:
    """Convert ``bounds`` to :class:`Bounds`.

    Args:
        bounds: a :class:`Bounds`, a pair ``(lower, upper)`` of (D,) arrays, or a (2, D) array.

    Returns:
        :class:`Bounds` with floating (D,) ``lower`` and ``upper``.

    Raises:
        ValueError: shapes differ, are not 1-D, or (for concrete values) a bound is not finite or
            ``upper <= lower``.
    """
    if isinstance(bounds, Bounds):
        lower, upper = bounds.lower, bounds.upper
    else:
        lower, upper = bounds[0], bounds[1]
    dtype = jnp.result_type(float)
    lower = jnp.asarray(lower, dtype)
    upper = jnp.asarray(upper, dtype)
    if lower.ndim != 1 or lower.shape != upper.shape:
        raise ValueError(
            f"bounds must be two (D,) arrays, got shapes {lower.shape} and {upper.shape}"
        )
    if _is_concrete(lower) and _is_concrete(upper):
        lo, hi = np.asarray(lower), np.asarray(upper)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise ValueError("bounds must be finite")
        if np.any(hi <= lo):
            bad = np.nonzero(hi <= lo)[0].tolist()
            raise ValueError(f"bounds need upper > lower; violated at indices {bad}")
    return Bounds(lower=lower, upper=upper)


def sanitize_fitness(fitness: Array) -> Array:
    """Map NaN fitness to ``+inf`` (the worst value under minimisation).

    Args:
        fitness: (P,) fitness, lower is better.

    Returns:
        (P,) floating fitness without NaN.
    """
    fitness = jnp.asarray(fitness)
    if not jnp.issubdtype(fitness.dtype, jnp.floating):
        fitness = fitness.astype(jnp.result_type(float))
    return jnp.where(jnp.isnan(fitness), jnp.inf, fitness)


def normalize(x: Array, lower: Array, upper: Array) -> Array:
    """Map real parameters to box coordinates in [0, 1]: ``(x - lower) / (upper - lower)``."""
    return (x - lower) / (upper - lower)


def denormalize(z: Array, lower: Array, upper: Array) -> Array:
    """Map box coordinates in [0, 1] back to real parameters: ``lower + z (upper - lower)``."""
    return lower + z * (upper - lower)


def reflect_unit(z: Array) -> Array:
    """Fold any real ``z`` into [0, 1] by mirror reflection at 0 and 1 (a triangle wave).

    ``z`` already in [0, 1] is unchanged; ``-0.2 -> 0.2``, ``1.3 -> 0.7``, ``2.4 -> 0.4``. The fold
    is continuous and keeps the density of a sample near a bound instead of piling mass onto it
    as clipping does. A final clip guards against rounding.
    """
    t = jnp.mod(z, 2.0)
    return jnp.clip(jnp.where(t > 1.0, 2.0 - t, t), 0.0, 1.0)


@runtime_checkable
class Strategy(Protocol):
    """Interface shared by all optimisers (evosax ask/tell shape).

    Attributes:
        popsize: number P of candidates per generation.
    """

    popsize: int

    def init(self, key: Array, bounds: Any, init_mean: Array | None = None) -> Any:
        """Create the optimiser state for parameters in ``bounds`` (see :func:`as_bounds`).

        ``init_mean`` (D,) is an optional starting point inside the box (default: box centre).
        """
        ...

    def ask(self, key: Array, state: Any) -> tuple[Array, Any]:
        """Return ``(population (P, D) inside the bounds, new state)``."""
        ...

    def tell(self, state: Any, population: Array, fitness: Any) -> Any:
        """Update the state with the fitness of ``population`` (the array returned by ``ask``)."""
        ...

    def best(self, state: Any) -> tuple[Array, Any]:
        """Return ``(best parameters (D,), their fitness)`` seen so far."""
        ...
