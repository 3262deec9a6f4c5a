"""Particle swarm optimisation, thesis 2.2.1 (eq. 2.45-2.46), global-best topology.

Each particle i has a position x_i (a parameter vector in the box) and a velocity v_i. After the
swarm has been evaluated, every particle moves (thesis eq. 2.45-2.46, from its ref. [22])::

    v_i <- omega v_i + c1 r1 * (x_pb,i - x_i) + c2 r2 * (x_gb - x_i)     (2.45)
    x_i <- x_i + v_i                                                      (2.46)

with ``r1, r2 ~ U(0, 1)`` drawn independently per particle and per dimension, ``x_pb,i`` the best
position particle i has visited, ``x_gb`` the best position of the whole swarm, c1 = c2 = 2.05
(cognitive and social factors) and omega = 0.729 (constriction factor). Thesis 2.2.1 limits the
normalised velocity to 0.3: ``|v_d| <= 0.3 (upper_d - lower_d)``, applied after eq. 2.45.

Note on the constants: eq. 2.45 applies omega to the inertia term only, and c1 = c2 = 2.05 are
not multiplied by it. This is therefore not Clerc's constriction form
``v <- chi (v + c1 r1 (...) + c2 r2 (...))`` with chi = 0.7298, whose equivalent is
omega = 0.7298, c1 = c2 = 1.49445. The thesis values give c1 + c2 = 4.1, above the order-2
(variance) stability limit 24 (1 - omega^2) / (7 - 5 omega) = 3.35 of a stagnating swarm: without
the clamp the spread of the particles would grow. The velocity clamp bounds it and convergence is
slower than with Clerc's values. The defaults follow the thesis;
``PSO(P, c1=1.49445, c2=1.49445)`` gives Clerc's swarm.

Bounds (SPEC §4, "parameters kept in their ranges"): after eq. 2.46 the position is clipped to
``[lower, upper]``, and every velocity component whose position was clipped is set to zero, so a
particle sitting on a bound does not keep pushing through it and leaves it only when attracted
back by x_pb or x_gb.

Initialisation: positions uniform in the box; with an ``init_mean``, uniform in the box
``init_mean +- init_spread (upper - lower) / 2`` intersected with the bounds, and (by default)
particle 0 exactly at ``init_mean``. Velocities uniform in ``+- init_velocity * v_max`` with
``v_max = vmax_frac (upper - lower)`` (by default the full clamp ``+- v_max``).

Ask/tell: the first ``ask`` returns the initial positions unchanged; each later ``ask`` applies
eq. 2.45-2.46 with the personal and global bests known from the previous ``tell``. Fitness is
lower-is-better, NaN is treated as +inf and a best is replaced only by a strictly better value,
so a failed rollout never becomes a best.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from .base import Array, as_bounds, sanitize_fitness


@struct.dataclass
class SwarmState:
    """Swarm geometry shared by :class:`PSO` and the stage PSO.

    Attributes:
        lower: (D,) lower bounds.
        upper: (D,) upper bounds.
        position: (P, D) current particle positions x (last population asked).
        velocity: (P, D) current velocities v, ``|v_d| <= vmax_frac (upper_d - lower_d)``.
        pbest_position: (P, D) personal bests x_pb (initial positions until a valid evaluation).
        gbest_position: (D,) global best x_gb (``init_mean`` or the box centre until a valid
            evaluation).
        generation: () int32, number of ``tell`` calls so far.
    """

    lower: Array
    upper: Array
    position: Array
    velocity: Array
    pbest_position: Array
    gbest_position: Array
    generation: Array


@struct.dataclass
class PSOState(SwarmState):
    """State of :class:`PSO` (all fields of :class:`SwarmState` plus the scalar fitness).

    Attributes:
        pbest_fitness: (P,) fitness of each personal best, ``+inf`` before a valid evaluation.
        gbest_fitness: () fitness of the global best, ``+inf`` before a valid evaluation.
    """

    pbest_fitness: Array
    gbest_fitness: Array


def init_swarm(
    key: Array,
    bounds: Any,
    popsize: int,
    init_mean: Array | None,
    init_spread: float,
    init_velocity: float,
    vmax_frac: float,
    include_mean: bool,
) -> dict[str, Array]:
    """Initial positions and velocities of a swarm (fields of :class:`SwarmState`).

    Args:
        key: PRNG key.
        bounds: box, anything :func:`jaxgait.optim.base.as_bounds` accepts.
        popsize: number of particles P.
        init_mean: optional (D,) centre of the initial cloud (clipped into the box).
        init_spread: width of the initial cloud around ``init_mean`` as a fraction of each range.
        init_velocity: initial velocities are uniform in ``+- init_velocity * v_max``.
        vmax_frac: velocity clamp as a fraction of each range (thesis: 0.3).
        include_mean: place particle 0 exactly at ``init_mean``.

    Returns:
        dict with the :class:`SwarmState` fields.
    """
    b = as_bounds(bounds)
    lower, upper = b.lower, b.upper
    dim = lower.shape[0]
    k_pos, k_vel = jax.random.split(key)
    u = jax.random.uniform(k_pos, (popsize, dim), dtype=lower.dtype)
    if init_mean is None:
        centre = 0.5 * (lower + upper)
        lo, hi = lower, upper
    else:
        centre = jnp.clip(jnp.asarray(init_mean, lower.dtype), lower, upper)
        half = 0.5 * init_spread * (upper - lower)
        lo = jnp.maximum(lower, centre - half)
        hi = jnp.minimum(upper, centre + half)
    position = lo + u * (hi - lo)
    if init_mean is not None and include_mean:
        position = position.at[0].set(centre)
    vmax = vmax_frac * (upper - lower)
    velocity = (
        init_velocity
        * vmax
        * jax.random.uniform(k_vel, (popsize, dim), dtype=lower.dtype, minval=-1.0, maxval=1.0)
    )
    return dict(
        lower=lower,
        upper=upper,
        position=position,
        velocity=velocity,
        pbest_position=position,
        gbest_position=centre,
        generation=jnp.zeros((), jnp.int32),
    )


def move_swarm(
    key: Array,
    state: SwarmState,
    omega: float,
    c1: float,
    c2: float,
    vmax_frac: float,
) -> tuple[Array, Array]:
    """One PSO move, thesis eq. 2.45-2.46, with the velocity clamp and the box.

    Args:
        key: PRNG key for r1, r2 ~ U(0, 1), each (P, D).
        state: swarm state (positions, velocities, personal and global bests, bounds).
        omega: constriction (inertia) factor, thesis 0.729.
        c1: cognitive factor, thesis 2.05.
        c2: social factor, thesis 2.05.
        vmax_frac: velocity clamp as a fraction of each range, thesis 0.3.

    Returns:
        ``(position, velocity)``, each (P, D): positions inside the bounds; the velocity component
        of a clipped coordinate is zero.
    """
    x, v = state.position, state.velocity
    k1, k2 = jax.random.split(key)
    r1 = jax.random.uniform(k1, x.shape, dtype=x.dtype)
    r2 = jax.random.uniform(k2, x.shape, dtype=x.dtype)
    v = omega * v + c1 * r1 * (state.pbest_position - x) + c2 * r2 * (state.gbest_position - x)
    vmax = vmax_frac * (state.upper - state.lower)
    v = jnp.clip(v, -vmax, vmax)  # thesis 2.2.1: |v_nd| <= 0.3
    x_new = x + v  # eq. 2.46
    x_box = jnp.clip(x_new, state.lower, state.upper)
    v = jnp.where(x_box != x_new, 0.0, v)  # stop at the bound
    return x_box, v


def swarm_ask(
    key: Array, state: SwarmState, omega: float, c1: float, c2: float, vmax_frac: float
) -> tuple[Array, SwarmState]:
    """Ask step shared by PSO and stage PSO: initial positions at generation 0, else a move."""
    x, v = move_swarm(key, state, omega, c1, c2, vmax_frac)
    first = state.generation == 0
    x = jnp.where(first, state.position, x)
    v = jnp.where(first, state.velocity, v)
    return x, state.replace(position=x, velocity=v)


@dataclasses.dataclass(frozen=True)
class PSO:
    """Particle swarm optimisation (thesis 2.2.1, eq. 2.45-2.46), lower fitness is better.

    Attributes:
        popsize: number of particles P.
        omega: constriction factor omega (thesis 0.729).
        c1: cognitive factor (thesis 2.05).
        c2: social factor (thesis 2.05).
        vmax_frac: velocity clamp, fraction of each parameter range (thesis 0.3).
        init_spread: width of the initial cloud around ``init_mean``, fraction of each range
            (ignored without ``init_mean``: then the whole box).
        init_velocity: initial velocities uniform in ``+- init_velocity * vmax_frac * range``.
        include_mean: with ``init_mean``, particle 0 starts exactly at it.
    """

    popsize: int
    omega: float = 0.729
    c1: float = 2.05
    c2: float = 2.05
    vmax_frac: float = 0.3
    init_spread: float = 0.2
    init_velocity: float = 1.0
    include_mean: bool = True

    def __post_init__(self):
        if int(self.popsize) != self.popsize or self.popsize < 1:
            raise ValueError(f"popsize must be a positive integer, got {self.popsize}")
        if not self.vmax_frac > 0:
            raise ValueError(f"vmax_frac must be > 0, got {self.vmax_frac}")
        if not self.init_spread > 0:
            raise ValueError(f"init_spread must be > 0, got {self.init_spread}")

    def _init_swarm(self, key: Array, bounds: Any, init_mean: Array | None) -> dict[str, Array]:
        return init_swarm(
            key,
            bounds,
            self.popsize,
            init_mean,
            self.init_spread,
            self.init_velocity,
            self.vmax_frac,
            self.include_mean,
        )

    def init(self, key: Array, bounds: Any, init_mean: Array | None = None) -> PSOState:
        """Initial swarm in ``bounds`` (see module docstring); all fitness ``+inf``."""
        fields = self._init_swarm(key, bounds, init_mean)
        dtype = fields["lower"].dtype
        return PSOState(
            **fields,
            pbest_fitness=jnp.full((self.popsize,), jnp.inf, dtype),
            gbest_fitness=jnp.asarray(jnp.inf, dtype),
        )

    def ask(self, key: Array, state: SwarmState) -> tuple[Array, SwarmState]:
        """Population (P, D) to evaluate: the initial positions first, then eq. 2.45-2.46."""
        return swarm_ask(key, state, self.omega, self.c1, self.c2, self.vmax_frac)

    def tell(self, state: PSOState, population: Array, fitness: Array) -> PSOState:
        """Update personal and global bests with the (P,) ``fitness`` of ``population``.

        Lower is better; NaN counts as ``+inf``; a best is replaced only by a strictly better
        fitness, so ``+inf``/NaN never enter the bests.
        """
        f = sanitize_fitness(fitness).astype(state.pbest_fitness.dtype)
        better = f < state.pbest_fitness
        pbest_position = jnp.where(better[:, None], population, state.pbest_position)
        pbest_fitness = jnp.where(better, f, state.pbest_fitness)
        i = jnp.argmin(pbest_fitness)
        improved = pbest_fitness[i] < state.gbest_fitness
        return state.replace(
            pbest_position=pbest_position,
            pbest_fitness=pbest_fitness,
            gbest_position=jnp.where(improved, pbest_position[i], state.gbest_position),
            gbest_fitness=jnp.where(improved, pbest_fitness[i], state.gbest_fitness),
            generation=state.generation + 1,
        )

    def best(self, state: PSOState) -> tuple[Array, Array]:
        """``(x_gb (D,), its fitness ())``; fitness ``+inf`` if nothing valid was seen yet."""
        return state.gbest_position, state.gbest_fitness
