"""Registry of optimisation experiments (thesis Table 3.1, ch. 3; SPEC §5).

Every experiment is a small frozen :class:`Experiment` config. ``get_experiment(name,
**overrides)`` returns a copy with fields replaced and checked; :func:`list_experiments`
describes them all. :func:`jaxgait.train.train` runs one.

=================  =======  ===============  =========  ===============================  =====
name               model    environment      optimiser  objective                        k
=================  =======  ===============  =========  ===============================  =====
``exp1``           FBL      flat [1]         stage PSO  (d, C_speed, -E)                 1
``exp2``           FBL      flat             stage PSO  (d, C_speed, C_steplengths, -E)  1
``exp3``           FBL      flat             stage PSO  (d, C_speed, C_steplengths,      1
                                                        C_angles, -E)
``exp4``           FBL      flat             PSO        d - aE + bC_angles + cC_steplen.  1
                                                        + dC_speed (eq. 2.55 + 2.56)
``exp5``           FBL+     flat             stage PSO  exp2 stages, v* = 2.5 m/s        1
``fblplus_run``    FBL+     flat             CMA-ES     quickstart's at 2.5 m/s + 20 x   1
                                                        (flight - double stance)
``exp5_table``     FBL+     push [2]         stage PSO  (d, C_trunk, C_speed, C_angles,  1
                                                        C_cot), v* = 2.5 m/s
``exp6a`` / ``b``  FBL/+    random push [3]  stage PSO  (d, C_trunk, C_speed, C_angles,  5
                                                        C_cot), d > 10 m opens stage 1
``exp7a`` / ``b``  FBL/+    wavy [4]         stage PSO  as exp6                          5
``fbl_humanlike``  FBL      flat             stage PSO  exp3's + angles 0.9, GRF peak    1
                                                        <= 1.3 BW, GRF corr 0.9
``exp3_cmaes``     FBL      flat             CMA-ES     exp3 stages (rank key)           1
``exp7a_cmaes``    FBL      wavy             CMA-ES     exp7 stages (rank key)           5
``quickstart``     FBL      flat             CMA-ES     d + 20 upright + 10 C_speed      1
                                                        + 20 upright C_speed, 16 x 40,
                                                        20 s, from the Geyer-Herr gains
``wang_walk_*``    wang8    flat             CMA-ES     quickstart's + 10 C_trunk        1
                                                        - 0.004/m J_effort, 50 x 40-80
=================  =======  ===============  =========  ===============================  =====

Common settings (thesis ch. 3): v* = 1.3 m/s, 60 particles x 150 iterations, d_lim = 35 m on
flat ground and 120 m on the perturbed environments, entrance conditions of Table 2.8 (see
:mod:`jaxgait.train.objective`). Choices made here where the thesis is silent:

* Time limit (``duration``): 60 s for d_lim = 35 m (a 1.3 m/s gait needs 27 s, thesis 2.2.2
  asks t_lim > 23 s) and 120 s for d_lim = 120 m (92 s at 1.3 m/s).
* exp4 weights (thesis 2.2.1.1: weights of decreasing orders of magnitude, values not given):
  distance 1, C_speed 1 [s/m], C_steplengths 0.1, C_angles 0.1, energy 1e-5 [1/J].
* Robust experiments exp6 use worst of 5 like exp7 (thesis 3.2 evaluates "each particle 5
  times" on both perturbed environments).
* exp5 follows the thesis text (flat ground, exp2's stages, v* = 2.5 m/s, SPEC §8);
  ``exp5_table`` keeps Table 3.1's environment 2 and stage list.
* quickstart (the main job, ``./jg train``): starts from the Geyer-Herr gains (the table's
  initial values), which fall after 1.7 s.  While the rollouts fall, F = d + 10 C_speed:
  walking further at a speed near v*.  A rollout that walks the whole 20 s gains 20
  (``upright``) and its speed error counts 30 times (``speed`` + ``upright_speed``), more
  than d = v t rewards speed (20 m per m/s), so the optimum is a 20 s walk at v*.  16
  candidates are one direct call (no lane queue), so the iterations, the final evaluation
  and the perturbation check share one compiled rollout.  A candidate that walks the 20 s
  becomes the best only if it and 8 copies perturbed by 1e-6 stay up in the final
  evaluation's batch (``confirm_best``: a walk that owes nothing to rounding).  The run stops
  at the first iteration whose best walks the 20 s within 0.05 m/s of v* (``stop_speed_tol``);
  the 40 iterations are a cap.
* fbl_humanlike_cmaes: the human-likeness goals of ``fbl_humanlike`` as one weighted sum for
  CMA-ES (16 x 60, 20 s rollouts, sigma 0.05 of the ranges, from ``fbl_walk``): quickstart's
  walk terms, which dominate, plus 10 ``grf_peak`` (per BW of stance peak above 1.3 BW),
  10 ``grf_corr``, 5 ``corr_hip``, 5 ``corr_knee``, 10 ``corr_ankle`` and 0.02
  ``energy_per_m`` (per J/m).  A cheaper search than the stage PSO (exp3's full-size run never
  left its angles stage, the ankle being the weakest joint).
* fbl_ankle_humanlike: the same search on the ``fbl_ankle`` model
  (:mod:`jaxgait.control.fblankle`: a swing drive of SOL and GAS apart from their stance
  S0, and TA damping of the foot's plantarflexion in stance), from ``fbl_ankle_walk``
  (``fbl_humanlike`` with the extras neutral, the same gait).
* fblplus_humanlike: the same search on FBL+ (16 x 350, sigma 0.05), whose swing-end PD
  rules (thesis 2.1.3: VAS towards a knee target, HFL/GLU towards a hip target once the
  swing foot is ahead of the CoM) extend the knee before landing; GRF-peak weight 30, energy
  0.04 per J/m and 10 x -(Wang's standard score), from ``fblplus_humanlike_start``
  (``fbl_humanlike`` lifted to FBL+ with a gentle VAS swing-end PD).  The shipped preset
  ``fblplus_humanlike`` is its best continued in two more stages: 150 iterations with the
  energy weight 0.1, then 450 with 0.3 and the mean cycle's correlations held above 0.915
  (``corr_floor``; experiments/humanlike/README.md).
* fblplus_run: exp5's stages (thesis 3.3.1) found a fast walk (2.37 m/s over 60 s, double
  stance 0.11 of the time, no flight: experiments/full/exp5, shipped as ``fblplus_fastwalk``),
  because nothing in them asks for flight.  This CMA-ES search (16 x 150, 20 s rollouts,
  sigma 0.05 of the ranges) starts from that walk at v0 = v* = 2.5 m/s and adds two running
  task terms to quickstart's: 20 x (-double-stance fraction) (Wang's) and 20 x flight
  fraction (neither foot on the ground), each 0 for a rollout that falls.  It too found a
  fast walk (2.24 m/s, double stance 0.17); the attempts are in ``experiments/running``.
* wang_walk_1p25 / 1p0 / 1p5 / 1p75 (Wang et al. 2012 section 6: nwalk, swalk, fwalk,
  vwalk): CMA-ES with Wang's population 50 on the 8-muscle controller; nwalk starts from the
  table's initial values (the Geyer-Herr gains extended to RF, SI and SP), swalk and fwalk
  from nwalk, vwalk from fwalk (Wang starts each from a neighbouring speed's solution);
  each starts at its target speed (Wang: 1.3 m/s for walking).
  Wang's return R = sum of task terms - w_e J_effort is maximised as F = d + 20 upright +
  10 C_speed + 20 upright C_speed + 10 C_trunk + C_effort: the task terms (a target CoM speed,
  not falling over the rollout -- 20 s here, Wang's 10 s walked 60 s less reliably --, the
  upper body in the lean band) dominate, C_effort = -(0.004 / mass) J_effort (J_effort =
  100 J_M + 0.5 J_L, J_M with Wang's metabolic model and basal rate; J_R = 0 in the planar
  model) is his term as he weighs it.  Wang's sigma 0.005 is for his normalised parameters;
  here sigma is 0.1 of each range.
* wang_run_3p0 / 4p0 / 5p0 (Wang section 6, running): the same search at v* = 3, 4, 5 m/s
  plus 20 x (-double-stance fraction); as Wang, 3 m/s starts from the preset
  ``wang_run_start`` (the table's Geyer-Herr values with the GAS and SOL force-feedback gains
  doubled) at v0 = 3.05 m/s, and each faster one from the slower one's solution (on
  ``wang8_run``, the running ranges the shipped ``wang_run_3p0`` needs).
* wang_push_walk_1p25, wang_push_run_4p0 (Wang section 6): nwalk and the 4 m/s runner
  re-optimised on environment 2 with one 100 N (50 N for running), 0.4 s forward push on the
  trunk at a random time in 3-8 s, the worst of 4 push times kept (a push at any phase).
* Start: the thesis starts from a walking gait (2.2.2.1), here the ``fbl_walk`` preset
  (``fblplus_walk``, the same gait with neutral FBL+ extras, for the FBL+ experiments);
  ``init = None`` starts PSO uniformly in the ranges (CMA-ES at the box centre), ``"table"``
  at the parameter table's initial values (Geyer's gains).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from jaxgait import models
from jaxgait.analysis.refdata import GAIT_REFERENCES
from jaxgait.core.limits import LimitError, check_distance, check_duration
from jaxgait.sim.model import DYNAMICS, POSES

#: Optimisers (keys of :data:`jaxgait.optim.STRATEGIES`).
OPTIMISERS = ("pso", "stage_pso", "cmaes")
#: Version of the config format written to JSON (bump when fields change meaning).
CONFIG_FORMAT = 1


class ExperimentError(ValueError):
    """Unknown experiment, unknown field or invalid value; the message lists valid choices."""


def _pairs(x: Any, what: str) -> tuple[tuple[str, Any], ...]:
    """Mapping or sequence of pairs -> tuple of (str, value) pairs (order kept)."""
    if x is None:
        return ()
    if isinstance(x, Mapping):
        items = list(x.items())
    else:
        try:
            items = [tuple(p) for p in x]
        except TypeError:
            raise ExperimentError(
                f"{what} must be a mapping or a list of pairs, got {x!r}"
            ) from None
    out = []
    for p in items:
        if len(p) != 2 or not isinstance(p[0], str):
            raise ExperimentError(f"{what}: entries must be (name, value) pairs, got {p!r}")
        out.append((p[0], p[1]))
    return tuple(out)


def _number(name: str, v: Any, rule: str, ok) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ExperimentError(f"invalid {name}={v!r}: must be a number {rule}")
    if not ok(float(v)):
        raise ExperimentError(f"invalid {name}={v!r}: must be {rule}")
    return float(v)


def _integer(name: str, v: Any, lo: int) -> int:
    whole = isinstance(v, int) or (isinstance(v, float) and v.is_integer())
    if isinstance(v, bool) or not whole or int(v) < lo:
        raise ExperimentError(f"invalid {name}={v!r}: must be an integer >= {lo}")
    return int(v)


@dataclass(frozen=True)
class Experiment:
    """One optimisation experiment (a plain, frozen config; JSON via :meth:`to_dict`).

    Attributes:
      name: registry name (also the default results folder ``runs/<name>``).
      description: one line.
      model: planar model of the registry (``fbl``, ``fblplus``, ...; :mod:`jaxgait.models`
        when the experiment is run).
      env: environment name (:data:`jaxgait.world.envs.ENVIRONMENTS`).
      env_overrides: ((field, value), ...) replaced in the environment config.
      optimiser: ``stage_pso``, ``pso`` or ``cmaes``.
      optimiser_options: ((name, value), ...) hyper-parameters (e.g. ``sigma_init`` for CMA-ES,
        ``init_spread`` for PSO).
      stages: ((criterion, entrance threshold or None), ...) for a stage objective.
      weights: ((criterion, weight), ...) for a weighted (scalar) objective.
      targets: ((name, value), ...), e.g. v_desired [m/s], sl_desired [m].
      d_lim: distance stopping criterion [m] (inf = none).
      duration: time limit of a rollout [s].
      worst_of_k: environments per parameter set per iteration; the worst score is kept.
      particles: population size.
      iterations: number of iterations (generations).
      init: start: a preset name/path, ``"table"`` (table initial values) or None (uniform in
        the ranges for PSO, box centre for CMA-ES).
      seed: seed of every random draw of the run (initial swarm, environments, moves).
      stage_cap: stage PSO only: a particle at stage N reaches stage N+1 at most per iteration
        (thesis 2.2.1.2).
      v0: initial forward speed of the body [m/s].
      pose: initial posture, a key of :data:`jaxgait.sim.model.POSES` (Geyer's walking
        start by default).  Written to the config and the best preset only when not the
        default, so configs written before it existed still match.
      batch_size: rollouts per device call (None: the whole population x k at once).
      lanes: a number: the rollouts of an iteration are queued and run over this many lanes
        per device, a lane taking the next rollout as soon as its own ended
        (:mod:`jaxgait.sim.lanes`); 0: direct calls of ``batch_size`` rollouts side by side;
        None (default): automatic, a queue over
        :data:`~jaxgait.train.evaluator.CPU_AUTO_LANES` lanes per CPU device when more than
        ``CPU_AUTO_QUEUE_ABOVE`` rollouts fall to a device and no ``batch_size`` is set, else direct
        calls (accelerators run wide batches at full speed).
      stop_speed_tol: early stop [m/s]: the run ends (complete) after the first iteration
        whose best rollout walked the whole ``duration`` without falling at a mean speed
        within this of ``v_desired``; None (default): every iteration runs.  Written to the
        config only when set, so configs written before it existed still match.
      confirm_best: a candidate whose rollout lasted the whole ``duration`` without falling
        becomes the run's best only if it and its copies perturbed by 1e-6 (relative) all
        stay up in the final evaluation's batch (:func:`jaxgait.train.results.confirm_walk`),
        so the best is not a gait that walks by the grace of float32 rounding; one extra
        call per such candidate.  Written to the config only when true.
      reference: the human gait the correlation and standard-score criteria (and
        ``grf_corr``) compare with: ``"walking"`` (Winter, the default) or ``"running"``
        (Fukuchi 3.5 m/s; :func:`jaxgait.analysis.refdata.gait_reference`).
        Written to the config only when not walking.
      dynamics: the rollouts' :attr:`jaxgait.sim.SimConfig.dynamics`: ``"planar"`` (the
        default for new runs: the planar tree's equations of motion, 1.5x faster a step at
        the queue's widths) or ``"mjx"`` (MJX's passes).  Written to the config and the
        best preset only when ``"planar"``: a config or preset without it ran ``"mjx"``
        (every one written before the field existed), and resumes and evaluates with it.
    """

    name: str
    description: str = ""
    model: str = "fbl"
    env: str = "flat"
    env_overrides: tuple = ()
    optimiser: str = "stage_pso"
    optimiser_options: tuple = ()
    stages: tuple = ()
    weights: tuple = ()
    targets: tuple = (("v_desired", 1.3),)
    d_lim: float = 35.0
    duration: float = 60.0
    worst_of_k: int = 1
    particles: int = 60
    iterations: int = 150
    init: str | None = "fbl_walk"
    seed: int = 0
    stage_cap: bool = True
    v0: float = 1.3
    pose: str = "geyer"
    batch_size: int | None = None
    lanes: int | None = None
    stop_speed_tol: float | None = None
    confirm_best: bool = False
    reference: str = "walking"
    dynamics: str = "planar"

    def __post_init__(self):
        s = lambda k, v: object.__setattr__(self, k, v)
        if not isinstance(self.name, str) or not self.name:
            raise ExperimentError(f"invalid name={self.name!r}: must be a non-empty string")
        if not isinstance(self.description, str):
            raise ExperimentError("description must be a string")
        if not _known_model(self.model, self.init):
            raise ExperimentError(
                f"invalid model={self.model!r}; valid models: "
                f"{', '.join(models.model_names('planar'))}"
            )
        if self.optimiser not in OPTIMISERS:
            raise ExperimentError(
                f"invalid optimiser={self.optimiser!r}; valid optimisers: {', '.join(OPTIMISERS)}"
            )
        s("env_overrides", _pairs(self.env_overrides, "env_overrides"))
        s("optimiser_options", _pairs(self.optimiser_options, "optimiser_options"))
        s(
            "targets",
            tuple(
                (k, _number(f"targets.{k}", v, "", math.isfinite))
                for k, v in _pairs(self.targets, "targets")
            ),
        )
        s(
            "weights",
            tuple(
                (k, _number(f"weights.{k}", v, "", math.isfinite))
                for k, v in _pairs(self.weights, "weights")
            ),
        )
        stages = []
        for e in self.stages if self.stages is not None else ():
            e = (e, None) if isinstance(e, str) else tuple(e)
            if len(e) != 2 or not isinstance(e[0], str):
                raise ExperimentError(
                    f"stages: entries must be (criterion, threshold|None), got {e!r}"
                )
            thr = None if e[1] is None else _number("stage threshold", e[1], "", math.isfinite)
            stages.append((e[0], thr))
        s("stages", tuple(stages))
        s("d_lim", _number("d_lim", self.d_lim, "> 0 (inf for none)", lambda v: v > 0))
        s(
            "duration",
            _number("duration", self.duration, "> 0 and finite", lambda v: 0 < v < math.inf),
        )
        try:
            check_distance(self.d_lim, "d_lim")
            check_duration(self.duration, what="duration")
        except LimitError as e:
            raise ExperimentError(str(e)) from None
        s("v0", _number("v0", self.v0, "finite", math.isfinite))
        if self.pose not in POSES:
            raise ExperimentError(
                f"invalid pose={self.pose!r}: must be one of {', '.join(sorted(POSES))}"
            )
        if self.dynamics not in DYNAMICS:
            raise ExperimentError(
                f"invalid dynamics={self.dynamics!r}: must be one of {', '.join(DYNAMICS)}"
            )
        if self.reference not in GAIT_REFERENCES:
            raise ExperimentError(
                f"invalid reference={self.reference!r}: must be one of {', '.join(GAIT_REFERENCES)}"
            )
        s("worst_of_k", _integer("worst_of_k", self.worst_of_k, 1))
        s("particles", _integer("particles", self.particles, 2))
        s("iterations", _integer("iterations", self.iterations, 1))
        s("seed", _integer("seed", self.seed, 0))
        if self.batch_size is not None:
            s("batch_size", _integer("batch_size", self.batch_size, 1))
        if self.lanes is not None:
            s("lanes", _integer("lanes", self.lanes, 0))
        if self.stop_speed_tol is not None:
            tol = self.stop_speed_tol
            rule = ">= 0 [m/s] (null: no early stop)"
            s("stop_speed_tol", _number("stop_speed_tol", tol, rule, lambda v: 0 <= v < math.inf))
            if "v_desired" not in dict(self.targets):
                raise ExperimentError(
                    f"invalid stop_speed_tol={tol!r}: the early stop needs targets.v_desired"
                )
        if not isinstance(self.confirm_best, bool):
            raise ExperimentError(
                f"invalid confirm_best={self.confirm_best!r}: must be true or false"
            )
        if not isinstance(self.stage_cap, bool):
            raise ExperimentError(f"invalid stage_cap={self.stage_cap!r}: must be true or false")
        if self.init is not None and (not isinstance(self.init, str) or not self.init):
            raise ExperimentError(
                f"invalid init={self.init!r}: a preset name/path, 'table' or null"
            )
        self._check_deep()

    def _check_deep(self) -> None:
        """Check names against the environment, criteria and optimiser registries."""
        from jaxgait.train import objective as obj
        from jaxgait.world.envs import ENVIRONMENTS, get_env_config

        if self.env not in ENVIRONMENTS:
            raise ExperimentError(
                f"invalid env={self.env!r}; valid environments: {', '.join(ENVIRONMENTS)}"
            )
        try:
            get_env_config(self.env, **dict(self.env_overrides))
        except (ValueError, TypeError) as e:
            raise ExperimentError(f"env_overrides: {e}") from None
        try:
            self.objective()
        except obj.ObjectiveError as e:
            raise ExperimentError(f"experiment {self.name!r}: {e}") from None
        try:
            self.strategy()
        except (ValueError, TypeError) as e:
            raise ExperimentError(f"optimiser_options for {self.optimiser}: {e}") from None

    # ------------------------------------------------------------------ builders
    def objective(self):
        """The :class:`~jaxgait.train.objective.StageObjective` or ``WeightedObjective``."""
        from jaxgait.train.objective import make_objective

        return make_objective(
            stages=self.stages or None,
            weights=self.weights or None,
            targets=dict(self.targets),
            d_lim=self.d_lim,
        )

    def strategy(self):
        """The optimiser (:func:`jaxgait.optim.make_strategy`) with ``particles`` candidates."""
        from jaxgait.optim import make_strategy

        return make_strategy(self.optimiser, self.particles, **dict(self.optimiser_options))

    def env_config(self):
        """The :class:`~jaxgait.world.envs.EnvConfig` with ``env_overrides`` applied."""
        from jaxgait.world.envs import get_env_config

        return get_env_config(self.env, **dict(self.env_overrides))

    # ------------------------------------------------------------------ JSON
    def to_dict(self) -> dict:
        """JSON-ready dict (pairs become objects, stages lists; inf becomes the string "inf")."""
        d = {}
        for f in dataclasses.fields(self):
            if f.name.startswith("_"):
                continue
            v = getattr(self, f.name)
            if (f.name, v) in (
                ("stop_speed_tol", None),
                ("confirm_best", False),
                ("pose", "geyer"),
                ("reference", "walking"),
                ("dynamics", "mjx"),
            ):
                continue  # unset: configs written before the field existed stay equal
            if f.name in ("env_overrides", "optimiser_options", "targets", "weights"):
                v = dict(v)
            elif f.name == "stages":
                v = [list(p) for p in v]
            elif isinstance(v, float) and not math.isfinite(v):
                v = "inf" if v > 0 else "-inf"
            d[f.name] = v
        return d

    @classmethod
    def from_dict(cls, d: Mapping, where: str = "config") -> Experiment:
        """Inverse of :meth:`to_dict`; unknown keys are an error naming ``where``."""
        if not isinstance(d, Mapping):
            raise ExperimentError(f"{where}: an experiment config must be a JSON object")
        names = field_names()
        unknown = sorted(set(d) - set(names))
        if unknown:
            raise ExperimentError(
                f"{where}: unknown field(s) {', '.join(unknown)}; valid fields: {', '.join(names)}"
            )
        kw = dict(d)
        kw.setdefault("dynamics", "mjx")  # configs written without it ran MJX's dynamics
        for k in ("d_lim", "duration", "v0"):
            if isinstance(kw.get(k), str) and kw[k] in ("inf", "Infinity"):
                kw[k] = math.inf
        try:
            return cls(**kw)
        except ExperimentError as e:
            raise ExperimentError(f"{where}: {e}") from None
        except TypeError as e:
            raise ExperimentError(f"{where}: {e}") from None

    def replace(self, **overrides) -> Experiment:
        """Copy with fields replaced (checked as :func:`get_experiment` does)."""
        return _replace(self, overrides)


def field_names() -> tuple[str, ...]:
    """Public field names of :class:`Experiment`."""
    return tuple(f.name for f in dataclasses.fields(Experiment) if not f.name.startswith("_"))


def _replace(base: Experiment, overrides: Mapping) -> Experiment:
    names = field_names()
    unknown = sorted(set(overrides) - set(names))
    if unknown:
        raise ExperimentError(
            f"unknown field(s) {', '.join(unknown)} for experiment {base.name!r}; "
            f"valid fields: {', '.join(names)}"
        )
    kw = dict(overrides)
    for k in ("env_overrides", "optimiser_options", "targets"):
        if k in kw and isinstance(kw[k], Mapping):  # merge into the existing pairs
            kw[k] = {**dict(getattr(base, k)), **kw[k]}
    return dataclasses.replace(base, **kw)


# ---------------------------------------------------------------------------------- registry

_V = (("v_desired", 1.3),)
_ROBUST = (("distance", None), ("trunk", 10.0), ("speed", None), ("angles", None), ("cot", None))
_EXP2_STAGES = (("distance", None), ("speed", None), ("steplengths", None), ("energy", None))
_EXP3_STAGES = _EXP2_STAGES[:3] + (("angles", None), ("energy", None))
#: exp3's stages with the human-likeness criteria before energy: every joint correlation
#: above 0.9 (C_angles is their minimum), no stance peak above 1.3 BW, GRF correlation 0.9.
#: (An entry's threshold is the condition on the previous stage's criterion that opens it.)
_HUMANLIKE_STAGES = _EXP2_STAGES[:3] + (
    ("angles", None),
    ("grf_peak", 0.9),
    ("grf_corr", -1e-6),
    ("energy", 0.9),
)
#: quickstart's task: a 20 s walk at v* (see the module docstring).
_QUICKSTART_WEIGHTS = (
    ("distance", 1.0),
    ("upright", 20.0),
    ("speed", 10.0),
    ("upright_speed", 20.0),
)
#: A weighted form of the human-likeness goals for CMA-ES: quickstart's walk (20 s at v*)
#: dominates; then 10 per BW of stance peak above 1.3 BW, 10 x GRF correlation, 5 x the hip
#: and knee and 10 x the ankle correlation (the weakest joint), 0.02 per J/m of energy.
_HUMANLIKE_WEIGHTS = _QUICKSTART_WEIGHTS + (
    ("grf_peak", 10.0),
    ("grf_corr", 10.0),
    ("corr_hip", 5.0),
    ("corr_knee", 5.0),
    ("corr_ankle", 10.0),
    ("energy_per_m", 0.02),
)
#: The FBL+ search's weights: the human-likeness terms with the GRF-peak and energy weights of
#: ``fbl_ankle_humanlike``'s shipped search (30, 0.04) and Wang's standard score (10 per SD).
_HUMANLIKE_PLUS_WEIGHTS = tuple(
    (k, {"grf_peak": 30.0, "energy_per_m": 0.04}.get(k, w)) for k, w in _HUMANLIKE_WEIGHTS
) + (("standard_score", 10.0),)
# shared settings of several experiments (keyword groups of ``Experiment``)
_HUMANLIKE_CMAES = {
    "optimiser": "cmaes",
    "optimiser_options": (("sigma_init", 0.05),),
    "weights": _HUMANLIKE_WEIGHTS,
    "d_lim": math.inf,
    "duration": 20.0,
    "particles": 16,
    "iterations": 60,
}
_FBLPLUS = {"model": "fblplus", "init": "fblplus_walk"}
_RUNNING = {"targets": (("v_desired", 2.5),), "duration": 30.0, "v0": 2.5}
_ROBUST_RUN = {"stages": _ROBUST, "d_lim": 120.0, "duration": 120.0, "worst_of_k": 5}
_CMAES = {"optimiser": "cmaes", "optimiser_options": (("sigma_init", 0.1),)}


def _known_model(name, init) -> bool:
    """A registered planar model, or one a preset defines (:func:`jaxgait.presets.ensure_model`)."""
    from jaxgait.presets import ensure_model

    return isinstance(name, str) and ensure_model(name, init)


def _e(**kw) -> Experiment:
    return Experiment(**kw)


#: Wang et al. 2012 section 6: CMA-ES with population 50 on the 8-muscle controller; the
#: objective is the return of his section 5 as a weighted sum (see the module docstring).
_WANG = dict(
    model="wang8",
    optimiser="cmaes",
    optimiser_options=(("sigma_init", 0.1),),
    particles=50,
    d_lim=math.inf,
    duration=20.0,
)
_WANG_WEIGHTS = _QUICKSTART_WEIGHTS + (
    ("trunk", 10.0),
    ("effort", 1.0),
)


def _wang(name: str, v: float, init: str, what: str, **kw) -> Experiment:
    return _e(
        name=name,
        description=f"Wang 2012 {what}: wang8, CMA-ES 50, v* {v:g} m/s, task terms - w_e J_effort",
        targets=(("v_desired", float(v)),),
        init=init,
        **{**_WANG, "weights": _WANG_WEIGHTS, "v0": float(v), **kw},
    )


EXPERIMENTS: dict[str, Experiment] = {
    e.name: e
    for e in (
        _e(
            name="exp1",
            description="Table 3.1 exp 1: flat, FBL, stage PSO (d, C_speed, -E)",
            stages=(("distance", None), ("speed", None), ("energy", None)),
        ),
        _e(
            name="exp2",
            description="Table 3.1 exp 2: flat, FBL, stage PSO (d, C_speed, C_steplengths, -E)",
            stages=_EXP2_STAGES,
        ),
        _e(
            name="exp3",
            description=(
                "Table 3.1 exp 3: flat, FBL, stage PSO (d, C_speed, C_steplengths, C_angles, -E)"
            ),
            stages=_EXP3_STAGES,
        ),
        _e(
            name="fbl_humanlike",
            description=(
                "exp3 with human-likeness stages: angles > 0.9, stance GRF peak <= 1.3 BW, "
                "GRF correlation with Winter > 0.9, then -E"
            ),
            stages=_HUMANLIKE_STAGES,
        ),
        _e(
            name="fbl_humanlike_cmaes",
            description=(
                "CMA-ES from fbl_walk: quickstart's 20 s walk at 1.3 m/s plus penalties on the "
                "stance GRF peak above 1.3 BW, rewards for the GRF and joint correlations with "
                "Winter, and energy per metre"
            ),
            **_HUMANLIKE_CMAES,
        ),
        _e(
            name="fbl_ankle_humanlike",
            description=(
                "fbl_humanlike_cmaes's objective on the fbl_ankle model (FBL + swing "
                "plantarflexor drive + TA foot-lowering damping), from fbl_ankle_walk"
            ),
            model="fbl_ankle",
            init="fbl_ankle_walk",
            **_HUMANLIKE_CMAES,
        ),
        _e(
            name="fblplus_humanlike",
            description=(
                "the human-likeness search on FBL+ (its swing-end PD rules land the leg with an "
                "extended knee), with Wang's standard score, from fblplus_humanlike_start"
            ),
            model="fblplus",
            init="fblplus_humanlike_start",
            confirm_best=True,
            **{**_HUMANLIKE_CMAES, "weights": _HUMANLIKE_PLUS_WEIGHTS, "iterations": 350},
        ),
        _e(
            name="exp4",
            description="Table 3.1 exp 4: flat, FBL, standard PSO, weighted eq. 2.55 + C_speed",
            optimiser="pso",
            weights=(
                ("distance", 1.0),
                ("speed", 1.0),
                ("steplengths", 0.1),
                ("angles", 0.1),
                ("energy", 1e-5),
            ),
        ),
        _e(
            name="exp5",
            description="thesis 3.3.1 exp 5: FBL+ running on flat ground, exp2 stages, v* 2.5 m/s",
            stages=_EXP2_STAGES,
            **_FBLPLUS,
            **_RUNNING,
        ),
        _e(
            name="fblplus_run",
            description=(
                "FBL+ running: CMA-ES from exp5's fast walk (fblplus_fastwalk), quickstart's "
                "20 s task at v* 2.5 m/s plus 20 x (-double-stance fraction) and 20 x flight "
                "fraction"
            ),
            model="fblplus",
            init="fblplus_fastwalk",
            optimiser="cmaes",
            optimiser_options=(("sigma_init", 0.05),),
            weights=_QUICKSTART_WEIGHTS + (("no_double_stance", 20.0), ("flight", 20.0)),
            particles=16,
            iterations=150,
            d_lim=math.inf,
            confirm_best=True,
            **{**_RUNNING, "duration": 20.0},
        ),
        _e(
            name="exp5_table",
            description="Table 3.1 exp 5 as printed: FBL+ on env 2 (one push), robust stages",
            env="push",
            stages=_ROBUST,
            **_FBLPLUS,
            **_RUNNING,
        ),
        _e(
            name="exp6a",
            description="Table 3.1 exp 6a: random pushes, FBL, robust stages, worst of 5",
            env="random_push",
            **_ROBUST_RUN,
        ),
        _e(
            name="exp6b",
            description="Table 3.1 exp 6b: random pushes, FBL+, robust stages, worst of 5",
            env="random_push",
            **_FBLPLUS,
            **_ROBUST_RUN,
        ),
        _e(
            name="exp7a",
            description="Table 3.1 exp 7a: wavy ground, FBL, robust stages, worst of 5",
            env="wavy",
            **_ROBUST_RUN,
        ),
        _e(
            name="exp7b",
            description="Table 3.1 exp 7b: wavy ground, FBL+, robust stages, worst of 5",
            env="wavy",
            **_FBLPLUS,
            **_ROBUST_RUN,
        ),
        _e(
            name="exp3_cmaes",
            description="exp3 with CMA-ES (stage fitness as a rank key), sigma 0.1 of the ranges",
            stages=_EXP3_STAGES,
            **_CMAES,
        ),
        _e(
            name="exp7a_cmaes",
            description="exp7a with CMA-ES (stage fitness as a rank key), sigma 0.1 of the ranges",
            env="wavy",
            **_CMAES,
            **_ROBUST_RUN,
        ),
        _e(
            name="quickstart",
            description=(
                "the main job: CMA-ES from the Geyer-Herr gains (which fall after 1.7 s) to a "
                "gait that walks 20 s near 1.3 m/s on flat ground"
            ),
            optimiser="cmaes",
            optimiser_options=(("sigma_init", 0.1),),
            weights=_QUICKSTART_WEIGHTS,
            targets=_V,
            d_lim=math.inf,
            duration=20.0,
            particles=16,
            iterations=40,
            init="table",
            stop_speed_tol=0.05,
            confirm_best=True,
        ),
        _wang("wang_walk_1p25", 1.25, "table", "nwalk from the Geyer-Herr gains", iterations=80),
        _wang("wang_walk_1p0", 1.0, "wang_walk_1p25", "swalk from nwalk", iterations=40),
        _wang("wang_walk_1p5", 1.5, "wang_walk_1p25", "fwalk from nwalk", iterations=40),
        _wang("wang_walk_1p75", 1.75, "wang_walk_1p5", "vwalk from fwalk", iterations=40),
        *(
            _wang(
                f"wang_run_{v:g}p0",
                v,
                init,
                f"running at {v:g} m/s from {init}",
                weights=_WANG_WEIGHTS + (("no_double_stance", 20.0),),
                iterations=80,
                v0=v0,
                model=model,
            )
            # each faster run starts from the slower one's runner, in the running ranges
            # (wang8_run) that the shipped wang_run_3p0 needs
            for v, v0, init, model in (
                (3, 3.05, "wang_run_start", "wang8"),
                (4, 4.0, "wang_run_3p0", "wang8_run"),
                (5, 5.0, "wang_run_4p0", "wang8_run"),
            )
        ),
        _wang(
            "wang_push_walk_1p25",
            1.25,
            "wang_walk_1p25",
            "nwalk tolerant of 100 N, 0.4 s forward pushes on the trunk (worst of 4 push times)",
            env="push",
            env_overrides=(("magnitude", 100.0), ("duration", 0.4)),
            worst_of_k=4,
            iterations=40,
        ),
        _wang(
            "wang_push_run_4p0",
            4.0,
            "wang_run_4p0",
            "4 m/s running tolerant of 50 N, 0.4 s forward pushes (worst of 4 push times)",
            model="wang8_run",
            env="push",
            env_overrides=(("magnitude", 50.0), ("duration", 0.4)),
            worst_of_k=4,
            iterations=40,
            v0=4.0,
            weights=_WANG_WEIGHTS + (("no_double_stance", 20.0),),
        ),
    )
}


def list_experiments() -> list[str]:
    """Registry names, in registry order."""
    return list(EXPERIMENTS)


def describe_experiments() -> str:
    """One line per experiment: name, model, environment, optimiser, size, description."""
    w = max(len(n) for n in EXPERIMENTS)
    lines = []
    for n, e in EXPERIMENTS.items():
        size = f"{e.particles}x{e.iterations}" + (f" k={e.worst_of_k}" if e.worst_of_k > 1 else "")
        lines.append(
            f"{n:<{w}}  {e.model:<7} {e.env:<11} {e.optimiser:<9} {size:<13} {e.description}"
        )
    return "\n".join(lines)


def get_experiment(name: str, **overrides) -> Experiment:
    """The registry experiment ``name`` with fields replaced by ``overrides``.

    Mapping fields (``targets``, ``env_overrides``, ``optimiser_options``) given as dicts are
    merged into the registry values; every other field is replaced.

    Raises:
      ExperimentError: unknown name (lists the registry), unknown field (lists the fields) or
        invalid value (says the rule).
    """
    if name not in EXPERIMENTS:
        raise ExperimentError(
            f"unknown experiment {name!r}; valid experiments: {', '.join(EXPERIMENTS)}"
        )
    return _replace(EXPERIMENTS[name], overrides)


def load_config(path: str | Path) -> Experiment:
    """Read an experiment config JSON (a ``config.json`` of a results folder, or a bare
    :meth:`Experiment.to_dict`). Errors name the file, and the line and column for bad JSON."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise ExperimentError(f"{path}: cannot read config file: {e}") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise ExperimentError(
            f"{path}: invalid JSON at line {e.lineno}, column {e.colno}: {e.msg}"
        ) from None
    if isinstance(doc, dict) and "experiment" in doc and isinstance(doc["experiment"], dict):
        doc = doc["experiment"]
    return Experiment.from_dict(doc, where=str(path))


def resolve_experiment(config: Experiment | str | Path, **overrides) -> Experiment:
    """An :class:`Experiment` from itself, a registry name or a config JSON path."""
    if isinstance(config, Experiment):
        return config.replace(**overrides) if overrides else config
    s = str(config)
    if isinstance(config, str) and s in EXPERIMENTS:
        return get_experiment(s, **overrides)
    if s.endswith(".json") or Path(s).is_file():
        exp = load_config(s)
        return exp.replace(**overrides) if overrides else exp
    raise ExperimentError(f"unknown experiment {s!r}; valid experiments: {', '.join(EXPERIMENTS)}")
