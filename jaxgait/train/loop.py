"""Run an optimisation experiment: population rollouts, fitness, optimiser, checkpoints, results.

Python API (notebooks)::

    from jaxgait.train import train
    result = train("quickstart", out_dir="runs/quickstart")      # or an Experiment / config.json
    result.best_params, result.best_score, result.measures

Command line (a thin layer over :func:`train`)::

    python -m jaxgait.train                      # list the experiments
    python -m jaxgait.train exp7a [--particles N] [--iterations N] [--seed S] [--out DIR]
        [--resume] [--duration S] [--d-lim M] [--worst-of K] [--set key=value ...] [--no-plots]

Only flags actually given override the experiment (:mod:`jaxgait.train.experiments`). ``--set``
takes any experiment field, values as JSON (``--set init=null``, ``--set targets.v_desired=1.5``,
``--set optimiser_options.sigma_init=0.05``; dotted keys merge into mapping fields).

One iteration (thesis 2.2.1, 3.2): ask the optimiser for P parameter sets; draw P x k fresh
environments (keys from the seed and the iteration); roll all P x k out as one population,
sharded over the local devices (:func:`population_mesh`); measure each rollout
(:func:`jaxgait.analysis.measures.compute_measures`), score it (:mod:`jaxgait.train.objective`), keep the worst
of the k scores per parameter set and tell the optimiser. Every random key is
``fold_in(PRNGKey(seed), iteration)``, so a run killed at any moment and resumed from its last
checkpoint ends exactly as an uninterrupted run.

Results folder (``out_dir``, default ``runs/<experiment>``):

* ``config.json``: the experiment and the jaxgait version;
* ``checkpoints/``: orbax checkpoints of the train state, every iteration, last 3 kept;
* ``history.csv``: one row per iteration (best so far, best of the iteration, particles per
  stage, rollouts/s), rewritten after every iteration;
* ``best.json`` (a preset: ``python -m jaxgait.evaluate runs/exp3``) and ``best_params.txt``
  (readable table), rewritten whenever the best improves;
* at the end: ``measures.json`` (the best re-evaluated on the experiment environment) and
  ``plots/`` (joint angles vs Winter, GRF, activations vs EMG, stick figure and, for stage
  objectives, ``stage_progress.png``).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import functools
import io
import json
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from jaxgait.optim import INVALID_STAGE, stage_argbest, stage_better
from jaxgait.presets import PresetError, load_preset
from jaxgait.train import objective as objective_mod
from jaxgait.train.checkpoint import CheckpointError, RunCheckpoints
from jaxgait.train.experiments import (
    CONFIG_FORMAT,
    EXPERIMENTS,
    Experiment,
    ExperimentError,
    describe_experiments,
    load_config,
    resolve_experiment,
)

#: Default parent of results folders.
DEFAULT_RUNS = Path("runs")
#: Name of the mesh axis the population is sharded over.
POP_AXIS = "pop"
#: fold_in tags of the keys that are not per-iteration.
_INIT_TAG, _EVAL_TAG = 0x1D17, 0xE7A1
#: Fallback location (source checkout) of the walking gait used before ``fbl_walk`` ships.
_FBL_WALK_RUN = Path(__file__).resolve().parents[2] / "experiments/fbl_walk/run1/best.json"


class TrainError(ValueError):
    """Bad input to :func:`train` (model not available, results folder in use, bad start)."""


def jaxgait_version() -> str:
    """Installed jaxgait version (``"unknown"`` outside an installed package)."""
    try:
        from importlib.metadata import version

        return version("jaxgait")
    except Exception:  # noqa: BLE001 - metadata missing in odd setups
        return "unknown"


def config_document(exp: Experiment) -> dict:
    """The config JSON of a run: experiment fields, jaxgait version and format number."""
    return {
        "format": CONFIG_FORMAT,
        "jaxgait_version": jaxgait_version(),
        "experiment": exp.to_dict(),
    }


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


# ------------------------------------------------------------------------------- model / init


@functools.lru_cache(maxsize=4)
def get_model(name: str):
    """The simulation model ``name`` (cached, so compiled rollouts are shared)."""
    from jaxgait import sim

    try:
        return sim.make_model(name)
    except KeyError:
        raise TrainError(
            f"model {name} not available yet: this version of jaxgait simulates 'fbl' only "
            f"(experiments on {name!r} are registered for when it lands)"
        ) from None


def resolve_init(init: str | None, table) -> np.ndarray | None:
    """Starting point (D,) of the search: a preset, the table's init (``"table"``) or None.

    A preset is matched to ``table`` by parameter name: names the table lacks are an error,
    names the preset lacks take the table's initial values (so an FBL preset can start a model
    whose table extends FBL's). ``"fbl_walk"`` falls back to
    ``experiments/fbl_walk/run1/best.json`` of a source checkout while the shipped preset is
    missing.
    """
    if init is None:
        return None
    if init == "table":
        return np.asarray(table.init, float)
    try:
        _, _, doc = load_preset(init)
    except PresetError:
        if init != "fbl_walk" or not _FBL_WALK_RUN.is_file():
            raise
        _, _, doc = load_preset(_FBL_WALK_RUN)
    values = {str(k): float(v) for k, v in doc.get("params", {}).items()}
    unknown = sorted(set(values) - set(table.names))
    if unknown:
        raise TrainError(
            f"init preset {init!r} has parameters the model's table {table.name!r} lacks: "
            + ", ".join(unknown)
        )
    vec = table.pack(values)
    try:
        table.check(vec, where=f"init preset {init!r}")
    except ValueError as e:
        raise TrainError(str(e)) from None
    return vec


# ------------------------------------------------------------------------------- devices


def population_mesh(devices: Sequence | None = None) -> Mesh:
    """1-D mesh ``("pop",)`` over ``devices`` (default: all local devices)."""
    devs = list(jax.local_devices() if devices is None else devices)
    if not devs:
        raise TrainError("no devices to run on")
    return Mesh(np.array(devs), (POP_AXIS,))


def shard_population(tree: Any, mesh: Mesh) -> Any:
    """Put every leaf's leading (population) axis across the mesh (size a multiple of it)."""
    sharding = NamedSharding(mesh, PartitionSpec(POP_AXIS))
    return jax.device_put(tree, sharding)


