"""Gradient refinement of controller parameters through the differentiable rollout (SPEC §4).

:func:`jaxgait.sim.rollout` stops with a ``lax.while_loop``, which reverse-mode autodiff does
not support; this module rolls :func:`jaxgait.sim.step` out with fixed-length scans instead:

* :func:`advance`: forward only, any number of steps (``fori_loop``), for warm-ups and checks;
* :func:`window`: the differentiable window. The window is cut into segments of
  ``segment_steps`` physics steps; each segment is a ``lax.scan`` of :func:`~jaxgait.sim.step`
  wrapped in ``jax.checkpoint`` (only the segment boundaries are stored for the backward pass,
  the steps of a segment are recomputed), and an outer scan runs up to ``max_segments`` of them,
  a segment past the traced ``n_segments`` being skipped by ``lax.cond``. One compiled program
  therefore serves every window length up to ``max_segments x segment_steps``.

Objectives of a window (all minimised, :data:`OBJECTIVES`):

* ``"energy"``: metabolic cost of transport over the window, dE / (m g dx) (thesis 2.1.2.4),
  dx floored at 1 cm, plus ``speed_weight (dx / T - v*)^2`` so that energy is not saved by
  slowing down;
* ``"angles"``: mean squared difference [deg^2] of the right hip, knee and ankle angles to
  Winter's mean curves (thesis eq. 2.48-2.51 use the correlation; a squared error is its smooth
  counterpart), the gait phase of each sample taken from time with the cycle start and period
  measured before the window (fixed, not differentiated).

Phase switches: the reflex gates (stance / swing / stance end) are ``jnp.where`` on the filtered
ground load, the muscle stimulations are clipped, the contact and ligament forces switch on and
off. Nothing is smoothed here: the gradient is the pathwise derivative of the time-discretised
dynamics with every switch held at the step where it happens (zero through the gate itself, the
full derivative through each active branch). It is exact wherever no switch moves to another step
under a small change of the parameters, which the finite-difference test checks on a short
window; over longer windows it is a useful descent direction, not the derivative of the
(discontinuous) window cost. Short windows (0.05-2 s), gradient clipping and a check that the
refined gait still walks (:func:`refine`) keep it safe. Smoothing the gates (e.g. a sigmoid of
the load instead of the ``where``) would need a change in :mod:`jaxgait.control.fbl`.

:func:`refine` is the optimiser: ``optax.chain(clip_by_global_norm, adam)`` on the parameters
in box coordinates (each range mapped to [0, 1]), clipped to the ranges after each update. The
window starts from the state the initial parameters reach after ``warmup_s`` (the same function is
optimised at every step), or, with ``rewarm``, every step re-runs the warm-up with the current
parameters and differentiates the window after it (truncated backpropagation as in brax's APG).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import sim
from jaxgait.world.envs import Env

#: Window objectives (minimised).
OBJECTIVES = ("energy", "angles")


class GradientError(ValueError):
    """Bad settings for the gradient refinement (window, objective, learning rate...)."""


@dataclass(frozen=True)
class WindowConfig:
    """Settings of the differentiable window.

    Attributes:
      window_s: differentiated window [s].
      warmup_s: forward-only simulation before the window [s] (reach the limit cycle).
      segment_s: checkpointed segment length [s] (memory ~ window / segment states).
      objective: ``"energy"`` or ``"angles"`` (see the module docstring).
      v_desired: target speed of the ``energy`` objective [m/s].
      speed_weight: weight of (v - v*)^2 in the ``energy`` objective [s^2/m^2].
      log_every: physics steps between the angle samples of the ``angles`` objective.
    """

    window_s: float = 1.0
    warmup_s: float = 3.0
    segment_s: float = 0.05
    objective: str = "energy"
    v_desired: float = 1.3
    speed_weight: float = 1.0
    log_every: int = 10

    def __post_init__(self):
        if self.objective not in OBJECTIVES:
            raise GradientError(
                f"unknown objective {self.objective!r}; valid objectives: {', '.join(OBJECTIVES)}"
            )
        for name in ("window_s", "segment_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0 < v < math.inf):
                raise GradientError(f"{name} must be a positive number of seconds, got {v!r}")
        if not (isinstance(self.warmup_s, (int, float)) and 0 <= self.warmup_s < math.inf):
            raise GradientError(f"warmup_s must be >= 0 seconds, got {self.warmup_s!r}")
        if not (isinstance(self.log_every, int) and self.log_every >= 1):
            raise GradientError(f"log_every must be a positive integer, got {self.log_every!r}")

    def steps(self, dt: float) -> tuple[int, int, int]:
        """(warm-up steps, steps per segment, segments) for physics step ``dt`` [s]."""
        seg = max(1, round(self.segment_s / dt))
        seg = -(-seg // self.log_every) * self.log_every
        n_seg = max(1, round(self.window_s / (seg * dt)))
        return round(self.warmup_s / dt), seg, n_seg


def _sim_cfg() -> sim.SimConfig:
    # no stopping criterion inside the window: the scans have a fixed length
    return sim.SimConfig(duration=1e9)


# --------------------------------------------------------------------------- rollouts


@functools.partial(jax.jit, static_argnums=(0,))
def _advance(model, params, env, state, n_steps):
    cfg = _sim_cfg()
    return jax.lax.fori_loop(0, n_steps, lambda i, s: sim.step(model, cfg, params, env, s), state)


def advance(model, params, env: Env, state: sim.SimState, n_steps: int) -> sim.SimState:
    """``n_steps`` physics steps from ``state`` (forward only; ``n_steps`` is traced)."""
    return _advance(model, params, env, state, jnp.asarray(n_steps, jnp.int32))


def start_state(model, params, env: Env, warmup_steps: int, v0: float = 1.3) -> sim.SimState:
    """Initial posture (:func:`jaxgait.sim.initial_state`) advanced by ``warmup_steps``."""
    cfg = sim.SimConfig(duration=1e9, v0=v0)
    s0 = sim.initial_state(model, params, env, cfg)
    return advance(model, params, env, s0, warmup_steps)


def window(
    model,
    params,
    env: Env,
    state: sim.SimState,
    n_segments,
    segment_steps: int,
    max_segments: int,
    log_every: int,
):
    """Differentiable window of ``n_segments x segment_steps`` steps from ``state``.

    Args:
      model: :class:`~jaxgait.sim.Model`.
      params: (D,) parameters (differentiated).
      env, state: environment and start state (treated as constants).
      n_segments: () int, traced, ``<= max_segments``.
      segment_steps: static steps per checkpointed segment (a multiple of ``log_every``).
      max_segments: static length of the outer scan.
      log_every: static steps between logged samples.

    Returns:
      ``(final_state, samples)``: ``samples`` has leaves of shape
      (max_segments, segment_steps // log_every, ...): ``t`` [s], ``qpos`` [m, rad] and ``live``
      (the sample belongs to an executed segment).
    """
    cfg = _sim_cfg()
    per = segment_steps // log_every

    def inner(s, _):
        s = jax.lax.fori_loop(0, log_every, lambda i, x: sim.step(model, cfg, params, env, x), s)
        return s, (s.t, s.qpos)

    @jax.checkpoint
    def segment(s):
        return jax.lax.scan(inner, s, None, length=per)

    def skip(s):
        t = jnp.zeros((per,), s.t.dtype)
        q = jnp.zeros((per,) + s.qpos.shape, s.qpos.dtype)
        return s, (t, q)

    def outer(s, i):
        s, (t, q) = jax.lax.cond(i < n_segments, segment, skip, s)
        live = jnp.full((per,), i < n_segments)
        return s, {"t": t, "qpos": q, "live": live}

    return jax.lax.scan(outer, state, jnp.arange(max_segments))


# --------------------------------------------------------------------------- objectives


def _winter_deg() -> tuple[np.ndarray, np.ndarray]:
    from jaxgait.analysis.refdata import winter_walking_kinematics

    ref = winter_walking_kinematics()
    return np.asarray(ref.gait_cycle_pct) / 100.0, np.asarray(ref.mean_deg)


def cycle_timing(state: sim.SimState, leg: int = 0) -> tuple[jax.Array, jax.Array]:
    """(start [s], period [s]) of the last full cycle of ``leg`` from the recorded touchdowns.

    The period is that last full cycle's; the start is the last touchdown. Both are returned as
    constants (``stop_gradient``). Without two touchdowns the period is 1 s.
    """
    ev = state.events
    n = jnp.minimum(ev.n, ev.t.shape[0])
    idx = jnp.arange(ev.t.shape[0])
    mine = (idx < n) & (ev.leg == leg)
    last = jnp.max(jnp.where(mine, ev.t, -jnp.inf))
    prev = jnp.max(jnp.where(mine & (ev.t < last), ev.t, -jnp.inf))
    period = jnp.where(jnp.isfinite(prev), last - prev, 1.0)
    start = jnp.where(jnp.isfinite(last), last, state.t)
    return jax.lax.stop_gradient(start), jax.lax.stop_gradient(period)


def window_loss(
    model,
    cfg: WindowConfig,
    params,
    env: Env,
    state: sim.SimState,
    n_segments,
    segment_steps: int,
    max_segments: int,
):
    """Objective (minimised) of the window from ``state``; returns ``(loss, aux dict)``."""
    end, smp = window(
        model, params, env, state, n_segments, segment_steps, max_segments, cfg.log_every
    )
    dt_win = end.t - state.t
    d_e = end.energy - state.energy
    pts0 = model.points(state.qpos, jnp.zeros((), state.qpos.dtype))
    pts1 = model.points(end.qpos, jnp.zeros((), end.qpos.dtype))
    dx = pts1[7, 0] - pts0[7, 0]
    speed = dx / jnp.maximum(dt_win, 1e-6)
    cot = d_e / (model.mass * 9.81 * jnp.maximum(dx, 0.01))
    start, period = cycle_timing(state)
    pct, ref = _winter_deg()
    t = smp["t"].reshape(-1)
    q = smp["qpos"].reshape(t.shape[0], -1)
    live = smp["live"].reshape(-1)
    phase = jnp.mod((t - start) / period, 1.0)
    target = jnp.stack(
        [
            jnp.interp(phase, jnp.asarray(pct, t.dtype), jnp.asarray(ref[:, j], t.dtype))
            for j in range(3)
        ],
        -1,
    )
    err = jnp.rad2deg(q[:, 3:6]) - target
    mse = jnp.sum(jnp.where(live[:, None], err**2, 0.0)) / (3 * jnp.maximum(jnp.sum(live), 1))
    if cfg.objective == "energy":
        loss = cot + cfg.speed_weight * (speed - cfg.v_desired) ** 2
    else:
        loss = mse
    aux = {
        "cot": cot,
        "speed": speed,
        "angle_mse_deg2": mse,
        "energy_J": d_e,
        "dx_m": dx,
        "fell": end.fell,
    }
    return loss, aux


@functools.partial(jax.jit, static_argnums=(0, 1, 5, 6))
def _loss_and_grad(model, cfg, params, env, state, segment_steps, max_segments, n_segments):
    f = lambda p: window_loss(model, cfg, p, env, state, n_segments, segment_steps, max_segments)
    return jax.value_and_grad(f, has_aux=True)(params)


def loss_and_grad(
    model,
    cfg: WindowConfig,
    params,
    env: Env,
    state: sim.SimState,
    n_segments: int | None = None,
    max_segments: int | None = None,
):
    """``((loss, aux), d loss / d params)`` of the window of ``cfg`` from ``state``.

    ``n_segments`` (default: the window of ``cfg``) may be smaller than ``max_segments`` (default
    ``n_segments``) to evaluate shorter windows with the same compiled program.
    """
    _, seg, n_seg = cfg.steps(model.dt)
    n = n_seg if n_segments is None else int(n_segments)
    m = n if max_segments is None else int(max_segments)
    if not 1 <= n <= m:
        raise GradientError(f"need 1 <= n_segments ({n}) <= max_segments ({m})")
    # window and warm-up lengths do not enter the traced function: one compiled program
    traced_cfg = dataclasses.replace(cfg, window_s=1.0, warmup_s=0.0, segment_s=1.0)
    n = jnp.asarray(n, jnp.int32)
    return _loss_and_grad(model, traced_cfg, params, env, state, seg, m, n)


# --------------------------------------------------------------------------- refinement


@dataclass
class RefineResult:
    """Outcome of :func:`refine`.

    Attributes:
      params: (D,) refined parameters (inside the table ranges).
      initial_params: (D,) starting parameters.
      losses: window objective before each update (and after the last one).
      aux: per-evaluation dicts of window measures (cot, speed, angle_mse_deg2, ...).
      fell_initial, fell_final: a ``check_s`` rollout from the initial posture fell.
      grad_norms: global gradient norm of each update (before clipping).
      step_scales: fraction of the Adam step taken by each accepted update (safeguard).
      rejected: updates for which every trial step fell (the refinement stopped there).
    """

    params: np.ndarray
    initial_params: np.ndarray
    losses: list[float] = field(default_factory=list)
    aux: list[dict] = field(default_factory=list)
    grad_norms: list[float] = field(default_factory=list)
    fell_initial: bool | None = None
    fell_final: bool | None = None
    step_scales: list[float] = field(default_factory=list)
    rejected: list[int] = field(default_factory=list)


def walks(model, params, env: Env, seconds: float, v0: float = 1.3) -> bool:
    """True if a ``seconds`` rollout from the initial posture does not fall."""
    cfg = sim.SimConfig(duration=1e9, v0=v0)
    s = sim.initial_state(model, params, env, cfg)
    s = advance(model, params, env, s, round(seconds / model.dt))
    return not bool(s.fell)


def refine(
    model,
    params,
    env: Env,
    cfg: WindowConfig = WindowConfig(),
    steps: int = 10,
    learning_rate: float = 0.003,
    max_grad_norm: float = 1.0,
    check_s: float | None = 10.0,
    progress: Callable[[str], object] | None = None,
    rewarm: bool = False,
    max_segments: int | None = None,
    safeguard: bool = True,
    max_halvings: int = 4,
) -> RefineResult:
    """Adam steps on the window objective, parameters kept in their ranges.

    Args:
      model: :class:`~jaxgait.sim.Model` (its table gives the ranges).
      params: (D,) starting parameters (e.g. an optimised preset).
      env: environment.
      cfg: window settings.
      steps: number of Adam updates.
      learning_rate: Adam step in box coordinates (fraction of each parameter range).
      max_grad_norm: global-norm clip of the gradient (box coordinates).
      check_s: length of the no-fall check of the initial and final parameters [s] (None: skip).
      progress: callable receiving one line per step.
      rewarm: re-run the warm-up with the current parameters before every step (the window
        then starts wherever the new gait is after ``warmup_s``); default False: the window
        starts from the state the initial parameters reach, so every step optimises the same
        function (a window shorter than a gait cycle is otherwise dominated by the shift of
        its start within the cycle).
      max_segments: outer scan length of the compiled window (default: the window's segment
        count); a larger value lets one compiled program serve several window lengths.
      safeguard: check every update with a ``check_s`` rollout from the initial posture; an
        update whose gait falls is halved (up to ``max_halvings`` times) and the refinement
        stops if every trial falls. Lowering the energy of a window readily trades away
        stability that shows only seconds later; the check keeps the refined gait walking.
      max_halvings: trials per update of the safeguard.

    Returns:
      :class:`RefineResult`; ``losses[0]`` / ``losses[-1]`` are the objective of the initial /
      final parameters.
    """
    import optax

    if not (isinstance(steps, int) and steps >= 0):
        raise GradientError(f"steps must be a non-negative integer, got {steps!r}")
    if not (isinstance(max_halvings, int) and max_halvings >= 0):
        raise GradientError(f"max_halvings must be a non-negative integer, got {max_halvings!r}")
    if not learning_rate > 0 or not max_grad_norm > 0:
        raise GradientError("learning_rate and max_grad_norm must be > 0")
    table = model.table
    dtype = jnp.asarray(params).dtype
    lo = jnp.asarray(table.lower, dtype)
    hi = jnp.asarray(table.upper, dtype)
    x0 = jnp.clip(jnp.asarray(params, dtype), lo, hi)
    z = (x0 - lo) / (hi - lo)
    opt = optax.chain(optax.clip_by_global_norm(max_grad_norm), optax.adam(learning_rate))
    opt_state = opt.init(z)
    warm, _, _ = cfg.steps(model.dt)
    res = RefineResult(params=np.asarray(x0), initial_params=np.asarray(x0))

    fixed = None if rewarm else start_state(model, x0, env, warm, cfg.v_desired)

    def evaluate(zz):
        x = lo + zz * (hi - lo)
        s = start_state(model, x, env, warm, cfg.v_desired) if rewarm else fixed
        (loss, aux), g = loss_and_grad(model, cfg, x, env, s, max_segments=max_segments)
        return loss, aux, g * (hi - lo)  # chain rule into box coordinates

    def falls(zz) -> bool:
        return not walks(model, lo + zz * (hi - lo), env, check_s, cfg.v_desired)

    res.fell_initial = falls(z) if check_s else None
    loss, aux, gz = evaluate(z)
    res.losses.append(float(loss))
    res.aux.append({n: float(v) for n, v in aux.items()})
    for k in range(steps):
        gz = jnp.where(jnp.isfinite(gz), gz, 0.0)
        res.grad_norms.append(float(optax.tree.norm(gz)))
        upd, new_state = opt.update(gz, opt_state, z)
        scale, z_new = 1.0, None
        for _ in range(max_halvings + 1):
            cand = jnp.clip(z + scale * upd, 0.0, 1.0)
            if not (safeguard and check_s and falls(cand)):
                z_new = cand
                break
            scale *= 0.5
        if z_new is None:
            res.rejected.append(k)
            if progress is not None:
                progress(f"step {k + 1}/{steps}: every trial step falls; stopping")
            break
        z, opt_state = z_new, new_state
        loss, aux, gz = evaluate(z)
        res.losses.append(float(loss))
        res.aux.append({n: float(v) for n, v in aux.items()})
        res.step_scales.append(scale)
        if progress is not None:
            progress(
                f"step {k + 1}/{steps}: loss {res.losses[-2]:.5g} -> {res.losses[-1]:.5g}, "
                f"|g| {res.grad_norms[-1]:.3g}, step scale {scale:g}"
            )
    res.params = np.asarray(lo + z * (hi - lo))
    if check_s:
        res.fell_final = falls(z)
    return res
