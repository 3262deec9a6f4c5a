"""Stage PSO, thesis 2.2.1.2 and Table 2.8 (SPEC §4).

The objective is split into stages 0..S-1, each with its own criterion (e.g. Table 2.8: distance
d, C_angles, C_speed, C_steplengths, -E), all MAXIMISED. Every stage s >= 1 has an entrance
condition (e.g. stage 1 is entered when d > 0.99 d_lim); stage 0 has none. A candidate's stage is
the last stage of the leading run of satisfied entrance conditions, i.e. one below the lowest
stage whose entrance condition fails, and its value is that stage's criterion.

Order (SPEC §4): a higher stage is better; within a stage a higher value is better. A NaN value
(a failed rollout) is the worst candidate of all: it is ranked as the sentinel ``(-1, -inf)``,
the value personal and global bests start from, and a best is replaced only by a strictly better
pair, so NaN never enters the state.

The swarm moves exactly as the plain PSO (eq. 2.45-2.46, :mod:`jaxgait.optim.pso`); only the
personal and global bests are chosen by the (stage, value) order.

Fitness convention of :meth:`StagePSO.tell`: a pair ``(stage, value)`` with ``stage`` int32 (P,)
and ``value`` float (P,), value to be maximised (unlike the lower-is-better scalar fitness of the
other strategies). :func:`stage_rank_key` turns a pair into a lower-is-better scalar so a staged
problem can also be given to PSO or CMA-ES.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax.numpy as jnp
from flax import struct

from .base import Array
from .pso import PSO, SwarmState

#: Stage of a candidate whose value is NaN, and of bests before any valid evaluation.
INVALID_STAGE = -1


def canonical_stage(stage: Array, value: Array) -> tuple[Array, Array]:
    """Map NaN values to the worst pair ``(INVALID_STAGE, -inf)``.

    Args:
        stage: (...,) integer stages.
        value: (...,) criterion values (maximised).

    Returns:
        ``(stage int32, value float)`` of the same shape, without NaN.
    """
    value = jnp.asarray(value)
    if not jnp.issubdtype(value.dtype, jnp.floating):
        value = value.astype(jnp.result_type(float))
    bad = jnp.isnan(value)
    stage = jnp.where(bad, INVALID_STAGE, jnp.asarray(stage).astype(jnp.int32))
    return stage, jnp.where(bad, -jnp.inf, value)


def stage_better(a: tuple[Array, Array], b: tuple[Array, Array]) -> Array:
    """Whether ``a = (stage, value)`` is strictly better than ``b`` (elementwise).

    Higher stage wins; at equal stage the higher value wins (thesis 2.2.1.2, Table 2.8: every
    criterion is maximised). NaN values rank below everything, so ``(2, -5)`` beats
    ``(1, 100)``, ``(1, 3)`` beats ``(1, 2)``, anything valid beats ``(s, nan)``, and
    ``(s, nan)`` beats nothing.

    Returns:
        boolean array of the broadcast shape.
    """
    sa, va = canonical_stage(*a)
    sb, vb = canonical_stage(*b)
    return (sa > sb) | ((sa == sb) & (va > vb))


def stage_argbest(stage: Array, value: Array) -> Array:
    """Index of the best pair of a (P,) population by the (stage, value) order (first on ties)."""
    s, v = canonical_stage(stage, value)
    top = jnp.max(s)
    in_top = s == top
    vbest = jnp.max(jnp.where(in_top, v, -jnp.inf))
    return jnp.argmax(in_top & (v == vbest))


def stage_rank_key(stage: Array, value: Array, scale: float = 1.0) -> Array:
    """Lower-is-better scalar key of a (stage, value) pair, for scalar optimisers.

    ``key = -(stage + 1/2 + arctan(value / scale) / pi)``: the squashed value lies in (0, 1), so
    every candidate of a higher stage has a lower key, and within a stage the key decreases with
    the value. NaN maps to ``+inf``. The order is exact between stages; within a stage it is
    monotone but limited by float resolution once ``|value / scale|`` is large (about 1e3 in
    float32): choose ``scale`` near the typical magnitude of the criteria. Use
    :func:`stage_better` for exact comparisons.

    Args:
        stage: (...,) integer stages.
        value: (...,) criterion values (maximised).
        scale: value scale of the squashing.

    Returns:
        (...,) float keys, lower is better.
    """
    s, v = canonical_stage(stage, value)
    squashed = 0.5 + jnp.arctan(v / scale) / jnp.pi
    key = -(s.astype(v.dtype) + squashed)
    return jnp.where(s == INVALID_STAGE, jnp.inf, key)


def evaluate_stages(
    criteria: Array, entrance_ok: Array, max_stage: Array | None = None
) -> tuple[Array, Array]:
    """Stage and value of each candidate (thesis 2.2.1.2).

    Args:
        criteria: (..., S) criterion of every stage for each candidate (maximised).
        entrance_ok: (..., S-1) booleans, column k: the entrance condition of stage k+1 holds
            (stage 0 has no entrance condition). Computed by the caller, e.g. with
            :func:`threshold_entrance`.
        max_stage: optional (...,) cap on the stage. The thesis evaluates a particle at stage N
            only up to stage N+1 in one iteration; pass ``state.stage + 1`` of a
            :class:`StagePSOState` to reproduce that. ``None``: no cap.

    Returns:
        ``(stage int32 (...,), value (...,))``: ``stage`` is the number of leading satisfied
        entrance conditions (the lowest stage whose entrance fails, minus one), ``value`` is
        ``criteria[..., stage]``.

    Raises:
        ValueError: ``entrance_ok`` does not have one column less than ``criteria``.
    """
    criteria = jnp.asarray(criteria)
    ok = jnp.asarray(entrance_ok).astype(bool)
    n_stages = criteria.shape[-1]
    if ok.shape[-1] != n_stages - 1 or ok.shape[:-1] != criteria.shape[:-1]:
        raise ValueError(
            f"entrance_ok must have shape (..., S-1) = {criteria.shape[:-1] + (n_stages - 1,)}"
            f" for criteria of shape {criteria.shape}, got {ok.shape}"
        )
    stage = jnp.sum(jnp.cumprod(ok.astype(jnp.int32), axis=-1), axis=-1).astype(jnp.int32)
    if max_stage is not None:
        stage = jnp.minimum(stage, jnp.maximum(jnp.asarray(max_stage, jnp.int32), 0))
    value = jnp.take_along_axis(criteria, stage[..., None], axis=-1)[..., 0]
    return stage, value


def threshold_entrance(criteria: Array, thresholds: Array) -> Array:
    """Entrance conditions of the form "stage s+1 is entered when criterion s > threshold s".

    This is the shape of Table 2.8: d > 0.99 d_lim enters stage 1, C_angles > 0.8 stage 2, the
    speed condition enters stage 3 (read as |v - v*| < 0.05, i.e. C_speed > -0.05 with
    C_speed = -|v* - v|), C_steplengths > 6 stage 4: thresholds ``[0.99 d_lim, 0.8, -0.05, 6]``.
    A NaN criterion fails its condition.

    Args:
        criteria: (..., S) criterion of every stage (maximised).
        thresholds: (S-1,) threshold on the criterion of stages 0..S-2.

    Returns:
        (..., S-1) booleans for :func:`evaluate_stages`.
    """
    criteria = jnp.asarray(criteria)
    thresholds = jnp.asarray(thresholds, criteria.dtype)
    return criteria[..., :-1] > thresholds


@struct.dataclass
class StagePSOState(SwarmState):
    """State of :class:`StagePSO`: the :class:`SwarmState` fields plus the staged bests.

    Attributes:
        pbest_stage: (P,) int32 stage of each personal best (``-1`` before a valid evaluation).
        pbest_value: (P,) criterion value of each personal best (``-inf`` before).
        gbest_stage: () int32 stage of the global best (``-1`` before).
        gbest_value: () criterion value of the global best (``-inf`` before).
        stage: (P,) int32 stage of each particle at its last evaluation (0 at the start and after
            a failed evaluation), for the ``max_stage`` rule of :func:`evaluate_stages`.
    """

    pbest_stage: Array
    pbest_value: Array
    gbest_stage: Array
    gbest_value: Array
    stage: Array


@dataclasses.dataclass(frozen=True)
class StagePSO(PSO):
    """Stage PSO (thesis 2.2.1.2): PSO moves, bests ranked by (stage, value).

    Same hyper-parameters and ``ask`` as :class:`jaxgait.optim.pso.PSO`. ``tell`` takes
    ``fitness = (stage int32 (P,), value float (P,))`` with value MAXIMISED; ``best`` returns
    ``(params (D,), (stage, value))``.
    """

    def init(self, key: Array, bounds: Any, init_mean: Array | None = None) -> StagePSOState:
        """Initial swarm (as :meth:`PSO.init`); all bests at the sentinel ``(-1, -inf)``."""
        fields = self._init_swarm(key, bounds, init_mean)
        dtype = fields["lower"].dtype
        return StagePSOState(
            **fields,
            pbest_stage=jnp.full((self.popsize,), INVALID_STAGE, jnp.int32),
            pbest_value=jnp.full((self.popsize,), -jnp.inf, dtype),
            gbest_stage=jnp.asarray(INVALID_STAGE, jnp.int32),
            gbest_value=jnp.asarray(-jnp.inf, dtype),
            stage=jnp.zeros((self.popsize,), jnp.int32),
        )

    def tell(
        self, state: StagePSOState, population: Array, fitness: tuple[Array, Array]
    ) -> StagePSOState:
        """Update the bests with ``fitness = (stage (P,), value (P,))``, value maximised.

        A best is replaced only by a strictly better pair (:func:`stage_better`); NaN values are
        the worst pair and never enter the state.
        """
        stage, value = canonical_stage(*fitness)
        value = value.astype(state.pbest_value.dtype)
        better = stage_better((stage, value), (state.pbest_stage, state.pbest_value))
        pbest_position = jnp.where(better[:, None], population, state.pbest_position)
        pbest_stage = jnp.where(better, stage, state.pbest_stage)
        pbest_value = jnp.where(better, value, state.pbest_value)
        i = stage_argbest(pbest_stage, pbest_value)
        improved = stage_better(
            (pbest_stage[i], pbest_value[i]), (state.gbest_stage, state.gbest_value)
        )
        return state.replace(
            pbest_position=pbest_position,
            pbest_stage=pbest_stage,
            pbest_value=pbest_value,
            gbest_position=jnp.where(improved, pbest_position[i], state.gbest_position),
            gbest_stage=jnp.where(improved, pbest_stage[i], state.gbest_stage),
            gbest_value=jnp.where(improved, pbest_value[i], state.gbest_value),
            stage=jnp.maximum(stage, 0),
            generation=state.generation + 1,
        )

    def best(self, state: StagePSOState) -> tuple[Array, tuple[Array, Array]]:
        """``(x_gb (D,), (stage (), value ()))``; ``(-1, -inf)`` if nothing valid was seen."""
        return state.gbest_position, (state.gbest_stage, state.gbest_value)
