"""A queue of rollouts over a fixed number of lanes: every lane busy until the queue is empty.

A generation of an optimiser is Q (candidate, environment) rollouts of very different lengths
(a faller ends after a second, a walker runs to its distance limit).  ``vmap(rollout)`` runs
the batch until its slowest member ends, while the lanes of the others idle.
:func:`lane_rollouts` instead runs L lanes in chunks (the chunks of :func:`rollout`); at each
chunk end the lanes whose rollout is done hand its trace, events and summary to ``finish``
(whose result lands in the rollout's slot) and take the next rollout from the queue, until
the queue is empty.

Each rollout starts at a chunk boundary of its lane and runs the same chunks as
:func:`~jaxgait.sim.rollout.rollout` does alone, so its trace, events and summary are those of
the rollout alone up to the rounding of a different batch (the physics is vectorised over a
different set of lanes).

Once the queue is empty the generation's tail is its last, longest rollouts (the walkers)
while the other lanes idle.  With ``drain`` widths the program then shrinks: once no more
rollouts are active than the next width, the active lanes are gathered into that many lanes
and run on in a narrower (cheaper) batch, as many times as ``drain`` names widths.  Each width
is its own compiled chunk program.

Lane utilisation = busy lane-steps / all lane-steps, counted in whole chunks (a lane is busy
during a chunk if it holds a rollout that was not done when the chunk began); the lanes of a
drained phase count at that phase's width.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from jaxgait.sim.model import Model, SimConfig
from jaxgait.sim.rollout import empty_trace, rollout_steps, run_chunk, summary_of
from jaxgait.sim.step import initial_state
from jaxgait.world.envs import Env


@struct.dataclass
class LaneStats:
    """Counts of a scheduled evaluation.

    Attributes:
      busy: () lane-steps spent on rollouts (physics steps x lanes).
      total: () all lane-steps of the program.
      chunks: () chunks run.
    """

    busy: jax.Array
    total: jax.Array
    chunks: jax.Array

    @property
    def utilisation(self) -> jax.Array:
        return self.busy / jnp.maximum(self.total, 1)


def _take(tree, idx):
    return jax.tree.map(lambda x: x[idx], tree)


def _select(mask, a, b):
    """Per lane: ``a`` where ``mask`` else ``b`` (leaves with a leading lane axis)."""

    def pick(x, y):
        m = mask.reshape(mask.shape + (1,) * (x.ndim - 1))
        return jnp.where(m, x, y)

    return jax.tree.map(pick, a, b)


def lane_rollouts(
    model: Model,
    cfg: SimConfig,
    params: jax.Array,
    env: Env,
    finish: Callable[..., Any],
    n_lanes: int,
    commands=None,
    aux=None,
    drain=(),
):
    """Run the Q rollouts of ``params`` (Q, D) on ``env`` (batch of Q) over ``n_lanes`` lanes.

    Args:
      model, cfg: as for :func:`~jaxgait.sim.rollout.rollout` (static).
      params: (Q, D) parameter sets; env: Q environments (leading axis); commands: optional
        batch of Q schedules.
      finish: ``(trace, events, summary, aux) -> pytree`` on a batch of rollouts (leading
        axis; traceable), e.g. their measures or scores; called with one rollout at a time,
        as each ends.
      n_lanes: L, the lanes run side by side (static; more than Q leaves some idle).
      aux: optional pytree with a leading axis of Q, each rollout's row handed to ``finish``
        (e.g. a per-candidate stage cap).
      drain: decreasing lane counts (static, each below ``n_lanes``) the program shrinks to
        once the queue is empty and no more rollouts are active than that count; () never.

    Returns:
      ``(results, stats)``: ``finish``'s outputs stacked over the Q rollouts in queue order,
      and :class:`LaneStats`.
    """
    q = params.shape[0]
    lanes = int(n_lanes)
    if lanes < 1:
        raise ValueError(f"n_lanes must be at least 1, got {n_lanes}")
    widths = tuple(int(w) for w in drain)
    if any(w < 1 for w in widths) or any(
        b >= a for a, b in zip((lanes, *widths), widths, strict=False)
    ):
        raise ValueError(
            f"drain must be decreasing lane counts from 1 to below n_lanes={lanes}, got {drain}"
        )
    log_every, rpc, n_chunks = rollout_steps(cfg, model.dt)
    n_rows = math.ceil(cfg.duration / cfg.log_dt)
    steps_per_chunk = rpc * log_every

    def inputs(item):
        """The parameters, environments and schedules of the lanes' rollouts."""
        c = None if commands is None else _take(commands, item)
        return params[item], _take(env, item), c

    def start(item):
        return jax.vmap(lambda p, e, c: initial_state(model, p, e, cfg, c))(*inputs(item))

    def chunk_all(lane_in, s):
        f = lambda p, e, s, c: run_chunk(model, cfg, p, e, s, c)
        return jax.vmap(f)(*lane_in[:2], s, lane_in[2])

    def finish_all(trace, s, aux_rows):
        rows = jax.tree.map(lambda x: x[:, :n_rows], trace)
        summary = jax.vmap(lambda st: summary_of(model, st))(s)
        return finish(rows, s.events, summary, aux_rows)

    def finish_ended(trace, s, item, k, ended, results):
        """``finish`` on each ended lane alone (a batch of one), its result in its slot.

        A lane's buffer keeps the rows of its earlier rollouts past those its current one
        wrote (``k`` chunks); they are zeroed here, in the ended lane's copy only, so
        ``finish`` sees the trace of the rollout alone (zero past its end) without a refill
        clearing every lane's whole buffer."""
        order = jnp.argsort(~ended, stable=True)  # the ended lanes first
        row = jnp.arange(n_chunks * rpc)

        def mine(x, lane):
            written = row < k[lane] * rpc
            return jnp.where(written.reshape((-1,) + (1,) * (x.ndim - 2)), x[lane], 0)[None]

        def one(i, res):
            lane = order[i]
            tr = jax.tree.map(lambda x: mine(x, lane), trace)
            st = jax.tree.map(lambda x: x[lane][None], s)
            a = None if aux is None else _take(aux, item[lane][None])
            out = finish_all(tr, st, a)
            return jax.tree.map(lambda r, o: r.at[item[lane]].set(o[0]), res, out)

        return jax.lax.fori_loop(0, ended.sum(), one, results)

    item0 = jnp.minimum(jnp.arange(lanes), q - 1)
    active0 = jnp.arange(lanes) < q
    s0 = start(item0)
    trace0 = jax.vmap(lambda st: empty_trace(model, cfg, st))(s0)
    aux0 = None if aux is None else _take(aux, item0)
    out_shape = jax.eval_shape(finish_all, trace0, s0, aux0)
    results0 = jax.tree.map(lambda x: jnp.zeros((q,) + x.shape[1:], x.dtype), out_shape)
    zero = jnp.zeros((), jnp.int32)
    stats0 = LaneStats(busy=zero, total=zero, chunks=zero)

    def body(carry):
        item, lane_in, active, k, s, trace, nxt, results, stats = carry
        # an idle lane keeps its state (as vmap(rollout) keeps its done rollouts'), so a
        # fallen body is not integrated on for the rest of the queue
        s_new, rows = chunk_all(lane_in, s)
        s = _select(active, s_new, s)
        trace = jax.vmap(
            lambda buf, r, k: jax.tree.map(
                lambda b, x: jax.lax.dynamic_update_slice_in_dim(b, x, k * rpc, 0), buf, r
            )
        )(trace, rows, k)
        stats = LaneStats(
            busy=stats.busy + active.sum().astype(jnp.int32) * steps_per_chunk,
            total=stats.total + active.shape[0] * steps_per_chunk,
            chunks=stats.chunks + 1,
        )
        k = k + 1
        ended = active & (s.done | (k >= n_chunks))
        results = finish_ended(trace, s, item, k, ended, results)
        # the ended lanes take the next rollouts of the queue, in lane order
        new_item = nxt + jnp.cumsum(ended) - 1
        take = ended & (new_item < q)
        item = jnp.where(take, new_item, item)
        nxt = nxt + take.sum().astype(jnp.int32)
        active = (active & ~ended) | take

        def refill(s, lane_in):
            return _select(take, start(item), s), inputs(item)

        s, lane_in = jax.lax.cond(jnp.any(take), refill, lambda s, li: (s, li), s, lane_in)
        k = jnp.where(take, 0, k)
        return item, lane_in, active, k, s, trace, nxt, results, stats

    def cond_until(width):
        """Run while a lane is active and, before a drain to ``width`` lanes, until the
        queue is empty with at most ``width`` rollouts active."""

        def cond(carry):
            active, nxt = carry[2], carry[6]
            go = jnp.any(active)
            if width is not None:
                go = go & ~((nxt >= q) & (active.sum() <= width))
            return go

        return cond

    def narrow(carry, width):
        """The active lanes gathered into the first ``width`` lanes (the rest are idle)."""
        item, lane_in, active, k, s, trace, nxt, results, stats = carry
        keep = jnp.argsort(~active, stable=True)[:width]
        lane = lambda t: _take(t, keep)
        return (
            item[keep],
            lane(lane_in),
            active[keep],
            k[keep],
            lane(s),
            lane(trace),
            nxt,
            results,
            stats,
        )

    k0 = jnp.zeros((lanes,), jnp.int32)
    nxt0 = jnp.asarray(min(lanes, q), jnp.int32)
    carry = (item0, inputs(item0), active0, k0, s0, trace0, nxt0, results0, stats0)
    for width in (*widths, None):
        carry = jax.lax.while_loop(cond_until(width), body, carry)
        if width is not None:
            carry = narrow(carry, width)
    return carry[7], carry[8]
