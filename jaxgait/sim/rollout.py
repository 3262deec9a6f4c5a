"""Rollouts: the step scanned in chunks, with a decimated trace, events and a summary.

``rollout`` scans :func:`jaxgait.sim.step.step` in chunks inside a ``while_loop`` that stops
once the rollout (or, under ``vmap``, every rollout of the batch) is done, logging a
decimated :class:`~jaxgait.sim.trace.Trace`, the touchdown
:class:`~jaxgait.sim.trace.Events` and a :class:`~jaxgait.sim.trace.Summary`.  It is
``vmap``-able over parameter vectors, environments and command schedules; ``jit`` it at the
edge (see :func:`make_rollout`).
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp

from jaxgait.control.commands import CommandLaw, Schedule
from jaxgait.sim.model import Model, SimConfig, SimState
from jaxgait.sim.step import initial_state, step
from jaxgait.sim.trace import Summary, Trace
from jaxgait.world.envs import Env


def _log_row(model: Model, s: SimState, alive) -> Trace:
    pts, lin = jax.linearize(lambda q: model.points(q, jnp.zeros((), q.dtype)), s.qpos)
    com_vel = lin(s.qvel)[7]
    return Trace(
        t=s.t,
        qpos=s.qpos,
        com=pts[7],
        com_vel=com_vel,
        grf=s.grf,
        stance=s.gait.stance,
        act=s.muscle.act,
        stim=s.stim,
        energy=s.energy,
        alive=alive,
    )


def rollout_steps(cfg: SimConfig, dt: float) -> tuple[int, int, int]:
    """(physics steps per log row, rows per chunk, number of chunks)."""
    log_every = round(cfg.log_dt / dt)
    if log_every < 1 or abs(log_every * dt - cfg.log_dt) > 1e-9:
        raise ValueError(f"log_dt {cfg.log_dt} must be a whole multiple of dt {dt}")
    rows_per_chunk = max(1, round(cfg.chunk_s / cfg.log_dt))
    n_rows = math.ceil(cfg.duration / cfg.log_dt)
    n_chunks = math.ceil(n_rows / rows_per_chunk)
    return log_every, rows_per_chunk, n_chunks


def empty_trace(model: Model, cfg: SimConfig, s0: SimState) -> Trace:
    """A zero trace buffer of ``n_chunks * rows_per_chunk`` rows shaped like :func:`_log_row`."""
    _, rpc, n_chunks = rollout_steps(cfg, model.dt)
    row0 = _log_row(model, s0, jnp.ones((), bool))
    return jax.tree.map(lambda x: jnp.zeros((n_chunks * rpc,) + x.shape, x.dtype), row0)


def run_chunk(
    model: Model,
    cfg: SimConfig,
    params,
    env: Env,
    s: SimState,
    commands: Schedule | None = None,
    command_law: CommandLaw | None = None,
):
    """One chunk (``rows_per_chunk`` logged rows) from ``s``: ``(state, rows)``."""
    log_every, rpc, _ = rollout_steps(cfg, model.dt)

    def one_row(s, _):
        s = jax.lax.fori_loop(
            0, log_every, lambda i, s: step(model, cfg, params, env, s, commands, command_law), s
        )
        return s, _log_row(model, s, ~s.done)

    return jax.lax.scan(one_row, s, None, length=rpc)


def summary_of(model: Model, s: SimState) -> Summary:
    """The :class:`Summary` of a final state (a rollout that never reached "done" is closed
    at its current time; the duration normally stops it)."""
    return Summary(
        duration=jnp.where(s.done, s.end_t, s.t),
        distance=jnp.where(s.done, s.end_x, model.points(s.qpos, 0.0 * s.t)[7, 0]) - s.x0,
        fell=s.fell,
        energy=jnp.where(s.done, s.end_energy, s.energy),
        trunk_lean_sum=jnp.where(s.done, s.end_lean, s.lean_sum),
        mass=jnp.asarray(model.mass, s.t.dtype),
        limit_torque_sq=jnp.where(s.done, s.end_limit_sq, s.limit_sq),
    )


def rollout(
    model: Model,
    cfg: SimConfig,
    params,
    env: Env,
    commands: Schedule | None = None,
    command_law: CommandLaw | None = None,
):
    """Simulate one parameter set in one environment.

    Args:
      model, cfg: static model and settings; params: (D,) parameters; env: environment.
      commands: optional :class:`~jaxgait.control.commands.Schedule` of the controller's
        control vector (a pytree: batch it with ``vmap`` like ``env``); default: the
        controller's defaults throughout.
      command_law: optional static :class:`~jaxgait.control.commands.CommandLaw` run inside
        the step after the sensors.

    Returns (trace: Trace with leading time axis, events: Events, summary: Summary,
    final state).  Stops at the first chunk end after the rollout is done.
    """
    _, rpc, n_chunks = rollout_steps(cfg, model.dt)
    s0 = initial_state(model, params, env, cfg, commands, command_law)
    trace0 = empty_trace(model, cfg, s0)

    def chunk(carry):
        k, s, trace = carry
        s, rows = run_chunk(model, cfg, params, env, s, commands, command_law)
        trace = jax.tree.map(
            lambda buf, r: jax.lax.dynamic_update_slice_in_dim(buf, r, k * rpc, 0), trace, rows
        )
        return k + 1, s, trace

    def cond(carry):
        k, s, _ = carry
        return (k < n_chunks) & ~s.done

    _, s, trace = jax.lax.while_loop(cond, chunk, (jnp.zeros((), jnp.int32), s0, trace0))
    n_rows = math.ceil(cfg.duration / cfg.log_dt)
    trace = jax.tree.map(lambda x: x[:n_rows], trace)
    return trace, s.events, summary_of(model, s), s


def make_rollout(
    model: Model, cfg: SimConfig, batched: bool = True, command_law: CommandLaw | None = None
):
    """jit-compiled rollout ``f(params, env, commands=None)``; with ``batched`` it maps over
    (params (B, D), env batch, schedule batch or None)."""
    f = partial(rollout, model, cfg, command_law=command_law)
    if batched:
        f = jax.vmap(f)
    return jax.jit(f)
