"""Robustness of a walking parameter set (thesis 3.2, Fig. 3.6; 7.2-7.3.1, Figs. 7.4-7.5).

Three measures, each over N seeded environment draws (mean +- SD over seeds; the SD is the
sample SD, ddof = 1, and 0 for a single seed):

(a) **Maximum push** [N] (thesis 3.2.2, Fig. 3.6 B, Fig. 7.4 middle): the largest push
    amplitude the walker recovers from.  Each seed fixes one push (start time uniform in the
    ``push`` environment's window [3, 8] s; duration, angle and height drawn from the
    ``random_push`` environment's distributions: gamma duration of mean 0.25 s, angle
    ~ N(0, pi/2) to the ground, height uniform over the trunk; or, with
    ``push_env="push"``, the ``push`` environment's fixed 0.25 s horizontal forward push at
    mid-trunk).  Only the amplitude F varies within a seed.  A trial *survives* if the walker
    did not fall before ``t0 + duration + after_push`` (it must also not fall before the
    push).  The search is a ladder over increasing amplitudes 0, dF, 2 dF, ... evaluated
    ``per_rung`` amplitudes at a time for all seeds in one ``vmap``-ed batch, followed by
    m-section refinement between the last surviving and the first failing amplitude.  The
    reported amplitude is the largest tested F such that **every** tested amplitude <= F
    survived (monotone per seed: a walker that survives all amplitudes up to F reports at
    least F; a failure is never skipped over).  Seeds still standing at ``push_max`` report
    ``push_max`` and are counted as censored.

(b) **Maximum slope change** [%] on wavy ground (thesis 3.2.3, Fig. 3.6 C, Fig. 7.4 right):
    environment 4 (thesis 2.2.4.2) as the thesis defines it: trapezoids whose equal up/down
    angles grow structure after structure towards alpha_max (here 20 % by default, twice the
    environment's 10 % default so a good walker does not run out of course), random
    lengths and gaps per seed.  The score is the grade 100 tan(alpha_i) of the last
    structure whose far end the centre of mass passed before the fall (0 if none).  A walker
    that does not fall within ``duration`` scores the last structure it passed, a lower
    bound, counted as censored.

(c) **Distance on the increasing slope** [m] (thesis 7.3.1, Fig. 7.5, without online
    control): environment 5 (grade 0 -> 30 % over 160 m), walked until the fall or
    ``duration``.  The terrain is deterministic, so without a perturbation every seed gives
    the same result (SD 0).  The seed variation comes from one small push per seed
    (``slope_jitter`` N, default 10 N, horizontal forward or backward at random, 0.25 s,
    mid-trunk, at a time uniform in [0.5, 2] s): a perturbation of the initial condition,
    not part of the thesis protocol.  The grade reached at the end is also reported
    (``slope_max_grade_pct``, the thesis's "maximum successfully managed slope").

The command line is :mod:`jaxgait.robustness`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.core.limits import LimitError, check_duration
from jaxgait.world import envs as envs_mod
from jaxgait.world.terrain import increasing_slope_grade, wavy_angles

TEST_CHOICES = ("push", "wavy", "slope")


@dataclass(frozen=True)
class RobustnessConfig:
    """Settings of the three robustness measures (module docstring).

    Attributes:
      seeds: number N of environment draws per measure.
      seed: base PRNG seed; draw i of measure m (0 push, 1 wavy, 2 slope) uses the key
        ``split(fold_in(PRNGKey(seed), m), N)[i]``.
      push_env: ``"random_push"`` (duration / angle / height drawn as in environment 3) or
        ``"push"`` (environment 2's fixed 0.25 s horizontal forward push at mid-trunk).
      push_t_min, push_t_max: window of the push start time [s] (the ``push``
        environment's defaults: after the gait has settled).
      after_push: T [s]: a trial survives if it does not fall before t0 + duration + T.
      push_step: ladder spacing dF [N].
      push_per_rung: amplitudes per seed evaluated in one batch (batch = seeds x this).
      push_max: largest amplitude tried [N]; seeds surviving it are censored.
      push_refine: m-section rounds after the ladder (each divides the bracket by
        push_per_rung + 1).
      push_max_duration: push durations are clipped to this [s] (gamma tail, P < 1e-3).
      push_duration: with ``push_env="push"``, the push's duration [s] (None: environment
        2's 0.25 s; e.g. 0.4 for Wang et al. 2012's 100 N, 0.4 s pushes).
      duration: maximal simulated time of the wavy-ground and slope walks [s].
      wavy_alpha_max: alpha_max of the wavy ground [rad] (default atan 0.20).
      slope_jitter: amplitude of the per-seed perturbation push on the slope [N].
      log_dt: trace period of the rollouts [s] (only the summary is used).
      v0: initial forward speed [m/s] of every rollout; None: the simulator's default
        (:attr:`jaxgait.sim.SimConfig.v0`).  The command passes the preset's ``v0`` entry,
        as ``evaluate`` does.
      pose: start posture (a key of :data:`jaxgait.sim.POSES`); None: Geyer's.  The command
        passes the preset's ``pose`` entry.
      dynamics: :attr:`jaxgait.sim.SimConfig.dynamics` of the rollouts; the command passes
        the preset's ``dynamics`` entry ("mjx" where it has none).
    """

    seeds: int = 5
    seed: int = 0
    push_env: str = "random_push"
    push_t_min: float = 3.0
    push_t_max: float = 8.0
    after_push: float = 5.0
    push_step: float = 20.0
    push_per_rung: int = 4
    push_max: float = 400.0
    push_refine: int = 1
    push_max_duration: float = 1.0
    push_duration: float | None = None
    duration: float = 60.0
    wavy_alpha_max: float = math.atan(0.20)
    slope_jitter: float = 10.0
    log_dt: float = 0.1
    v0: float | None = None
    pose: str | None = None
    dynamics: str = "mjx"

    def __post_init__(self):
        def need(ok, what):
            if not ok:
                raise ValueError(f"invalid robustness setting: {what}")

        need(isinstance(self.seeds, int) and self.seeds >= 1, f"seeds={self.seeds!r} (>= 1)")
        need(self.push_env in ("push", "random_push"), f"push_env={self.push_env!r}")
        need(
            0 <= self.push_t_min <= self.push_t_max,
            f"push window [{self.push_t_min}, {self.push_t_max}] s",
        )
        need(self.after_push > 0, f"after_push={self.after_push} (> 0 s)")
        need(self.push_max_duration > 0, f"push_max_duration={self.push_max_duration} (> 0 s)")
        need(
            self.push_duration is None
            or (self.push_env == "push" and 0 < self.push_duration <= self.push_max_duration),
            f"push_duration={self.push_duration} (push_env 'push' only, 0 < it <= "
            f"push_max_duration {self.push_max_duration} s)",
        )
        need(self.push_step > 0, f"push_step={self.push_step} (> 0 N)")
        need(self.push_per_rung >= 1, f"push_per_rung={self.push_per_rung} (>= 1)")
        need(self.push_max > 0, f"push_max={self.push_max} (> 0 N)")
        need(self.push_refine >= 0, f"push_refine={self.push_refine} (>= 0)")
        need(self.duration > 0, f"duration={self.duration} (> 0 s)")
        need(0 <= self.wavy_alpha_max < math.pi / 2, f"wavy_alpha_max={self.wavy_alpha_max}")
        need(self.slope_jitter >= 0, f"slope_jitter={self.slope_jitter} (>= 0 N)")
        need(
            self.v0 is None
            or (isinstance(self.v0, (int, float)) and not isinstance(self.v0, bool)
                and math.isfinite(self.v0)),
            f"v0={self.v0!r} (a finite speed [m/s] or None)",
        )  # fmt: skip
        if self.pose is not None:
            from jaxgait.sim.model import POSES

            need(self.pose in POSES, f"pose={self.pose!r} (one of {', '.join(sorted(POSES))})")
        from jaxgait.sim.model import DYNAMICS

        need(
            self.dynamics in DYNAMICS, f"dynamics={self.dynamics!r} (one of {', '.join(DYNAMICS)})"
        )
        try:
            check_duration(self.duration, what="duration of the slope walks")
            check_duration(
                self.push_t_max + self.push_max_duration + self.after_push,
                what="push trial (push window end + push duration + after_push)",
            )
        except LimitError as e:
            raise ValueError(f"invalid robustness setting: {e}") from None

    def keys(self, measure: str) -> jax.Array:
        """(N, 2) PRNG keys of one measure (``push``, ``wavy`` or ``slope``)."""
        base = jax.random.fold_in(jax.random.PRNGKey(self.seed), TEST_CHOICES.index(measure))
        return jax.random.split(base, self.seeds)


def mean_sd(x) -> tuple[float, float]:
    """(mean, sample SD with ddof = 1; 0 for one value)."""
    x = np.asarray(x, dtype=float)
    return float(np.mean(x)), float(np.std(x, ddof=1)) if x.size > 1 else 0.0


# ------------------------------------------------------------------------------ ladder search


@dataclass
class LadderResult:
    """Outcome of :func:`ladder_search` (per seed, NumPy).

    Attributes:
      best: (N,) reported amplitude: largest tested F with every tested amplitude <= F
        survived (0 when even F = 0 failed).
      first_fail: (N,) smallest tested amplitude that failed (inf if none).
      censored: (N,) bool, survived every amplitude up to ``max_amp``.
      fell_unpushed: (N,) bool, failed at F = 0.
      tested: list of (amps (N, m), survived (N, m)) batches in evaluation order.
    """

    best: np.ndarray
    first_fail: np.ndarray
    censored: np.ndarray
    fell_unpushed: np.ndarray
    tested: list


def _prefix_update(lo, hi, active, amps, ok):
    """Walk each active seed's amplitudes in increasing order: raise lo while they survive,
    set hi at the first failure.  Returns the new (lo, hi, still-bracketing mask)."""
    lo, hi = lo.copy(), hi.copy()
    failed = np.zeros_like(active)
    for i in np.flatnonzero(active):
        for a, s in sorted(zip(amps[i], ok[i], strict=True)):
            if not (a < hi[i]):
                break
            if s:
                lo[i] = max(lo[i], a) if np.isfinite(lo[i]) else a
            else:
                hi[i] = a
                failed[i] = True
                break
    return lo, hi, failed


def ladder_search(
    survive: Callable[[np.ndarray], np.ndarray],
    n_seeds: int,
    step: float,
    per_rung: int,
    max_amp: float,
    refine: int = 1,
) -> LadderResult:
    """Monotone largest-surviving-amplitude search, batched over seeds and amplitudes.

    Args:
      survive: maps amplitudes (n_seeds, per_rung) [N] to survived (n_seeds, per_rung) bool;
        row i is seed i.  Called with the same shape every time (one compilation).
      n_seeds: N.
      step: ladder spacing [N]; rung r tests (r per_rung + j) step, j < per_rung, from 0.
      per_rung: amplitudes per seed and call.
      max_amp: largest amplitude tested by the ladder [N].
      refine: rounds of m-section of the bracket (last survived, first failed).

    Returns:
      :class:`LadderResult`.  Per seed, ``best`` is the largest tested amplitude such that
      every tested amplitude <= best survived; the ladder stops for a seed at its first
      failure, so no failure below ``best`` is ever skipped.
    """
    lo = np.full(n_seeds, -np.inf)  # largest amplitude with all tested <= lo survived
    hi = np.full(n_seeds, np.inf)  # smallest failing amplitude
    alive = np.ones(n_seeds, bool)
    tested = []
    r = 0
    while alive.any() and r * per_rung * step <= max_amp:
        row = (r * per_rung + np.arange(per_rung)) * step
        row = np.where(row <= max_amp, row, max_amp)  # last rung: repeat the cap
        amps = np.tile(row, (n_seeds, 1))
        ok = np.asarray(survive(amps), bool).reshape(n_seeds, per_rung)
        tested.append((amps, ok))
        lo, hi, failed = _prefix_update(lo, hi, alive, amps, ok)
        alive &= ~failed
        r += 1
    censored = alive.copy()
    for _ in range(refine):
        active = np.isfinite(lo) & np.isfinite(hi)
        if not active.any():
            break
        frac = np.arange(1, per_rung + 1) / (per_rung + 1)
        span = np.where(active, hi - lo, 0.0)
        base = np.where(active, lo, 0.0)
        amps = base[:, None] + span[:, None] * frac[None, :]  # inactive rows: ignored
        ok = np.asarray(survive(amps), bool).reshape(n_seeds, per_rung)
        tested.append((amps, ok))
        lo, hi, _ = _prefix_update(lo, hi, active, amps, ok)
    fell_unpushed = ~np.isfinite(lo)
    best = np.where(fell_unpushed, 0.0, lo)
    return LadderResult(best, hi, censored, fell_unpushed, tested)


# ------------------------------------------------------------------------------ rollouts


@functools.lru_cache(maxsize=8)
def _summary_fn(model, cfg):
    """jit(vmap over environments) of the rollout -> (Summary, x0 of the CoM)."""
    from jaxgait import sim

    def one(params, env):
        _, _, summary, final = sim.rollout(model, cfg, params, env)
        return summary, final.x0

    return jax.jit(jax.vmap(one, in_axes=(None, 0)))


def _sim_cfg(duration: float, rcfg: RobustnessConfig):
    from jaxgait import sim

    start = {} if rcfg.v0 is None else {"v0": float(rcfg.v0)}
    if rcfg.pose is not None:
        start["pose"] = rcfg.pose
    start["dynamics"] = rcfg.dynamics
    return sim.SimConfig(duration=float(duration), log_dt=rcfg.log_dt, chunk_s=1.0, **start)


def push_base_envs(rcfg: RobustnessConfig, keys: jax.Array) -> envs_mod.Env:
    """(N,) flat-ground environments with one push of amplitude 0 in slot 0 (module doc)."""
    extra = {} if rcfg.push_duration is None else {"duration": float(rcfg.push_duration)}
    pcfg = envs_mod.get_env_config(
        "push", magnitude=0.0, t_min=rcfg.push_t_min, t_max=rcfg.push_t_max, **extra
    )
    base = envs_mod.make_env_batch(pcfg, keys)
    if rcfg.push_env == "random_push":
        rp = envs_mod.get_env_config("random_push")
        drawn = jax.vmap(rp.make_pushes)(jax.vmap(lambda k: jax.random.fold_in(k, 1))(keys))
        pushes = base.pushes
        base = base.replace(
            pushes=pushes.replace(
                duration=pushes.duration.at[:, 0].set(drawn.duration[:, 0]),
                angle=pushes.angle.at[:, 0].set(drawn.angle[:, 0]),
                height=pushes.height.at[:, 0].set(drawn.height[:, 0]),
            )
        )
    dur = jnp.minimum(base.pushes.duration, rcfg.push_max_duration)
    return base.replace(pushes=base.pushes.replace(duration=dur))


def with_amplitudes(base: envs_mod.Env, amps) -> envs_mod.Env:
    """(N m,) environments: seed i's environment with push amplitude amps[i, j] [N]."""
    amps = jnp.asarray(amps, base.pushes.magnitude.dtype)
    n, m = amps.shape
    rep = jax.tree.map(lambda x: jnp.repeat(x, m, axis=0), base)
    mag = rep.pushes.magnitude.at[:, 0].set(amps.reshape(n * m))
    return rep.replace(pushes=rep.pushes.replace(magnitude=mag))


def push_survived(summary, env: envs_mod.Env, after_push: float) -> np.ndarray:
    """True where the walker did not fall before t0 + duration + ``after_push`` (slot 0)."""
    t_end = env.pushes.t0[:, 0] + env.pushes.duration[:, 0] + after_push
    fell = np.asarray(summary.fell)
    return ~fell | (np.asarray(summary.duration) >= np.asarray(t_end))


def push_survive_fn(model, vec, rcfg: RobustnessConfig = RobustnessConfig()):
    """(survive, base envs): ``survive(amps (N, m)) -> (N, m) bool`` for the N push seeds.

    One batched rollout of N m trials per call, simulated for
    push_t_max + push_max_duration + after_push seconds (compiled once per batch shape).
    """
    base = push_base_envs(rcfg, rcfg.keys("push"))
    duration = rcfg.push_t_max + rcfg.push_max_duration + rcfg.after_push
    fn = _summary_fn(model, _sim_cfg(duration, rcfg))
    params = model.table.as_jnp(vec)

    def survive(amps):
        amps = np.asarray(amps, float)
        env = with_amplitudes(base, amps)
        summary, _ = fn(params, env)
        return push_survived(summary, env, rcfg.after_push).reshape(amps.shape)

    return survive, base


def max_push(model, vec, rcfg: RobustnessConfig = RobustnessConfig()) -> dict:
    """Largest push amplitude [N] recovered from, per seed (measure (a), module doc)."""
    survive, base = push_survive_fn(model, vec, rcfg)
    res = ladder_search(
        survive, rcfg.seeds, rcfg.push_step, rcfg.push_per_rung, rcfg.push_max, rcfg.push_refine
    )
    m, sd = mean_sd(res.best)
    return {
        "max_push_N": m,
        "max_push_N_sd": sd,
        "max_push_N_seeds": res.best.tolist(),
        "max_push_censored": int(res.censored.sum()),
        "max_push_fell_unpushed": int(res.fell_unpushed.sum()),
        "push_t0_s": np.asarray(base.pushes.t0[:, 0]).tolist(),
        "push_duration_s": np.asarray(base.pushes.duration[:, 0]).tolist(),
        "push_angle_rad": np.asarray(base.pushes.angle[:, 0]).tolist(),
        "push_batches": len(res.tested),
    }


def wavy_config(rcfg: RobustnessConfig) -> envs_mod.EnvConfig:
    """Environment 4 with alpha_max = ``rcfg.wavy_alpha_max`` (other fields default)."""
    return envs_mod.get_env_config("wavy", alpha_max=float(rcfg.wavy_alpha_max))


def slope_envs(rcfg: RobustnessConfig, keys: jax.Array) -> envs_mod.Env:
    """(N,) increasing-slope environments, each with its small perturbation push."""
    scfg = envs_mod.get_env_config("increasing_slope")
    env = envs_mod.make_env_batch(scfg, keys)
    u = jax.vmap(lambda k: jax.random.uniform(jax.random.fold_in(k, 2), (2,)))(keys)
    p = env.pushes
    pushes = p.replace(
        t0=p.t0.at[:, 0].set(0.5 + 1.5 * u[:, 0]),
        duration=p.duration.at[:, 0].set(0.25),
        magnitude=p.magnitude.at[:, 0].set(rcfg.slope_jitter),
        angle=p.angle.at[:, 0].set(jnp.where(u[:, 1] < 0.5, 0.0, jnp.pi)),
        height=p.height.at[:, 0].set(0.4),
    )
    return env.replace(pushes=pushes)


def wavy_score(env: envs_mod.Env, wcfg, x_end) -> tuple[np.ndarray, np.ndarray]:
    """(grade of the last structure passed [%], number of structures passed) per env."""
    n = wcfg.n_structures
    ends = np.asarray(env.terrain.xs)[:, 4 + 4 * np.arange(n)]  # far foot of each structure
    passed = (ends < np.asarray(x_end)[:, None]).sum(1)
    grades = 100.0 * np.tan(wavy_angles(wcfg))
    pct = np.where(passed > 0, grades[np.maximum(passed - 1, 0)], 0.0)
    return pct, passed


def walk_tests(model, vec, rcfg: RobustnessConfig = RobustnessConfig(), tests=("wavy", "slope")):
    """Measures (b) and (c): one batch of N wavy-ground and N increasing-slope walks."""
    tests = [t for t in ("wavy", "slope") if t in tests]
    if not tests:
        return {}
    wcfg = wavy_config(rcfg)
    batches = []
    if "wavy" in tests:
        batches.append(envs_mod.make_env_batch(wcfg, rcfg.keys("wavy")))
    if "slope" in tests:
        batches.append(slope_envs(rcfg, rcfg.keys("slope")))
    env = jax.tree.map(lambda *x: jnp.concatenate(x, 0), *batches)
    fn = _summary_fn(model, _sim_cfg(rcfg.duration, rcfg))
    summary, x0 = fn(model.table.as_jnp(vec), env)
    dist = np.asarray(summary.distance)
    fell = np.asarray(summary.fell)
    x_end = np.asarray(x0) + dist
    out = {}
    n = rcfg.seeds
    sl = {t: slice(i * n, (i + 1) * n) for i, t in enumerate(tests)}
    if "wavy" in sl:
        w = sl["wavy"]
        wenv = jax.tree.map(lambda x: x[w], env)
        pct, passed = wavy_score(wenv, wcfg, x_end[w])
        m, sd = mean_sd(pct)
        out.update(
            max_slope_pct=m,
            max_slope_pct_sd=sd,
            max_slope_pct_seeds=pct.tolist(),
            max_slope_censored=int((~fell[w]).sum()),
            wavy_structures_passed=passed.tolist(),
            wavy_distance_m=dist[w].tolist(),
        )
    if "slope" in sl:
        s = sl["slope"]
        scfg = envs_mod.get_env_config("increasing_slope")
        grade = 100.0 * np.asarray(increasing_slope_grade(scfg, x_end[s]))
        m, sd = mean_sd(dist[s])
        gm, gsd = mean_sd(grade)
        out.update(
            slope_distance_m=m,
            slope_distance_m_sd=sd,
            slope_distance_m_seeds=dist[s].tolist(),
            slope_max_grade_pct=gm,
            slope_max_grade_pct_sd=gsd,
            slope_censored=int((~fell[s]).sum()),
        )
    return out


def robustness(model, vec, rcfg: RobustnessConfig = RobustnessConfig(), tests=TEST_CHOICES):
    """All requested measures as one JSON-ready dict (see the module docstring)."""
    bad = sorted(set(tests) - set(TEST_CHOICES))
    if bad:
        raise ValueError(f"unknown robustness test(s) {bad}; valid: {', '.join(TEST_CHOICES)}")
    out = {"model": model.name, "seeds": rcfg.seeds, "settings": dataclasses.asdict(rcfg)}
    t = time.perf_counter()
    if "push" in tests:
        out.update(max_push(model, vec, rcfg))
    out.update(walk_tests(model, vec, rcfg, tests))
    out["wall_time_s"] = time.perf_counter() - t
    return out
