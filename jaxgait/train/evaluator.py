"""The population evaluator: P x k rollouts sharded over the local devices, scored."""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from jaxgait.sim.lanes import LaneStats
from jaxgait.sim.rollout import rollout_steps as sim_rollout_steps
from jaxgait.train import objective as objective_mod
from jaxgait.train.experiments import (
    Experiment,
)
from jaxgait.train.setup import POP_AXIS, TrainError, get_model

# ------------------------------------------------------------------------------- devices


def population_mesh(devices: Sequence | None = None) -> Mesh:
    """1-D mesh ``("pop",)`` over ``devices`` (default: all devices of all processes, i.e.
    the local devices unless ``jax.distributed`` joined several processes)."""
    devs = list(jax.devices() if devices is None else devices)
    if not devs:
        raise TrainError("no devices to run on")
    return Mesh(np.array(devs), (POP_AXIS,))


def shard_population(tree: Any, mesh: Mesh) -> Any:
    """Put every leaf's leading (population) axis across the mesh (size a multiple of it).

    Across processes (``jax.distributed``) every process holds the whole population (the
    optimiser runs replicated) and hands each of its devices that device's rows."""
    sharding = NamedSharding(mesh, PartitionSpec(POP_AXIS))
    if mesh.is_multi_process:

        def put(x):
            x = np.asarray(x)
            return jax.make_array_from_callback(x.shape, sharding, lambda idx: x[idx])

        return jax.tree.map(put, tree)
    return jax.device_put(tree, sharding)


def to_host(tree: Any) -> Any:
    """NumPy copies of every leaf; arrays spread over several processes are gathered first,
    so every process gets the whole result."""

    def get(x):
        if isinstance(x, jax.Array) and not x.is_fully_addressable:
            from jax.experimental import multihost_utils

            return np.asarray(multihost_utils.process_allgather(x, tiled=True))
        return np.asarray(x)

    return jax.tree.map(get, tree)


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


def _score_fn(objective, reference: str = "walking"):
    """``(trace, events, summary, max_stage) -> (stage, value, valid, distance, duration)``
    of a batch of rollouts (leading axis) for ``objective``: their measures (against the
    human gait ``reference``, :func:`jaxgait.analysis.refdata.gait_reference`), validity,
    fitness, and the distance [m] and time [s] walked."""
    from jaxgait.analysis.measures import compute_measures
    from jaxgait.analysis.refdata import gait_reference

    kin, grf = gait_reference(reference)
    measure = jax.vmap(
        functools.partial(compute_measures, reference=kin, grf_reference=grf, skip=2)
    )

    def score(trace, events, summary, max_stage):
        m = measure(trace, events, summary)
        valid = objective_mod.rollout_valid(trace, summary)
        stage, value = objective.fitness(m, valid, max_stage)
        return stage, value, valid, summary.distance, summary.duration

    return score


def worst_rows(stage: np.ndarray, value: np.ndarray) -> np.ndarray:
    """(P,) column of the worst of the k evaluations in each row of (P, k) ``stage, value``
    (the one :func:`~jaxgait.train.objective.worst_of_k` keeps: lowest stage, then lowest
    value; a failed (NaN) evaluation is the worst)."""
    stage = np.where(np.isnan(value), -(2**30), stage)
    value = np.where(np.isnan(value), -np.inf, value)
    return np.array([np.lexsort((v, s))[0] for s, v in zip(stage, value, strict=True)], int)


@functools.lru_cache(maxsize=32)
def _scorer(objective, reference: str = "walking"):
    """jit: rollouts -> (stage (B,), value (B,), valid (B,)) for ``objective`` (hashable)."""
    return jax.jit(_score_fn(objective, reference))


@functools.lru_cache(maxsize=16)
def _lane_scorer(
    model_name: str, cfg, objective, lanes: int, mesh: Mesh, drain=(), reference="walking"
):
    """jit: one queue of rollouts per device -> per rollout (stage, value, valid), lane counts.

    ``run(params (G, Q, D), env (G, Q), max_stage (G, Q), d_lim, v0)``: each of the G groups
    (one per device of ``mesh``) runs its queue of Q rollouts over ``lanes`` lanes
    (:func:`jaxgait.sim.lanes.lane_rollouts`, shrinking to the ``drain`` widths once its
    queue is empty) and scores each rollout when it ends.  The
    groups are split over the devices with ``shard_map``, so each device runs the queue's own
    program: under ``vmap`` over the groups the queue's branches (refill, scoring the ended
    lanes) would become selects computed at every chunk end, about 1.7x slower on exp3.
    """
    from jaxgait.sim.lanes import lane_rollouts

    model = get_model(model_name)
    finish = _score_fn(objective, reference)

    def one_device(params, env, max_stage, d_lim, v0):
        c = dataclasses.replace(cfg, d_lim=d_lim, v0=v0)
        first = lambda t: jax.tree.map(lambda x: x[0], t)
        out, stats = lane_rollouts(
            model, c, params[0], first(env), finish, lanes, aux=max_stage[0], drain=drain
        )
        return jax.tree.map(lambda x: x[None], (out, stats))

    pop, rep = PartitionSpec(POP_AXIS), PartitionSpec()
    run = jax.shard_map(
        one_device,
        mesh=mesh,
        in_specs=(pop, pop, pop, rep, rep),
        out_specs=pop,
        check_vma=False,
    )

    def scored(params, env, max_stage, d_lim, v0):
        out, stats = run(params, env, max_stage, d_lim, v0)
        return (*out, stats)

    return jax.jit(scored)


