"""CMA-ES (Hansen's covariance matrix adaptation) through evosax, in the box interface.

evosax's ``CMA_ES`` does the sampling and the updates; this wrapper adds the box:

* Normalised coordinates: CMA-ES runs on ``z = (x - lower) / (upper - lower)`` in [0, 1]^D, so
  parameters whose ranges differ by orders of magnitude get the same initial step size. The
  initial mean is ``init_mean`` (default: box centre) and the initial step size is
  ``sigma_init`` in these coordinates, i.e. a fraction of each range.
* Bounds by reflection: a sample outside [0, 1] is mirrored back into it
  (:func:`jaxgait.optim.base.reflect_unit`), so every candidate returned by ``ask`` lies in the
  box, without piling probability mass onto the bounds as clipping does.
* Lamarckian update: ``tell`` gives CMA-ES the candidates actually evaluated (the reflected
  ones, mapped back to [0, 1]). The new mean is a positively weighted average of in-box
  candidates, so it stays in the box.
* Fitness is lower-is-better; NaN counts as ``+inf``. When every candidate of a generation is
  ``+inf``/NaN, the distribution is left unchanged (only the generation counter advances).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from evosax.algorithms import CMA_ES
from flax import struct

from .base import Array, as_bounds, denormalize, normalize, reflect_unit, sanitize_fitness


@functools.lru_cache(maxsize=64)
def _evosax_cma(popsize: int, num_dims: int, dtype: str) -> tuple[CMA_ES, Any]:
    """One evosax CMA_ES and its default params per (P, D, float dtype).

    Reusing the object keeps evosax's jit caches warm. The params are computed once, by one
    ahead-of-time compiled call, so they are concrete arrays even when first requested while
    tracing (a cached tracer would leak into later traces).
    """
    with jax.ensure_compile_time_eval():
        es = CMA_ES(population_size=popsize, solution=np.zeros((num_dims,), dtype))
    params = jax.jit(lambda: es.default_params).lower().compile()()
    return es, params


def _strong(tree: Any) -> Any:
    """Drop weak types so the state has one fixed type as a ``lax.scan`` carry."""
    return jax.tree.map(lambda a: jnp.asarray(a, jnp.asarray(a).dtype), tree)


@struct.dataclass
class CMAESState:
    """State of :class:`CMAES`.

    Attributes:
        es: evosax ``CMA_ES`` state in normalised [0, 1] coordinates (mean (D,), std (), p_std,
            p_c (D,), C, B (D, D), D (D,), its own best and generation counter).
        lower: (D,) lower bounds.
        upper: (D,) upper bounds.
        best_params: (D,) best evaluated parameters in real coordinates (``init_mean`` or the box
            centre before a valid evaluation).
        best_fitness: () their fitness, ``+inf`` before a valid evaluation.
        generation: () int32, number of ``tell`` calls so far.
    """

    es: Any
    lower: Array
    upper: Array
    best_params: Array
    best_fitness: Array
    generation: Array


@dataclasses.dataclass(frozen=True)
class CMAES:
    """CMA-ES (evosax ``CMA_ES``) on box-bounded parameters, lower fitness is better.

    Attributes:
        popsize: population size P (>= 2).
        sigma_init: initial step size as a fraction of each parameter range.
    """

    popsize: int
    sigma_init: float = 0.3

    def __post_init__(self):
        if int(self.popsize) != self.popsize or self.popsize < 2:
            raise ValueError(f"CMA-ES needs an integer popsize >= 2, got {self.popsize}")
        if not self.sigma_init > 0:
            raise ValueError(f"sigma_init must be > 0, got {self.sigma_init}")

    def _es(self, lower: Array) -> tuple[CMA_ES, Any]:
        dtype = jnp.dtype(lower.dtype)
        es, params = _evosax_cma(int(self.popsize), int(lower.shape[0]), dtype.name)
        params = params.replace(std_init=jnp.asarray(self.sigma_init, dtype))
        return es, params

    def init(self, key: Array, bounds: Any, init_mean: Array | None = None) -> CMAESState:
        """Initial distribution N(init_mean, (sigma_init range)^2) in the box."""
        b = as_bounds(bounds)
        lower, upper = b.lower, b.upper
        if init_mean is None:
            mean = 0.5 * (lower + upper)
        else:
            mean = jnp.clip(jnp.asarray(init_mean, lower.dtype), lower, upper)
        es, params = self._es(lower)
        z_mean = normalize(mean, lower, upper)
        es_state = _strong(es.init(key, z_mean, params))
        # evosax marks "no best yet" with a NaN solution; keep the state NaN-free instead
        es_state = es_state.replace(best_solution=z_mean.astype(es_state.best_solution.dtype))
        return CMAESState(
            es=es_state,
            lower=lower,
            upper=upper,
            best_params=mean,
            best_fitness=jnp.asarray(jnp.inf, lower.dtype),
            generation=jnp.zeros((), jnp.int32),
        )

    def ask(self, key: Array, state: CMAESState) -> tuple[Array, CMAESState]:
        """Sample P candidates, reflect them into the box, return them in real coordinates."""
        es, params = self._es(state.lower)
        z, es_state = es.ask(key, state.es, params)
        x = denormalize(reflect_unit(z), state.lower, state.upper)
        x = jnp.clip(x, state.lower, state.upper)
        return x, state.replace(es=es_state)

    def tell(self, state: CMAESState, population: Array, fitness: Array) -> CMAESState:
        """Update the distribution with the (P,) ``fitness`` of ``population`` (lower better)."""
        es, params = self._es(state.lower)
        f = sanitize_fitness(fitness).astype(state.best_fitness.dtype)
        z = jnp.clip(normalize(population, state.lower, state.upper), 0.0, 1.0)
        # The key is unused by evosax's CMA-ES update; a fixed one keeps ``tell`` key-free.
        new_es, _ = es.tell(jax.random.key(0), z, f, state.es, params)
        all_failed = jnp.all(jnp.isposinf(f))
        new_es = _strong(new_es)
        es_state = jax.tree.map(lambda old, new: jnp.where(all_failed, old, new), state.es, new_es)
        i = jnp.argmin(f)
        improved = f[i] < state.best_fitness
        return state.replace(
            es=es_state,
            best_params=jnp.where(improved, population[i], state.best_params),
            best_fitness=jnp.where(improved, f[i], state.best_fitness),
            generation=state.generation + 1,
        )

    def best(self, state: CMAESState) -> tuple[Array, Array]:
        """``(best evaluated parameters (D,), their fitness ())``."""
        return state.best_params, state.best_fitness

    def mean(self, state: CMAESState) -> Array:
        """(D,) current distribution mean in real coordinates."""
        return denormalize(state.es.mean, state.lower, state.upper)