def padded_size(n: int, n_devices: int, batch_size: int | None) -> tuple[int, int]:
    """(rows per device call, number of calls) for n rollouts on n_devices.

    A call holds ``batch_size`` rollouts (default all n), rounded up to a multiple of the device
    count; the population is padded with copies of row 0 to ``calls x rows``.
    """
    rows = n if batch_size is None else min(batch_size, n)
    rows = -(-rows // n_devices) * n_devices
    return rows, -(-n // rows)


@functools.lru_cache(maxsize=16)
def _batched_rollout(model_name: str, cfg):
    """jit(vmap(rollout)) with the distance limit and the initial speed as traced arguments.

    ``cfg.d_lim`` is only compared with the distance in :func:`jaxgait.sim.step` and ``cfg.v0``
    only sets the initial velocity in :func:`jaxgait.sim.initial_state`, so both are passed as
    arrays: experiments that differ only in them share one compiled rollout. ``run(params,
    env, d_lim, v0)``.
    """
    from jaxgait import sim

    model = get_model(model_name)

    def run(params, env, d_lim, v0):
        c = dataclasses.replace(cfg, d_lim=d_lim, v0=v0)
        trace, events, summary, _ = jax.vmap(lambda p, e: sim.rollout(model, c, p, e))(params, env)
        return trace, events, summary

    return jax.jit(run)


@functools.lru_cache(maxsize=32)
def _scorer(objective):
    """jit: rollouts -> (stage (B,), value (B,), valid (B,)) for ``objective`` (hashable)."""
    from jaxgait.analysis.measures import compute_measures

    measure = jax.vmap(functools.partial(compute_measures, skip=2))

    def score(trace, events, summary, max_stage):
        m = measure(trace, events, summary)
        valid = objective_mod.rollout_valid(trace, summary)
        stage, value = objective.fitness(m, valid, max_stage)
        return stage, value, valid

    return jax.jit(score)


@functools.lru_cache(maxsize=16)
def _ask_tell(strategy):
    return jax.jit(strategy.ask), jax.jit(strategy.tell)


class PopulationEvaluator:
    """Rolls a population out (sharded over devices) and scores it with worst-of-k.

    Args:
      exp: the experiment (model, environment, duration, d_lim, k, batch size, objective).
      devices: devices of the population mesh (default all local devices).
    """

    def __init__(self, exp: Experiment, devices: Sequence | None = None):
        from jaxgait import sim

        self.exp = exp
        self.model = get_model(exp.model)
        self.mesh = population_mesh(devices)
        self.n_devices = self.mesh.devices.size
        self.sim_cfg = sim.SimConfig(duration=exp.duration)
        self.env_cfg = exp.env_config()
        self.objective = exp.objective()
        self.rollout = _batched_rollout(exp.model, self.sim_cfg)
        self.score = _scorer(self.objective)
        #: rollouts per device call: every call has this shape, so one compilation serves
        #: the iterations and the final evaluation.
        self.rows = padded_size(exp.particles * exp.worst_of_k, self.n_devices, exp.batch_size)[0]
        self.d_lim = jnp.asarray(exp.d_lim if math.isfinite(exp.d_lim) else jnp.inf, jnp.float32)
        self.v0 = jnp.asarray(exp.v0, jnp.float32)

    def run(self, params: jax.Array, env_keys: jax.Array):
        """Raw rollouts of (B, D) params on the environments of (B,) keys, chunked and padded.

        Every call holds :attr:`rows` rollouts (padded with copies of row 0). Yields
        ``(real, trace, events, summary)`` per call; ``real`` are the indices (into ``params``)
        of the unpadded rows, which come first in the call.
        """
        from jaxgait.world import envs

        n = params.shape[0]
        rows = self.rows
        calls = -(-n // rows)
        env_all = envs.make_env_batch(self.env_cfg, env_keys)
        for c in range(calls):
            idx = np.arange(c * rows, (c + 1) * rows)
            real = idx[idx < n]
            idx = np.where(idx < n, idx, 0)
            p = shard_population(jnp.asarray(params)[idx], self.mesh)
            e = shard_population(jax.tree.map(lambda x, i=idx: x[i], env_all), self.mesh)
            yield real, *self.rollout(p, e, self.d_lim, self.v0)

    def scores(self, params: jax.Array, env_keys: jax.Array, max_stage=None, keep_first=False):
        """Per-rollout ``(stage (B,), value (B,), valid (B,))`` (NumPy) of (B, D) params.

        ``max_stage``: optional (B,) cap of the stage (thesis 2.2.1.2); none by default.
        ``keep_first``: also return the (trace, events, summary) of row 0 (NumPy).
        """
        first = None
        n = params.shape[0]
        cap = np.full(n, self.objective.n_stages, np.int32) if max_stage is None else max_stage
        stage = np.zeros(n, np.int32)
        value = np.zeros(n, np.float64)
        valid = np.zeros(n, bool)
        for real, trace, events, summary in self.run(params, env_keys):
            m = real.size
            rows = trace.t.shape[0]
            ms = np.concatenate([np.asarray(cap)[real], np.zeros(rows - m, np.int32)])
            s, v, ok = self.score(trace, events, summary, jnp.asarray(ms))
            stage[real], value[real], valid[real] = (np.asarray(a)[:m] for a in (s, v, ok))
            if keep_first and first is None:
                first = jax.tree.map(lambda x: np.asarray(x[0]), (trace, events, summary))
        if keep_first:
            return stage, value, valid, first
        return stage, value, valid

    def evaluate(self, population: jax.Array, key: jax.Array, max_stage=None):
        """Worst-of-k ``(stage (P,), value (P,), n_failed_rollouts)`` of a (P, D) population.

        Each parameter set is rolled out on k fresh environments drawn from ``key``.
        """
        P, k = population.shape[0], self.exp.worst_of_k
        stage, value, valid = self.scores(
            jnp.repeat(population, k, axis=0),
            jax.random.split(key, P * k),
            None if max_stage is None else np.repeat(np.asarray(max_stage, np.int32), k),
        )
        ws, wv = objective_mod.worst_of_k(
            jnp.asarray(stage.reshape(P, k)), jnp.asarray(value.reshape(P, k))
        )
        return ws, wv.astype(jnp.float32), int((~valid).sum())


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
    )


def iteration_keys(base: jax.Array, iteration: int) -> tuple[jax.Array, jax.Array]:
    """(ask key, environment key) of an iteration: split(fold_in(base, iteration))."""
    k = jax.random.split(jax.random.fold_in(base, iteration))
    return k[0], k[1]


def run_iteration(exp: Experiment, strategy, evaluator: PopulationEvaluator, state: TrainState):
    """One iteration: ask, roll out P x k, worst of k, tell, update the best and history."""
    t0 = time.perf_counter()
    ask, tell = _ask_tell(strategy)
    it = int(state.iteration)
    k_ask, k_env = iteration_keys(state.key, it)
    population, opt_state = ask(k_ask, state.opt_state)
    objective = evaluator.objective
    max_stage = None
    if exp.optimiser == "stage_pso" and exp.stage_cap and objective.kind == "stage":
        max_stage = opt_state.stage + 1
    stage, value, _ = evaluator.evaluate(population, k_env, max_stage)
    opt_state = tell(
        opt_state, population, objective_mod.to_tell(exp.optimiser, objective, stage, value)
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
    secs = time.perf_counter() - t0
    n_roll = population.shape[0] * exp.worst_of_k
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
        hist_seconds=state.hist_seconds.at[it].set(secs),
        hist_rollouts=state.hist_rollouts.at[it].set(n_roll),
    )
    return new, better


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
        rows.append(row)
    return rows


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)


def write_history(path: Path, rows: list[dict]) -> None:
    """Write ``history.csv`` (atomically)."""
    if not rows:
        return
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    _atomic_write(path, buf.getvalue())


def _fmt_time(s: float) -> str:
    if not math.isfinite(s):
        return "?"
    s = int(round(s))
    h, r = divmod(s, 3600)
    m, sec = divmod(r, 60)
    return f"{h}h{m:02d}m" if h else (f"{m}m{sec:02d}s" if m else f"{sec}s")


def progress_line(exp: Experiment, objective, state: TrainState, eta_s: float, first: bool) -> str:
    """``exp3 it 12/150 | stages 0:10 1:30 2:20 | best stage 2 (...) | 95 rollouts/s | ETA``."""
    it = int(state.iteration) - 1
    counts = np.asarray(state.hist_stage_counts[it])
    if objective.kind == "stage":
        parts = [f"{s}:{int(counts[s + 1])}" for s in range(objective.n_stages) if counts[s + 1]]
        if counts[0]:
            parts.append(f"failed:{int(counts[0])}")
        pop = "stages " + " ".join(parts)
    else:
        pop = f"valid {int(exp.particles - counts[0])}/{exp.particles}"
    secs = float(state.hist_seconds[it])
    rate = int(state.hist_rollouts[it]) / max(secs, 1e-9)
    best = objective_mod.score_text(objective, state.best_stage, state.best_value)
    note = " (incl. compile)" if first else ""
    return (
        f"{exp.name} it {it + 1}/{exp.iterations} | {pop} | best {best} | "
        f"{rate:.1f} rollouts/s{note} | ETA {_fmt_time(eta_s)}"
    )


def save_best(out: Path, exp: Experiment, table, state: TrainState, objective) -> dict[str, Path]:
    """Write ``best.json`` (preset) and ``best_params.txt``; returns their paths."""
    from jaxgait.core.params import save_preset

    vec = np.clip(np.asarray(state.best_params, np.float64), table.lower, table.upper)
    text = objective_mod.score_text(objective, state.best_stage, state.best_value)
    p_json, p_txt = out / "best.json", out / "best_params.txt"
    save_preset(
        p_json,
        exp.model,
        table,
        vec,
        description=f"best of experiment {exp.name}: {exp.description}",
        experiment=exp.name,
        seed=exp.seed,
        iteration=int(state.iteration),
        score=text,
        stage=int(state.best_stage),
        value=float(state.best_value),
    )
    _atomic_write(
        p_txt,
        f"# experiment {exp.name}, iteration {int(state.iteration)}: {text}\n"
        + table.to_table(vec),
    )
    return {"best": p_json, "best_params": p_txt}


def plot_stage_progress(path: Path, rows: list[dict], criteria: Sequence[str]) -> Path:
    """Particles per stage (stacked) and the best stage over the iterations (PNG)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    it = np.array([r["iteration"] for r in rows])
    fig = Figure(figsize=(8, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    stacks = [np.array([r["n_failed"] for r in rows])]
    labels = ["failed"]
    for s, c in enumerate(criteria):
        stacks.append(np.array([r[f"stage_{s}"] for r in rows]))
        labels.append(f"stage {s}: {c}")
    ax.stackplot(it, *stacks, labels=labels, alpha=0.8)
    ax.set_xlabel("iteration")
    ax.set_ylabel("parameter sets per stage")
    ax2 = ax.twinx()
    ax2.step(it, [r["best_stage"] for r in rows], "k-", where="post", label="best stage")
    ax2.set_ylabel("best stage")
    ax2.set_ylim(-1.2, len(criteria) - 0.5)
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title("stage PSO progress")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path


def perturbed_copies(best, key, n: int, rel: float):
    """``n`` copies of the parameter vector ``best``, each scaled by (1 + rel N(0, 1))."""
    noise = jax.random.normal(key, (n, best.shape[0]))
    return best[None] * (1.0 + rel * noise.astype(best.dtype))


def perturbation_check(
    evaluator: PopulationEvaluator, best, env_key, key, n: int = 8, rel: float = 1e-6
) -> dict:
    """How many of ``n`` copies of ``best``, each scaled by (1 + rel N(0, 1)), do not fall.

    Run on the first evaluation environment.  A gait found by optimising one deterministic
    rollout can owe its success to rounding: when the best itself stays up there
    (``perturbed_reference_fell`` false), a fraction below 1 says it falls under changes as
    small as float32 rounding (use worst-of-k or a perturbed environment to train).
    """
    params = perturbed_copies(best, jax.random.fold_in(key, _EVAL_TAG + 1), n, rel)
    keys = jnp.repeat(env_key[None], n, axis=0)
    fell, dist = np.zeros(n, bool), np.zeros(n)
    for real, _, _, summary in evaluator.run(params, keys):
        fell[real] = np.asarray(summary.fell)[: real.size]
        dist[real] = np.asarray(summary.distance)[: real.size]
    return {
        "perturbed_relative": rel,
        "perturbed_copies": n,
        "perturbed_survival": float(1.0 - fell.mean()),
        "perturbed_distance_min_m": float(dist.min()),
    }


def final_evaluation(
    exp: Experiment, evaluator: PopulationEvaluator, state: TrainState, out: Path, plots: bool
) -> tuple[dict, dict[str, Path]]:
    """Re-evaluate the best on the experiment environment; write measures.json and plots.

    The best is rolled out on ``worst_of_k`` environments drawn from ``fold_in(seed key,
    EVAL)``; the measures are those of the first draw, the score is the worst of all draws
    (without the stage cap of the stage PSO).
    """
    from jaxgait.analysis.measures import MEASURE_UNITS, compute_measures
    from jaxgait.evaluate import json_safe

    k = exp.worst_of_k
    base = state.key
    keys = jax.random.split(jax.random.fold_in(base, _EVAL_TAG), k)
    params = jnp.repeat(state.best_params[None], k, axis=0)
    stages, values, _, first = evaluator.scores(params, keys, keep_first=True)
    ws, wv = objective_mod.worst_of_k(jnp.asarray(stages)[None], jnp.asarray(values)[None])
    trace, events, summary = first
    meas = jax.tree.map(np.asarray, compute_measures(trace, events, summary))
    report = {k_: json_safe(v) for k_, v in meas.items() if np.ndim(v) == 0}
    report["units"] = {k_: MEASURE_UNITS.get(k_, "") for k_ in report}
    report.update(
        experiment=exp.name,
        env=exp.env,
        duration_requested_s=exp.duration,
        d_lim_m=exp.d_lim if math.isfinite(exp.d_lim) else None,
        score=objective_mod.score_text(evaluator.objective, ws[0], wv[0]),
        stage=int(ws[0]),
        value=json_safe(float(wv[0])),
        worst_of=k,
    )
    report.update(perturbation_check(evaluator, state.best_params, keys[0], state.key))
    report["perturbed_reference_fell"] = bool(np.asarray(summary.fell))
    files = {"measures": out / "measures.json"}
    _atomic_write(
        files["measures"], json.dumps(json_safe(report), indent=2, allow_nan=False) + "\n"
    )
    if plots:
        from jaxgait.analysis.plots import plot_all
        from jaxgait.world.envs import make_env

        env = make_env(evaluator.env_cfg, keys[0])
        figs = plot_all(
            out / "plots",
            trace,
            events,
            summary,
            evaluator.model,
            terrain=jax.tree.map(np.asarray, env.terrain),
            measures_dict=meas,
        )
        files.update({f"plot_{n}": p for n, p in figs.items()})
    return report, files


def _prepare_out(out: Path, resume: bool) -> None:
    if out.exists() and not out.is_dir():
        raise TrainError(f"results folder {out} exists and is not a folder")
    ck = out / "checkpoints"
    if not resume and ck.is_dir() and any(p.name.isdigit() for p in ck.iterdir()):
        raise TrainError(
            f"{out} already holds checkpoints of a run; resume it with --resume "
            "(resume=True) or choose another output folder (nothing was overwritten)"
        )
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise TrainError(f"cannot create results folder {out}: {e}") from None


def train(
    config: Experiment | str | Path,
    out_dir: str | Path | None = None,
    resume: bool = False,
    progress: Callable[[str], Any] | None = print,
    max_iterations: int | None = None,
    *,
    devices: Sequence | None = None,
    plots: bool = True,
) -> TrainResult:
    """Run (or resume) an experiment.

    Args:
      config: an :class:`~jaxgait.train.experiments.Experiment`, a registry name or a config JSON.
      out_dir: results folder (default ``runs/<name>``).
      resume: continue from the newest readable checkpoint in ``out_dir/checkpoints`` (its
        config must equal this one); without a checkpoint, start from scratch.
      progress: callable receiving one line per iteration and notices (None: silent).
      max_iterations: stop after this many iterations in this call (the run stays resumable).
      devices: devices the population is sharded over (default all local devices).
      plots: write the figures at the end.

    Returns:
      :class:`TrainResult`.

    Raises:
      ExperimentError, TrainError, PresetError, CheckpointError (all with a message saying what
      and where). Nothing saved before is overwritten by a failed start.
    """
    say = progress or (lambda s: None)
    exp = resolve_experiment(config)
    if max_iterations is not None and (isinstance(max_iterations, bool) or max_iterations < 1):
        raise TrainError(f"max_iterations must be a positive integer, got {max_iterations!r}")
    model = get_model(exp.model)
    table = model.table
    out = Path(out_dir) if out_dir is not None else DEFAULT_RUNS / exp.name
    doc = config_document(exp)
    strategy = exp.strategy()
    evaluator = PopulationEvaluator(exp, devices)
    objective = evaluator.objective
    state = initial_state(exp, strategy, table, objective.n_stages)  # checks the init preset
    _prepare_out(out, resume)

    ckpt = RunCheckpoints(out / "checkpoints", doc, warn=say)
    files: dict[str, Path] = {}
    try:
        if resume:
            from orbax.checkpoint.utils import to_shape_dtype_struct

            restored = ckpt.restore(jax.tree.map(to_shape_dtype_struct, state))
            if restored is None:
                say(f"{exp.name}: no checkpoint in {ckpt.directory}; starting from iteration 0")
            else:
                state = restored[1]
                say(
                    f"{exp.name}: resumed from iteration {int(state.iteration)} in {ckpt.directory}"
                )
        _atomic_write(out / "config.json", json.dumps(doc, indent=2) + "\n")
        files["config"] = out / "config.json"
        start = int(state.iteration)
        stop = (
            exp.iterations
            if max_iterations is None
            else min(exp.iterations, start + max_iterations)
        )
        if start < stop:
            say(
                f"{exp.name}: {exp.particles} x {exp.worst_of_k} rollouts of {exp.duration:g} s "
                f"per iteration on {evaluator.n_devices} device(s); the first iteration compiles"
            )
        for it in range(start, stop):
            state, improved = run_iteration(exp, strategy, evaluator, state)
            ckpt.save(it + 1, state)
            rows = history_rows(state, objective)
            write_history(out / "history.csv", rows)
            if improved or not (out / "best.json").exists():
                files.update(save_best(out, exp, table, state, objective))
            done_secs = [r["seconds"] for r in rows[start:]]
            steady = done_secs[1:] or done_secs
            eta = (exp.iterations - (it + 1)) * float(np.mean(steady))
            say(progress_line(exp, objective, state, eta, first=(it == start)))
    finally:
        ckpt.close()

    rows = history_rows(state, objective)
    files["history"] = out / "history.csv"
    if not (out / "best.json").exists():
        files.update(save_best(out, exp, table, state, objective))
    files.setdefault("best", out / "best.json")
    files.setdefault("best_params", out / "best_params.txt")
    complete = int(state.iteration) >= exp.iterations
    measures = None
    if complete:
        measures, f = final_evaluation(exp, evaluator, state, out, plots)
        files.update(f)
        if plots and objective.kind == "stage" and rows:
            (out / "plots").mkdir(exist_ok=True)
            files["plot_stage_progress"] = plot_stage_progress(
                out / "plots" / "stage_progress.png", rows, objective.criteria
            )
        best = objective_mod.score_text(objective, state.best_stage, state.best_value)
        d, epm = measures.get("distance_m"), measures.get("energy_J_per_m")
        d = f"{d:.2f} m" if d is not None else "n/a"
        epm = f"{epm:.0f} J/m" if epm is not None else "n/a"
        say(
            f"{exp.name}: done; best {best}; re-evaluated (no stage cap): {measures['score']}, "
            f"distance {d}, {epm}; results in {out}"
        )
        surv = measures.get("perturbed_survival")
        if surv is not None and surv < 1.0 and not measures.get("perturbed_reference_fell"):
            say(
                f"warning: only {surv:.0%} of {measures['perturbed_copies']} copies of the best "
                f"perturbed by {measures['perturbed_relative']:g} (relative) stay up; this gait "
                "depends on rounding (train with --worst-of or a perturbed environment)"
            )
    return TrainResult(
        config=exp,
        out_dir=out,
        best_params=np.clip(np.asarray(state.best_params, np.float64), table.lower, table.upper),
        best_stage=int(state.best_stage),
        best_value=float(state.best_value),
        best_score=objective_mod.score_text(objective, state.best_stage, state.best_value),
        iterations_done=int(state.iteration),
        complete=complete,
        history=rows,
        measures=measures,
        files=files,
        state=state,
    )


# ------------------------------------------------------------------------------- CLI


def parse_set(items: Sequence[str]) -> dict:
    """``["a=1", "targets.v_desired=1.5"]`` -> ``{"a": 1, "targets": {"v_desired": 1.5}}``.

    Values are JSON (``null``, ``true``, numbers, lists, strings in quotes); anything that is not
    JSON is taken as a string; ``inf`` is infinity.
    """
    out: dict = {}
    for item in items:
        if "=" not in item:
            raise ExperimentError(f"--set {item!r}: expected key=value")
        key, raw = item.split("=", 1)
        key = key.strip()
        if not key:
            raise ExperimentError(f"--set {item!r}: empty key")
        if raw.strip() in ("inf", "+inf", "Infinity"):
            value: Any = math.inf
        else:
            try:
                value = json.loads(raw)
            except json.JSONDecodeError:
                value = raw
        if "." in key:
            head, sub = key.split(".", 1)
            out.setdefault(head, {})
            if not isinstance(out[head], dict):
                raise ExperimentError(f"--set {item!r}: {head} was also set as a whole")
            out[head][sub] = value
        else:
            out[key] = value
    return out


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m jaxgait.train",
        description="Optimise a gait controller: run (or resume) a registered experiment.",
        epilog="experiments:\n" + describe_experiments(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    S = argparse.SUPPRESS
    p.add_argument("experiment", nargs="?", help="experiment name or config JSON file")
    p.add_argument("--list", action="store_true", help="list the experiments and exit")
    p.add_argument("--particles", type=int, default=S, help="population size")
    p.add_argument("--iterations", type=int, default=S, help="number of iterations")
    p.add_argument("--seed", type=int, default=S, help="seed of every random draw")
    p.add_argument("--duration", type=float, default=S, help="time limit of a rollout [s]")
    p.add_argument("--d-lim", dest="d_lim", type=float, default=S, help="distance limit [m]")
    p.add_argument(
        "--worst-of",
        dest="worst_of_k",
        type=int,
        default=S,
        help="environments per parameter set (worst kept)",
    )
    p.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override any experiment field (repeatable; JSON values)",
    )
    p.add_argument("--out", type=Path, default=None, help="results folder (default runs/NAME)")
    p.add_argument("--resume", action="store_true", help="continue from the last checkpoint")
    p.add_argument("--no-plots", action="store_true", help="do not write figures")
    return p


def _cli_experiment(a: argparse.Namespace) -> tuple[Experiment, Path]:
    overrides = parse_set(a.sets)
    for k in ("particles", "iterations", "seed", "duration", "d_lim", "worst_of_k"):
        if k in vars(a):
            overrides[k] = getattr(a, k)
    base = resolve_experiment(a.experiment)
    out = a.out if a.out is not None else DEFAULT_RUNS / base.name
    saved_path = out / "config.json"
    if a.resume and saved_path.is_file():
        saved = load_config(saved_path)
        if saved.name != base.name:
            raise TrainError(
                f"{out} holds a run of experiment {saved.name!r}, not {base.name!r}; "
                "choose another --out or resume that experiment"
            )
        base = saved
    return base.replace(**overrides) if overrides else base, out


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit code (0 ok, 2 bad input, 130 interrupted)."""
    try:
        a = _parser().parse_args(argv)
    except SystemExit as e:
        return int(e.code) if isinstance(e.code, int) else 2
    if a.list or a.experiment is None:
        print("experiments (python -m jaxgait.train NAME):\n" + describe_experiments())
        return 0
    try:
        from jaxgait.core import compile_cache

        compile_cache.enable()  # later runs with the same shapes skip the compilation
    except ImportError:
        pass
    try:
        exp, out = _cli_experiment(a)
        result = train(
            exp, out, resume=a.resume, progress=lambda s: print(s, flush=True), plots=not a.no_plots
        )
    except KeyboardInterrupt:
        print("interrupted; continue with --resume (the last checkpoint is kept)", file=sys.stderr)
        return 130
    except (ExperimentError, TrainError, PresetError, CheckpointError) as e:
        print(f"jaxgait.train: error: {e}", file=sys.stderr)
        return 2
    print(f"best: {result.best_score}; results in {result.out_dir}")
    return 0


__all__ = [
    "EXPERIMENTS",
    "PopulationEvaluator",
    "TrainError",
    "TrainResult",
    "TrainState",
    "main",
    "population_mesh",
    "train",
]


if __name__ == "__main__":
    sys.exit(main())