#: Lanes per CPU device of the automatic queue (``Experiment.lanes`` None).  On 2 cores as
#: 2 host devices (:mod:`jaxgait.core.host_devices`) one exp3 generation (60 rollouts) took
#: 17.3 s over 6 lanes per device, 17-19 s over 8 and 15.7-16.2 s over 12, against 31-35 s
#: as 1 device over 16 lanes and 36 s in one direct call of 60 (benchmarks/README.md,
#: "Training throughput").
CPU_AUTO_LANES = 12

#: A CPU device queues its rollouts (over :data:`CPU_AUTO_LANES` lanes) only when it holds
#: more than this many; up to it, one direct call (e.g. the quickstart's 16 candidates, whose
#: iterations, final evaluation and perturbation check then share one compiled rollout).
CPU_AUTO_QUEUE_ABOVE = 16


#: Simulated time per chunk of the queued evaluation [s]: a lane whose rollout ends (a fall)
#: idles to the end of its chunk before it takes the next one, so shorter chunks waste less;
#: each chunk end costs a little (the refill's branch, the trace's row slices).  The direct
#: calls keep :class:`~jaxgait.sim.model.SimConfig`'s 1 s.  Measured in
#: ``benchmarks/train_throughput.py --compare-queue 12 --chunk-s 1 0.25`` (benchmarks/README.md).
QUEUE_CHUNK_S = 0.25


