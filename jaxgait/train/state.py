"""The iteration state (a pytree checkpointed every iteration) and one iteration."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxgait.optim import INVALID_STAGE, stage_argbest, stage_better
from jaxgait.train import objective as objective_mod
from jaxgait.train.evaluator import PopulationEvaluator, _ask_tell
from jaxgait.train.experiments import (
    Experiment,
)
from jaxgait.train.setup import _INIT_TAG, resolve_init

# ------------------------------------------------------------------------------- state


@struct.dataclass
class TrainState:
    """Everything a run carries from one iteration to the next (saved every iteration).

    Attributes:
      opt_state: the optimiser state (array-only pytree).
      key: (2,) uint32 base PRNG key ``PRNGKey(seed)``; iteration keys are folded from it.
      iteration: () int32 number of completed iterations.
      best_params: (D,) best parameters seen (by the stage order; stage 0 for scalar objectives).
      best_stage: () int32 their stage (-1 before any valid evaluation).
      best_value: () their value (maximised; -inf before).
      hist_best_stage, hist_best_value: (N,) best so far after each iteration.
      hist_iter_stage, hist_iter_value: (N,) best of each iteration.
      hist_n_valid: (N,) int32 parameter sets with a valid (finite) worst-of-k score.
      hist_stage_counts: (N, S + 1) int32 parameter sets per stage; column 0 counts failed
        rollouts (stage -1), column s + 1 stage s.
      hist_seconds: (N,) wall time of each iteration [s].
      hist_rollouts: (N,) int32 rollouts simulated per iteration (P k).
      hist_utilisation: (N,) lane utilisation of each iteration's scheduled evaluation
        (busy lane-steps / all lane-steps, :mod:`jaxgait.sim.lanes`).
      hist_busy_steps: (N,) its busy lane-steps (physics steps simulated for rollouts).
    """

    opt_state: Any
    key: jax.Array
    iteration: jax.Array
    best_params: jax.Array
    best_stage: jax.Array
    best_value: jax.Array
    hist_best_stage: jax.Array
    hist_best_value: jax.Array
    hist_iter_stage: jax.Array
    hist_iter_value: jax.Array
    hist_n_valid: jax.Array
    hist_stage_counts: jax.Array
    hist_seconds: jax.Array
    hist_rollouts: jax.Array
    hist_utilisation: jax.Array
    hist_busy_steps: jax.Array


@dataclass
class TrainResult:
    """What :func:`train` returns.

    Attributes:
      config: the experiment run.
      out_dir: results folder.
      best_params: (D,) best parameters (float64, inside the table ranges).
      best_stage, best_value: their fitness (stage 0 for scalar objectives; value maximised).
      best_score: readable fitness.
      iterations_done: completed iterations.
      complete: all ``config.iterations`` are done (measures and plots written).
      history: one dict per iteration (the rows of ``history.csv``).
      measures: scalar measures of the best on the experiment environment (when complete).
      files: name -> path of the files written.
      state: the final :class:`TrainState`.
      best_walk: (distance [m], time [s]) the best's rollout walked in the iteration that
        found it (None if unknown, e.g. a run resumed from an older results folder).
    """

    config: Experiment
    out_dir: Path
    best_params: np.ndarray
    best_stage: int
    best_value: float
    best_score: str
    iterations_done: int
    complete: bool
    history: list[dict]
    measures: dict | None = None
    files: dict[str, Path] = field(default_factory=dict)
    state: Any = None
    best_walk: tuple[float, float] | None = None


# ------------------------------------------------------------------------------- training


def initial_state(exp: Experiment, strategy, table, n_stages: int) -> TrainState:
    """Train state before the first iteration (deterministic in ``exp.seed``)."""
    base = jax.random.PRNGKey(exp.seed)
    lower = jnp.asarray(table.lower, jnp.float32)
    upper = jnp.asarray(table.upper, jnp.float32)
    init = resolve_init(exp.init, table)
    mean = None if init is None else jnp.asarray(init, jnp.float32)
    opt_state = strategy.init(jax.random.fold_in(base, _INIT_TAG), (lower, upper), mean)
    start = mean if mean is not None else 0.5 * (lower + upper)
    n = exp.iterations
    return TrainState(
        opt_state=opt_state,
        key=base,
        iteration=jnp.zeros((), jnp.int32),
        best_params=start,
        best_stage=jnp.asarray(INVALID_STAGE, jnp.int32),
        best_value=jnp.asarray(-jnp.inf, jnp.float32),
        hist_best_stage=jnp.full((n,), INVALID_STAGE, jnp.int32),
        hist_best_value=jnp.full((n,), jnp.nan, jnp.float32),
        hist_iter_stage=jnp.full((n,), INVALID_STAGE, jnp.int32),
        hist_iter_value=jnp.full((n,), jnp.nan, jnp.float32),
        hist_n_valid=jnp.zeros((n,), jnp.int32),
        hist_stage_counts=jnp.zeros((n, n_stages + 1), jnp.int32),
        hist_seconds=jnp.zeros((n,), jnp.float32),
        hist_rollouts=jnp.zeros((n,), jnp.int32),
        hist_utilisation=jnp.zeros((n,), jnp.float32),
        hist_busy_steps=jnp.zeros((n,), jnp.float32),
    )


#: History fields of :class:`TrainState` (leading axis: iterations) and their fill values
#: before an iteration ran.
HISTORY_FILL = {
    "hist_best_stage": INVALID_STAGE,
    "hist_best_value": np.nan,
    "hist_iter_stage": INVALID_STAGE,
    "hist_iter_value": np.nan,
    "hist_n_valid": 0,
    "hist_stage_counts": 0,
    "hist_seconds": 0.0,
    "hist_rollouts": 0,
    "hist_utilisation": 0.0,
    "hist_busy_steps": 0.0,
}


def history_length(state: TrainState) -> int:
    """Number of iterations the history arrays of ``state`` hold (the run's ``iterations``)."""
    return int(state.hist_best_stage.shape[0])


def keep_best(new: TrainState, old: TrainState) -> TrainState:
    """``new`` (the state after an iteration of ``old``) with ``old``'s best kept: the best
    parameters, stage and value, and the best-so-far entries of that iteration."""
    it = int(old.iteration)
    return new.replace(
        best_params=old.best_params,
        best_stage=old.best_stage,
        best_value=old.best_value,
        hist_best_stage=new.hist_best_stage.at[it].set(old.best_stage),
        hist_best_value=new.hist_best_value.at[it].set(old.best_value),
    )


def resize_history(state: TrainState, n: int) -> TrainState:
    """``state`` with history arrays for ``n`` iterations: the recorded iterations kept, new
    rows filled as :func:`initial_state` fills them (so a run extended from N to M
    iterations holds what a run of M iterations holds after N).

    Raises ValueError if ``n`` is below the number of completed iterations.
    """
    done = int(state.iteration)
    if n < done:
        raise ValueError(f"cannot shorten a run that has done {done} iterations to {n}")
    out = {}
    for name, fill in HISTORY_FILL.items():
        x = getattr(state, name)
        have = x.shape[0]
        if n <= have:
            out[name] = x[:n]
        else:
            pad = jnp.full((n - have,) + x.shape[1:], fill, x.dtype)
            out[name] = jnp.concatenate([jnp.asarray(x), pad])
    return state.replace(**out)


def iteration_keys(base: jax.Array, iteration: int) -> tuple[jax.Array, jax.Array]:
    """(ask key, environment key) of an iteration: split(fold_in(base, iteration))."""
    k = jax.random.split(jax.random.fold_in(base, iteration))
    return k[0], k[1]


@struct.dataclass
class Asked:
    """One run's half of an iteration before its rollouts: the population and its keys."""

    population: jax.Array
    opt_state: Any
    env_key: jax.Array
    max_stage: Any = None


def ask_population(exp: Experiment, strategy, objective, state: TrainState) -> Asked:
    """Ask the optimiser for the iteration's P parameter sets (and the stage cap)."""
    ask, _ = _ask_tell(strategy)
    k_ask, k_env = iteration_keys(state.key, int(state.iteration))
    population, opt_state = ask(k_ask, state.opt_state)
    max_stage = None
    if exp.optimiser == "stage_pso" and exp.stage_cap and objective.kind == "stage":
        max_stage = opt_state.stage + 1
    return Asked(population=population, opt_state=opt_state, env_key=k_env, max_stage=max_stage)


def tell_population(
    exp: Experiment,
    strategy,
    objective,
    state: TrainState,
    asked: Asked,
    stage,
    value,
    seconds: float,
    stats,
):
    """Tell the optimiser the worst-of-k ``stage, value`` (P,) of ``asked`` and record the
    iteration (``seconds`` of wall time, lane counts ``stats``): ``(new state, improved)``."""
    _, tell = _ask_tell(strategy)
    it = int(state.iteration)
    population = asked.population
    opt_state = tell(
        asked.opt_state, population, objective_mod.to_tell(exp.optimiser, objective, stage, value)
    )
    i = stage_argbest(stage, value)
    better = bool(stage_better((stage[i], value[i]), (state.best_stage, state.best_value)))
    best_params = jnp.where(better, population[i], state.best_params)
    best_stage = jnp.where(better, stage[i], state.best_stage)
    best_value = jnp.where(better, value[i], state.best_value)
    counts = jnp.stack(
        [jnp.sum(stage == s) for s in range(INVALID_STAGE, objective.n_stages)]
    ).astype(jnp.int32)
    jax.block_until_ready(opt_state)
    n_roll = population.shape[0] * exp.worst_of_k
    util = float(stats.utilisation) if stats is not None else 0.0
    busy = float(stats.busy) if stats is not None else 0.0
    new = state.replace(
        opt_state=opt_state,
        iteration=state.iteration + 1,
        best_params=best_params,
        best_stage=best_stage.astype(jnp.int32),
        best_value=best_value.astype(jnp.float32),
        hist_best_stage=state.hist_best_stage.at[it].set(best_stage),
        hist_best_value=state.hist_best_value.at[it].set(best_value),
        hist_iter_stage=state.hist_iter_stage.at[it].set(stage[i]),
        hist_iter_value=state.hist_iter_value.at[it].set(value[i]),
        hist_n_valid=state.hist_n_valid.at[it].set(jnp.sum(stage != INVALID_STAGE)),
        hist_stage_counts=state.hist_stage_counts.at[it].set(counts),
        hist_seconds=state.hist_seconds.at[it].set(seconds),
        hist_rollouts=state.hist_rollouts.at[it].set(n_roll),
        hist_utilisation=state.hist_utilisation.at[it].set(util),
        hist_busy_steps=state.hist_busy_steps.at[it].set(busy),
    )
    return new, better


def run_iteration(exp: Experiment, strategy, evaluator: PopulationEvaluator, state: TrainState):
    """One iteration: ask, roll out P x k, worst of k, tell, update the best and history."""
    t0 = time.perf_counter()
    objective = evaluator.objective
    asked = ask_population(exp, strategy, objective, state)
    stage, value, _ = evaluator.evaluate(asked.population, asked.env_key, asked.max_stage)
    jax.block_until_ready(stage)
    secs = time.perf_counter() - t0
    return tell_population(
        exp, strategy, objective, state, asked, stage, value, secs, evaluator.last_stats
    )


def history_rows(state: TrainState, objective) -> list[dict]:
    """The completed iterations of ``state`` as dicts (the rows of ``history.csv``)."""
    h = jax.tree.map(np.asarray, state)
    rows = []
    for it in range(int(h.iteration)):
        secs = float(h.hist_seconds[it])
        row = {
            "iteration": it + 1,
            "best_stage": int(h.hist_best_stage[it]),
            "best_value": float(h.hist_best_value[it]),
            "iter_best_stage": int(h.hist_iter_stage[it]),
            "iter_best_value": float(h.hist_iter_value[it]),
            "n_valid": int(h.hist_n_valid[it]),
            "n_failed": int(h.hist_stage_counts[it, 0]),
        }
        for s in range(objective.n_stages):
            row[f"stage_{s}"] = int(h.hist_stage_counts[it, s + 1])
        row["rollouts"] = int(h.hist_rollouts[it])
        row["seconds"] = round(secs, 3)
        row["rollouts_per_s"] = round(int(h.hist_rollouts[it]) / max(secs, 1e-9), 2)
        row["lane_utilisation"] = round(float(h.hist_utilisation[it]), 4)
        row["env_steps_per_s"] = round(float(h.hist_busy_steps[it]) / max(secs, 1e-9), 1)
        rows.append(row)
    return rows
