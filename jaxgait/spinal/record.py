"""Record the interneuron signals of a spinal-network rollout and analyse their variability
(thesis 6.4, 7.1.1; Fig. 7.1).

:func:`record` runs one preset on a network model (an FBL preset on ``fbl_net``: FBL
reorganised, every IN_SEN kept, pass-through links, so the gait is FBL's) and logs, every
``log_dt``, each IN's output (after control and gating: what it sends to its motoneuron),
its IN_SD gate and the stance of each leg.  :func:`analyse` cuts the signals at each leg's
touchdowns and computes the variability factors per IN and leg
(:func:`jaxgait.analysis.variability.variability`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import models
from jaxgait.analysis.variability import N_POINTS, Variability, cycle_starts, variability
from jaxgait.control.interneurons import IN_NAMES, IN_SEN
from jaxgait.presets import load_preset
from jaxgait.sim.model import SimConfig
from jaxgait.sim.step import initial_state, step
from jaxgait.world import envs

#: Sampling period of the recorded IN signals [s] (about 220 samples per 1.1 s cycle).
LOG_DT = 0.005


class SpinalError(ValueError):
    """Bad input to the spinal-network tools (preset, model, too short a walk)."""


@dataclass
class Record:
    """IN signals of one rollout (host arrays).

    Attributes:
      t: (T,) time [s]; out: (T, 2, K) IN outputs [stim]; gate: (T, 2, K) IN_SD gates;
      stance: (T, 2) bool; alive: (T,) bool; model: model name; vec: (28,) parameters;
      duration: simulated time before a fall or the end [s]; fell: bool; start: the
      preset's own start entries (``v0`` [m/s], ``pose``) the rollout used, if it has them.
    """

    t: np.ndarray
    out: np.ndarray
    gate: np.ndarray
    stance: np.ndarray
    alive: np.ndarray
    model: str
    vec: np.ndarray
    duration: float
    fell: bool
    start: dict = dataclasses.field(default_factory=dict)


def network_model_name(declared: str) -> str:
    """The network model a preset is recorded on: its own if it is a network, else the
    reorganised law of its table (``fbl_net`` for FBL's, ``fblplus_net`` for FBL+'s)."""
    m = models.get_model(declared)
    if getattr(m.controller.settings, "network", None) is not None:
        return declared
    nets = {"fbl": "fbl_net", "fblplus": "fblplus_net"}
    if m.table.name not in nets:
        raise SpinalError(
            f"model {declared!r} is not on FBL's or FBL+'s parameter table (no IN_SEN)"
        )
    return nets[m.table.name]


@functools.lru_cache(maxsize=8)
def _recorder(model, cfg: SimConfig):
    """The jitted recorder of one model object (a re-registered name is a new object)."""
    log_every = round(cfg.log_dt / model.dt)
    n_rows = math.ceil(cfg.duration / cfg.log_dt)

    def run(params, env):
        s0 = initial_state(model, params, env, cfg)

        def row(s, _):
            s = jax.lax.fori_loop(0, log_every, lambda i, s: step(model, cfg, params, env, s), s)
            return s, (s.t, s.ctrl.out, s.ctrl.gate, s.gait.stance, ~s.done)

        s, rows = jax.lax.scan(row, s0, None, length=n_rows)
        return rows, jnp.where(s.done, s.end_t, s.t), s.fell

    return jax.jit(run)


def record(
    preset, duration: float = 30.0, env: str = "flat", seed: int = 0, log_dt: float = LOG_DT
) -> Record:
    """Simulate ``preset`` (name, path or results folder) on its network model and log the
    IN signals every ``log_dt`` [s] for ``duration`` [s] in environment ``env``."""
    declared, vec, doc = load_preset(preset)
    name = network_model_name(declared)
    start = {k: doc[k] for k in ("v0", "pose", "dynamics") if k in doc}
    cfg = SimConfig(duration=float(duration), log_dt=float(log_dt), **start)
    e = envs.make_env(env, jax.random.PRNGKey(int(seed)))
    model = models.get_model(name)
    (t, out, gate, stance, alive), dur, fell = _recorder(model, cfg)(model.table.as_jnp(vec), e)
    h = lambda x: np.asarray(x)
    return Record(
        h(t), h(out), h(gate), h(stance), h(alive), name, vec, float(dur), bool(fell), start
    )


@dataclass
class Analysis:
    """Variability of every IN per leg, and the gait's cycle timing.

    Attributes:
      per_leg: {IN name: (right Variability, left Variability)}.
      stride_s: mean cycle duration over both legs [s].
      first_td: (2,) time of each leg's first touchdown [s].
      n_cycles: cycles analysed per leg.
    """

    per_leg: dict[str, tuple[Variability, Variability]]
    stride_s: float
    first_td: tuple[float, float]
    n_cycles: tuple[int, int]

    def factor(self, name: str, what: str) -> float:
        """Mean over the two legs of ``s``, ``v_mu`` or ``v_sigma`` of IN ``name``."""
        return float(np.mean([getattr(v, what) for v in self.per_leg[name]]))

    def table(self) -> list[dict]:
        """One row per IN: name, family, gate, target, s, v_mu, v_sigma (means over legs)."""
        rows = []
        for i in IN_SEN:
            rows.append(
                {
                    "name": i.name,
                    "family": i.family,
                    "gate": i.gate,
                    "replaceable": i.replaceable,
                    "s": self.factor(i.name, "s"),
                    "v_mu": self.factor(i.name, "v_mu"),
                    "v_sigma": self.factor(i.name, "v_sigma"),
                    "mean": float(np.mean([v.mean for v in self.per_leg[i.name]])),
                }
            )
        return rows


def analyse(rec: Record, skip: int = 2, n: int = N_POINTS) -> Analysis:
    """Cut each leg's IN signals at its touchdowns (after ``skip`` cycles) and compute the
    variability factors; :class:`SpinalError` if a leg has fewer than 3 cycles left."""
    alive = rec.alive
    t = rec.t[alive]
    per_leg: dict[str, list] = {nm: [] for nm in IN_NAMES}
    first, counts, durs = [], [], []
    for leg in (0, 1):
        starts = cycle_starts(rec.stance[alive, leg])
        if starts.size - skip < 4:
            raise SpinalError(
                f"{rec.model}: leg {leg} has {max(starts.size - 1, 0)} cycles in "
                f"{rec.duration:.1f} s ({'fell' if rec.fell else 'walked'}); need {skip + 3}"
            )
        first.append(float(t[starts[0]]))
        counts.append(int(starts.size - skip - 1))
        for k, nm in enumerate(IN_NAMES):
            v = variability(
                t,
                rec.out[alive, leg, k],
                starts,
                n=n,
                skip=skip,
                active=rec.gate[alive, leg, k] > 0.5,
            )
            per_leg[nm].append(v)
        durs.extend(per_leg[IN_NAMES[0]][-1].durations.tolist())
    return Analysis(
        per_leg={k: tuple(v) for k, v in per_leg.items()},
        stride_s=float(np.mean(durs)),
        first_td=(first[0], first[1]),
        n_cycles=(counts[0], counts[1]),
    )