def drain_widths(lanes: int) -> tuple[int, ...]:
    """The narrower lane counts a queue over ``lanes`` lanes drains to (see
    :func:`jaxgait.sim.lanes.lane_rollouts`): two thirds of them, a third, then one
    (12 lanes: 8, 4, 1).

    With the planar tree's step a chunk's cost is about a quarter fixed (0.0077 + 0.00197 w
    s at w lanes per device), so a narrower program saves most of an idle lane's cost.  The
    earlier ladder, a quarter then one (3, 1), kept an exp3 generation's few walkers on 12
    lanes until at most 3 were left; (8, 4, 1) raised exp3's lane utilisation from 0.83 to
    0.94 on one generation and from 77.8 % to 90.3 % over a full run, at the same wall time
    (benchmarks/README.md, "The drain ladder with the planar step")."""
    ladder = {max(1, 2 * lanes // 3), max(1, lanes // 3), 1}
    return tuple(w for w in sorted(ladder, reverse=True) if w < lanes)


def choose_lanes(exp: Experiment, n_devices: int, n_runs: int = 1) -> int | None:
    """Lanes per device of the queue for ``exp``, or None for direct calls (see
    ``Experiment.lanes``)."""
    if exp.lanes is not None:
        return exp.lanes or None
    per_device = -(-n_runs * exp.particles * exp.worst_of_k // n_devices)
    if exp.batch_size is not None or jax.default_backend() != "cpu":
        return None
    return CPU_AUTO_LANES if per_device > CPU_AUTO_QUEUE_ABOVE else None


@functools.lru_cache(maxsize=16)
def _ask_tell(strategy):
    return jax.jit(strategy.ask), jax.jit(strategy.tell)


class PopulationEvaluator:
    """Rolls a population out (sharded over devices) and scores it with worst-of-k.

    Args:
      exp: the experiment (model, environment, duration, d_lim, k, batch size, objective).
      devices: devices of the population mesh (default all local devices).
      n_runs: independent runs evaluated together (:meth:`evaluate_many`); a direct call
        holds all their rollouts (or ``batch_size``).
    """

    def __init__(self, exp: Experiment, devices: Sequence | None = None, n_runs: int = 1):
        from jaxgait import sim

        self.exp = exp
        self.model = get_model(exp.model, exp.init)
        self.mesh = population_mesh(devices)
        self.n_devices = self.mesh.devices.size
        self.sim_cfg = sim.SimConfig(duration=exp.duration, pose=exp.pose, dynamics=exp.dynamics)
        self.env_cfg = exp.env_config()
        self.objective = exp.objective()
        self.rollout = _batched_rollout(exp.model, self.sim_cfg)
        self.score = _scorer(self.objective, exp.reference)
        #: rollouts per device call: every call has this shape, so one compilation serves
        #: the iterations and the final evaluation.
        n = n_runs * exp.particles * exp.worst_of_k
        self.rows = padded_size(n, self.n_devices, exp.batch_size)[0]
        #: lanes per device of the scheduled evaluation (None: direct calls of :attr:`rows`)
        self.lanes = choose_lanes(exp, self.n_devices, n_runs)
        if self.lanes is not None:
            #: lane counts the queue shrinks to once it is empty (:func:`drain_widths`)
            self.drain = drain_widths(self.lanes)
            #: the queue's settings: :attr:`sim_cfg` in chunks of :data:`QUEUE_CHUNK_S`
            self.lane_cfg = dataclasses.replace(self.sim_cfg, chunk_s=QUEUE_CHUNK_S)
            self.lane_score = _lane_scorer(
                exp.model,
                self.lane_cfg,
                self.objective,
                self.lanes,
                self.mesh,
                self.drain,
                exp.reference,
            )
        #: lane counts (:class:`~jaxgait.sim.lanes.LaneStats`, summed over devices) of the
        #: last evaluation: of the queue, or of the direct calls (whose lanes idle from the end
        #: of their rollout to the end of the call's longest one).
        self.last_stats = None
        #: ``(distance [m], duration [s])`` (NumPy, one per rollout) of the last
        #: :meth:`scores`, and per item of the last :meth:`evaluate_many` those of each
        #: parameter set's worst-of-k rollout
        self.last_walk: tuple[np.ndarray, np.ndarray] | None = None
        self.last_walks: list[tuple[np.ndarray, np.ndarray]] = []
        #: per rollout of the last direct :meth:`scores` call: did it fall (None after a
        #: queued evaluation, whose program returns no fall flags)
        self.last_fell: np.ndarray | None = None
        # host scalars: replicated on every device (and process) of the mesh
        self.d_lim = np.float32(exp.d_lim if math.isfinite(exp.d_lim) else np.inf)
        self.v0 = np.float32(exp.v0)

    def run(self, params: jax.Array, env_keys: jax.Array, rows: int | None = None):
        """Raw rollouts of (B, D) params on the environments of (B,) keys, chunked and padded.

        Every call holds ``rows`` rollouts (default :attr:`rows`; padded with copies of row
        0). Yields ``(real, trace, events, summary)`` per call; ``real`` are the indices (into
        ``params``) of the unpadded rows, which come first in the call.
        """
        from jaxgait.world import envs

        n = params.shape[0]
        rows = self.rows if rows is None else rows
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
        With :attr:`lanes` set (and no ``keep_first``) the rollouts are queued over that many
        lanes per device (:meth:`lane_scores`); otherwise they run in direct calls of
        :attr:`rows`.  ``keep_first``: also return the (trace, events, summary) of row 0
        (NumPy).
        """
        n = params.shape[0]
        cap = np.full(n, self.objective.n_stages, np.int32) if max_stage is None else max_stage
        if self.lanes is not None and not keep_first:
            return self.lane_scores(params, env_keys, cap)
        first = None
        _, rpc, _ = sim_rollout_steps(self.sim_cfg, self.model.dt)
        chunk_steps = rpc * round(self.sim_cfg.log_dt / self.model.dt)
        busy = total = chunks = 0
        stage = np.zeros(n, np.int32)
        value = np.zeros(n, np.float64)
        valid = np.zeros(n, bool)
        dist, dur = np.zeros(n), np.zeros(n)
        fell = np.zeros(n, bool)
        # The iterations of a queued run compile no direct call, so the final evaluation's
        # few rollouts get a call of their own size instead of one padded to :attr:`rows`.
        rows = padded_size(n, self.n_devices, None)[0] if self.lanes is not None else None
        for real, trace, events, summary in self.run(params, env_keys, rows):
            m = real.size
            rows = trace.t.shape[0]
            ms = np.concatenate([np.asarray(cap)[real], np.zeros(rows - m, np.int32)])
            ms = shard_population(ms, self.mesh)
            s, v, ok, d, t = to_host(self.score(trace, events, summary, ms))
            stage[real], value[real], valid[real] = (a[:m] for a in (s, v, ok))
            dist[real], dur[real] = d[:m], t[:m]
            fell[real] = to_host(summary.fell)[:m]
            if keep_first and first is None:
                rec = (trace, events, summary)
                if self.mesh.is_multi_process:  # gather the call, keep row 0
                    first = jax.tree.map(lambda x: x[0], to_host(rec))
                else:
                    first = to_host(jax.tree.map(lambda x: x[0], rec))
            # each lane runs whole chunks until its rollout ends; the call until its longest
            ran = np.ceil(to_host(summary.duration) / self.sim_cfg.chunk_s - 1e-6)
            ran = np.maximum(ran, 1).astype(np.int64)
            busy += int(ran[:m].sum()) * chunk_steps
            total += int(ran.max()) * rows * chunk_steps
            chunks += int(ran.max())
        self.last_stats = LaneStats(busy=busy, total=total, chunks=chunks)
        self.last_walk = (dist, dur)
        self.last_fell = fell
        if keep_first:
            return stage, value, valid, first
        return stage, value, valid

    def lane_scores(self, params: jax.Array, env_keys: jax.Array, max_stage):
        """Scheduled evaluation: the B rollouts split into one queue per device, each run
        over :attr:`lanes` lanes, those with the highest ``max_stage`` first;
        ``(stage, value, valid)`` (NumPy, B each, in the order of ``params``).  The lane counts
        are kept in :attr:`last_stats`."""
        from jaxgait.world import envs

        n, d = params.shape[0], self.n_devices
        per = -(-n // d)
        cap = np.asarray(max_stage, np.int32)
        # The longest rollouts first, so that the queue's tail is short rollouts: a higher
        # stage cap (stage PSO: the candidate's stage + 1) predicts a longer walk.  The
        # ordered rollouts are dealt round-robin to the devices' queues.
        order = np.argsort(-cap, kind="stable")
        slots = np.full((d, per), -1)
        for g in range(d):
            mine = order[g::d]
            slots[g, : mine.size] = mine
        slots = slots.reshape(-1)
        real = slots >= 0
        idx = np.where(real, slots, order[0])  # short queues are padded with a copy
        env_all = envs.make_env_batch(self.env_cfg, env_keys)
        group = lambda x: x[idx].reshape((d, per) + x.shape[1:])
        p = shard_population(group(jnp.asarray(params)), self.mesh)
        e = shard_population(jax.tree.map(group, env_all), self.mesh)
        ms = shard_population(group(jnp.asarray(max_stage, jnp.int32)), self.mesh)
        out = to_host(self.lane_score(p, e, ms, self.d_lim, self.v0))
        stage, value, valid, dist, dur, stats = out
        self.last_stats = jax.tree.map(lambda x: x.sum(), stats)

        def flat(x):
            out = np.empty(n, x.dtype)
            out[slots[real]] = x.reshape(d * per)[real]
            return out

        self.last_walk = (flat(dist).astype(np.float64), flat(dur).astype(np.float64))
        self.last_fell = None  # the queued program returns no fall flags
        return flat(stage), flat(value).astype(np.float64), flat(valid)

    def evaluate(self, population: jax.Array, key: jax.Array, max_stage=None):
        """Worst-of-k ``(stage (P,), value (P,), n_failed_rollouts)`` of a (P, D) population.

        Each parameter set is rolled out on k fresh environments drawn from ``key``.
        """
        return self.evaluate_many([(population, key, max_stage)])[0]

    def evaluate_many(self, items: Sequence[tuple[jax.Array, jax.Array, Any]]):
        """:meth:`evaluate` of several populations ``[(population, key, max_stage), ...]``
        (independent runs of one experiment) in one evaluation: their P x k rollouts share
        the calls (or the queue), so every lane is busier and each population gets the
        rollouts it would get alone.  Returns one ``(stage, value, n_failed)`` per item."""
        k = self.exp.worst_of_k
        sizes = [int(pop.shape[0]) for pop, _, _ in items]
        params = jnp.concatenate([jnp.repeat(pop, k, axis=0) for pop, _, _ in items])
        keys = jnp.concatenate(
            [jax.random.split(key, n * k) for (_, key, _), n in zip(items, sizes, strict=True)]
        )
        caps = [
            np.full(n * k, self.objective.n_stages, np.int32)
            if ms is None
            else np.repeat(np.asarray(ms, np.int32), k)
            for (_, _, ms), n in zip(items, sizes, strict=True)
        ]
        stage, value, valid = self.scores(params, keys, np.concatenate(caps))
        dist, dur = self.last_walk
        out, at = [], 0
        self.last_walks = []
        for n in sizes:
            sl = slice(at, at + n * k)
            at += n * k
            st, va = stage[sl].reshape(n, k), value[sl].reshape(n, k)
            ws, wv = objective_mod.worst_of_k(jnp.asarray(st), jnp.asarray(va))
            out.append((ws, wv.astype(jnp.float32), int((~valid[sl]).sum())))
            pick = (np.arange(n), worst_rows(st, va))
            self.last_walks.append((dist[sl].reshape(n, k)[pick], dur[sl].reshape(n, k)[pick]))
        return out
