"""Training the automatic command law with CMA-ES (thesis 8.2's future work, issue: online control).

The law of :mod:`jaxgait.control.autopilot` has its gains as a parameter table with ranges
(:data:`~jaxgait.control.autopilot.AUTO_SPEED`).  :func:`tune` optimises a chosen subset of
them with CMA-ES (:class:`jaxgait.optim.CMAES`, evosax) on randomised tasks, the network and
its FBL parameters fixed:

* **speed tracking on flat ground** (or, with ``grade`` != 0, on ground that rises from level
  to that constant grade over ``grade_ramp_m`` metres, for a network trained to hold a
  grade): ``profiles`` random target profiles per generation
  (``segments`` segments of ``segment_s`` seconds, each target uniform in ``v_range``), the
  same profiles for every candidate of a generation (common random numbers), new ones every
  generation.  Cost of one rollout [m/s]: the RMS of v - v* over the settled samples (each
  segment after ``settle_s``; v the 1 s moving average of the CoM speed) that were walked,
  plus ``fall_penalty`` times the fraction of the profile lost to a fall;
* **the increasing slope** (environment ``increasing_slope``, 0 -> 30 % over 160 m), when
  ``slope_s`` > 0: one walk of ``slope_s`` seconds at the target ``slope_target``; cost
  ``slope_weight`` (1 - d / d_max) with d the distance walked and d_max the course length.

A candidate's fitness is the mean tracking cost over the profiles plus the slope cost
(lower is better).  :func:`evaluate_law` scores gains on profiles drawn from another seed
(held-out tasks), so the figures of a trained law are not those it was optimised on.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import asdict, dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import models, sim
from jaxgait.optim import CMAES
from jaxgait.presets import load_preset
from jaxgait.spinal.auto import moving_speed, profile_schedules
from jaxgait.spinal.record import SpinalError
from jaxgait.world import envs

#: log period of the tuning rollouts [s] (only the CoM path is used)
LOG_DT = 0.1


@dataclass(frozen=True)
class Tuning:
    """Tasks and optimiser settings of :func:`tune` (see the module docstring)."""

    tune: tuple[str, ...] = ("v_ref", "k_ff", "k_p", "k_i", "k_w", "tau_v")
    v_range: tuple[float, float] = (0.9, 1.5)
    segments: int = 3
    segment_s: float = 15.0
    settle_s: float = 5.0
    profiles: int = 3
    fall_penalty: float = 1.0
    slope_s: float = 0.0
    slope_target: float = 1.2
    slope_weight: float = 1.0
    grade: float = 0.0
    grade_ramp_m: float = 10.0
    popsize: int = 8
    generations: int = 10
    sigma: float = 0.1
    seed: int = 0

    def __post_init__(self):
        lo, hi = self.v_range
        if not 0 < lo <= hi:
            raise SpinalError(f"v_range must satisfy 0 < lo <= hi, got {self.v_range}")
        if self.segments < 1 or self.profiles < 1:
            raise SpinalError("segments and profiles must be >= 1")
        if not 0 <= self.settle_s < self.segment_s:
            raise SpinalError(f"need 0 <= settle_s < segment_s, got {self.settle_s}")
        if self.popsize < 2 or self.generations < 0:
            raise SpinalError("popsize must be >= 2 and generations >= 0")
        if not -0.5 <= self.grade <= 0.5 or self.grade_ramp_m <= 0:
            raise SpinalError(
                f"need a grade in [-0.5, 0.5] and a ramp > 0 m, got {self.grade}, "
                f"{self.grade_ramp_m}"
            )
        if self.slope_s < 0 or self.sigma <= 0:
            raise SpinalError("slope_s must be >= 0 and sigma > 0")
        if not self.tune:
            raise SpinalError("nothing to tune: name at least one gain")


def expand_names(requested, names) -> tuple[str, ...]:
    """The table entries to train: each requested name, or every entry starting with a
    prefix given as ``PREFIX*`` (``net_*``: every network parameter of a table with
    ``network_in_table``), in table order, without repeats."""
    out = []
    for r in requested:
        hit = [n for n in names if n.startswith(r[:-1])] if r.endswith("*") else [r]
        if not hit or hit[0] not in names:
            raise SpinalError(f"unknown gains {r!r}; the table's entries are {list(names)}")
        out += [n for n in hit if n not in out]
    return tuple(sorted(out, key=names.index))


def random_profiles(key, n: int, tcfg: Tuning) -> np.ndarray:
    """(n, segments) target speeds [m/s], uniform in ``v_range``."""
    lo, hi = tcfg.v_range
    return np.asarray(jax.random.uniform(key, (n, tcfg.segments), minval=lo, maxval=hi), float)


def tracking_cost(t, x, alive, profiles, tcfg: Tuning) -> tuple[np.ndarray, np.ndarray]:
    """Per rollout (cost [m/s], RMS error over the settled walked samples [m/s]).

    t, x, alive: (B, T) trace time, CoM x and alive flag; profiles: (B, segments)."""
    t = np.asarray(t, float)
    v = moving_speed(t, x, LOG_DT)
    alive = np.asarray(alive, bool)
    seg = np.minimum((t // tcfg.segment_s).astype(int), tcfg.segments - 1)
    target = np.take_along_axis(np.asarray(profiles, float), seg, axis=-1)
    settled = (t - seg * tcfg.segment_s) >= tcfg.settle_s
    ok = settled & alive & np.isfinite(v)
    err2 = np.where(ok, (v - target) ** 2, 0.0)
    n = ok.sum(-1)
    rms = np.where(n > 0, np.sqrt(err2.sum(-1) / np.maximum(n, 1)), tcfg.v_range[1])
    total = tcfg.segments * tcfg.segment_s
    walked = np.where(alive, t, 0.0).max(-1)
    lost = np.clip(1.0 - walked / total, 0.0, 1.0)
    lost = np.where(alive[..., -1], 0.0, lost)
    return rms + tcfg.fall_penalty * lost, rms


@functools.lru_cache(maxsize=8)
def _rollout(model, cfg: sim.SimConfig):
    return sim.make_rollout(model, cfg, batched=True)


class Tasks:
    """The compiled rollouts and fixed data of one tuning problem."""

    def __init__(self, preset, tcfg: Tuning):
        name, vec, doc = load_preset(preset)
        self.model = models.get_model(name)
        if "v_target" not in self.model.controller.command_names:
            raise SpinalError(f"{preset}: model {name!r} has no v_target command to train")
        table = self.model.table
        self.names = expand_names(tcfg.tune, table.names)
        self.preset, self.doc, self.base = preset, doc, np.asarray(vec, float)
        self.tcfg = tcfg
        self.idx = np.array([table.names.index(n) for n in self.names])
        self.lower = np.asarray(table.lower, float)[self.idx]
        self.upper = np.asarray(table.upper, float)[self.idx]
        v0 = float(doc.get("v0", sim.SimConfig.v0))
        total = tcfg.segments * tcfg.segment_s
        self.track_cfg = sim.SimConfig(duration=total, log_dt=LOG_DT, v0=v0, max_events=1024)
        if tcfg.grade == 0:
            self.track_env = envs.make_env("flat", jax.random.PRNGKey(0))
        else:
            gcfg = envs.get_env_config(
                "increasing_slope", final_grade=tcfg.grade, length=tcfg.grade_ramp_m
            )
            self.track_env = envs.make_env(gcfg, jax.random.PRNGKey(0))
        if tcfg.slope_s > 0:
            self.slope_cfg = sim.SimConfig(
                duration=tcfg.slope_s, log_dt=LOG_DT, v0=v0, max_events=1024
            )
            scfg = envs.get_env_config("increasing_slope")
            self.slope_env = envs.make_env(scfg, jax.random.PRNGKey(0))
            self.course_m = float(scfg.length)

    def full(self, z: np.ndarray) -> np.ndarray:
        """(P, D) table vectors from (P, n_tuned) tuned values."""
        out = np.tile(self.base, (z.shape[0], 1))
        out[:, self.idx] = z
        return out

    def costs(self, z: np.ndarray, profiles: np.ndarray) -> dict:
        """Per candidate of (P, n_tuned): fitness, tracking cost, RMS, slope distance."""
        tc = self.tcfg
        P, R = z.shape[0], profiles.shape[0]
        vecs = self.full(np.asarray(z, float))
        cmds = self.model.controller.commands
        dtype = jnp.float32
        p_rep = jnp.asarray(np.repeat(vecs, R, 0), dtype)
        sched = profile_schedules(cmds, np.tile(profiles, (P, 1)), tc.segment_s)
        env_b = jax.tree.map(lambda a: jnp.broadcast_to(a, (P * R, *jnp.shape(a))), self.track_env)
        tr, _, sm, _ = _rollout(self.model, self.track_cfg)(p_rep, env_b, sched)
        cost, rms = tracking_cost(
            np.asarray(tr.t),
            np.asarray(tr.com)[..., 0],
            np.asarray(tr.alive),
            np.tile(profiles, (P, 1)),
            tc,
        )
        cost, rms = cost.reshape(P, R), rms.reshape(P, R)
        fit = cost.mean(1)
        out = {"fitness": fit, "tracking": cost, "rms": rms}
        if tc.slope_s > 0:
            s_sched = profile_schedules(cmds, np.full((P, 1), tc.slope_target), tc.slope_s)
            env_s = jax.tree.map(lambda a: jnp.broadcast_to(a, (P, *jnp.shape(a))), self.slope_env)
            _, _, ss, _ = _rollout(self.model, self.slope_cfg)(
                jnp.asarray(vecs, dtype), env_s, s_sched
            )
            d = np.asarray(ss.distance, float)
            out["slope_distance_m"] = d
            out["fitness"] = fit + tc.slope_weight * np.clip(1.0 - d / self.course_m, 0, 1)
        return out


def tune(preset, tcfg: Tuning = Tuning(), log=print) -> dict:
    """CMA-ES on the gains ``tcfg.tune`` (names, or ``PREFIX*`` for every entry with that
    prefix) of a ``v_target`` model; returns the history, the
    best gains (by fitness; the last generation's mean is also scored) and a preset doc."""
    tasks = Tasks(preset, tcfg)
    opt = CMAES(popsize=tcfg.popsize, sigma_init=tcfg.sigma)
    key = jax.random.PRNGKey(tcfg.seed)
    key, k0 = jax.random.split(key)
    z0 = tasks.base[tasks.idx]
    state = opt.init(k0, (jnp.asarray(tasks.lower), jnp.asarray(tasks.upper)), jnp.asarray(z0))
    history = []
    best_z, best_f = z0.copy(), math.inf
    for g in range(tcfg.generations + 1):
        key, ka, kp = jax.random.split(key, 3)
        profiles = random_profiles(kp, tcfg.profiles, tcfg)
        if g == 0:  # the starting gains first, as a baseline on the same kind of tasks
            z = z0[None]
        else:
            zj, state = opt.ask(ka, state)
            z = np.asarray(zj, float)
        t0 = time.perf_counter()
        res = tasks.costs(z, profiles)
        fit = res["fitness"]
        if g > 0:
            state = opt.tell(state, jnp.asarray(z), jnp.asarray(fit))
        i = int(np.argmin(fit))
        if fit[i] < best_f:
            best_f, best_z = float(fit[i]), z[i].copy()
        row = {
            "generation": g,
            "best": float(fit[i]),
            "mean": float(np.mean(fit)),
            "rms_best": float(np.mean(res["rms"][i])),
            "best_so_far": best_f,
            "seconds": time.perf_counter() - t0,
        }
        if "slope_distance_m" in res:
            row["slope_distance_best_m"] = float(res["slope_distance_m"][i])
        history.append(row)
        log(
            f"gen {g}/{tcfg.generations}: best {row['best']:.4f} mean {row['mean']:.4f} "
            f"(rms {row['rms_best']:.3f} m/s) best so far {best_f:.4f} [{row['seconds']:.0f} s]"
        )
    # Each generation met new tasks, so the best single score is partly luck: the start, the
    # best candidate and the final mean are scored again on one fixed validation set.
    pick = {"start": z0, "best": best_z, "mean": np.asarray(opt.mean(state), float)}
    val_profiles = random_profiles(jax.random.PRNGKey(tcfg.seed + 500), 2 * tcfg.profiles, tcfg)
    val = tasks.costs(np.stack(list(pick.values())), val_profiles)["fitness"]
    choice = list(pick)[int(np.argmin(val))]
    log(
        "validation: "
        + ", ".join(f"{k} {v:.4f}" for k, v in zip(pick, val, strict=True))
        + f" -> {choice}"
    )
    z_final = pick[choice]
    gains = dict(
        zip(tasks.model.table.names, map(float, tasks.full(z_final[None])[0]), strict=True)
    )
    doc = dict(tasks.doc)
    doc["params"] = gains
    doc["tuning"] = {
        **asdict(tcfg),
        "validation": dict(zip(pick, map(float, val), strict=True)),
        "chosen": choice,
        "source": str(preset),
    }
    return {"history": history, "gains": gains, "tuned": list(tasks.names), "preset": doc}


def evaluate_law(preset, tcfg: Tuning, n_profiles: int = 8, seed: int = 1000) -> dict:
    """Score a preset's gains on ``n_profiles`` held-out profiles (another seed) and, with
    ``tcfg.slope_s`` > 0, on the increasing slope."""
    tasks = Tasks(preset, tcfg)
    profiles = random_profiles(jax.random.PRNGKey(seed), n_profiles, tcfg)
    z = np.tile(tasks.base[tasks.idx], (1, 1))
    res = tasks.costs(z, profiles)
    out = {
        "profiles": profiles.tolist(),
        "rms_mps": res["rms"][0].tolist(),
        "tracking_cost": res["tracking"][0].tolist(),
        "rms_mean_mps": float(np.mean(res["rms"][0])),
        "fitness": float(res["fitness"][0]),
    }
    if "slope_distance_m" in res:
        out["slope_distance_m"] = float(res["slope_distance_m"][0])
    return out
