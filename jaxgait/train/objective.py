"""Fitness of a population of rollouts: weighted objectives and stage fitness (thesis 2.2.1-2.2.3).

Two kinds of objective turn the measures of
:func:`jaxgait.analysis.measures.compute_measures` into a
score, both MAXIMISED here (the optimisers' conventions are applied by :func:`to_tell`):

* :class:`WeightedObjective`, the single-function objectives of thesis 2.2.3,
  F = sum_i w_i C_i, e.g. eq. 2.47 ``F = d - alpha E`` is ``{"distance": 1, "energy": alpha}``
  (the criterion ``energy`` is already -E), eq. 2.52 adds ``beta C_angles``, eq. 2.55
  ``gamma C_steplengths``, and the final function ``delta C_speed + zeta C_steplength``.
* :class:`StageObjective`, the stage PSO fitness of thesis 2.2.1.2 / 2.2.3.1: a list of
  stages ``[(criterion, entrance), ...]``. Stage 0 has no entrance condition; stage s >= 1 is
  entered when the criterion of stage s-1 exceeds its entrance threshold (the layout of
  Table 2.8, where the condition is printed in the row of the stage it opens). ``entrance =
  None`` takes the Table 2.8 condition of the previous stage's criterion
  (:data:`TABLE_2_8_EXIT`):

  ==============  ===========================  =========================================
  criterion       condition to pass            threshold on the (maximised) criterion
  ==============  ===========================  =========================================
  ``distance``    d > 0.99 d_lim               ``0.99 d_lim`` [m]
  ``angles``      C_angles > 0.8               ``0.8``
  ``speed``       abs(v - v*) < 0.05 m/s       ``-0.05`` (C_speed = -abs(v* - v))
  ``steplengths`` C_steplengths > 6            ``6``
  ``trunk``       0 < mean trunk lean < 0.105  ``-1e-6`` rad (C_trunk = 0 inside the band,
                                               thesis 3.2; 1e-6 rad of rounding allowed)
  ==============  ===========================  =========================================

  ``energy``, ``cot`` and the other criteria have no standard condition and need an explicit
  threshold if they are not the last stage. The robustness experiments (thesis 3.2) replace
  the first condition by d > 10 m: ``[("distance", None), ("trunk", 10.0), ...]``.

The thesis also caps the progress of a stage-PSO particle: a particle at stage N is evaluated
up to stage N+1 only (2.2.1.2); pass ``max_stage = state.stage + 1``.

Robust evaluation (thesis 3.2, SPEC §4): each parameter set is rolled out on k environments
and the WORST score is kept (:func:`worst_of_k`): the lowest scalar score, or for stage
fitness the lowest stage and, within it, the lowest value.

Failed rollouts: a rollout whose state became non-finite (see :func:`rollout_valid`) or whose
criteria are not finite scores NaN, mapped to the worst value of every convention (scalar
``-inf`` score / ``+inf`` fitness, stage pair ``(-1, -inf)``) before anything reaches an
optimiser, so it never enters an optimiser state or a best.

Three criteria are added here to the registry of :mod:`jaxgait.analysis.criteria` for the
scalar objectives (all maximised): ``upright`` = 1 if the rollout did not fall, else 0,
``energy_per_m`` = -E/d [J/m] (metabolic energy per metre, d floored at 1 mm) and
``upright_speed`` = upright x C_speed (the speed error counts only for a rollout that did not
fall, so a search from a falling start is not pulled towards v* before it walks); and
``effort`` = -(0.004 / mass) J_effort, the effort term of Wang et al. 2012's return
(section 5; J_effort = 100 J_M + 0.5 J_L with the rollout's metabolic model, the measure
``effort``); ``no_double_stance`` = -(double-stance fraction) of a rollout that did not
fall (-1 if it fell), ``flight`` = its flight fraction (0 if it fell) and ``flight_time`` =
flight fraction x duration [s] (fallen or not), for running; the human-likeness criteria
``grf_corr`` (the vertical GRF's correlation with Winter's over the last cycle), ``grf_peak``
(-(largest per-stance peak above :data:`GRF_PEAK_BOUND_BW`) in BW; ``grf_peak_mean``
the same of the mean per-stance peak), ``grf_loading_rate``
(-(largest one-step loading rate above :data:`GRF_RATE_BOUND_BW_S`) per 1000 BW/s),
``corr_hip``, ``corr_knee``, ``corr_ankle`` (each joint's correlation; ``angles`` is their
minimum; ``mean_cycle_corr_*`` the same of the mean of the last cycles), ``corr_floor``
(-(sum of the mean cycle's three and ``grf_corr``'s shortfalls below :data:`CORR_FLOOR`), a
hinge constraint), ``rom`` (-(|knee| + |ankle| range-of-motion difference from Winter's) /
10 deg) and ``standard_score`` (-(Wang's Table 1 standard score), the mean over hip, knee and
ankle, capped at :data:`STANDARD_SCORE_CAP`; ``mean_cycle_standard_score`` of the mean cycle)
with its per-joint ``standard_score_hip``, ``standard_score_knee``, ``standard_score_ankle``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp

from jaxgait.analysis import criteria as crit
from jaxgait.muscles.energy import WANG_EFFORT_SCALE
from jaxgait.optim import INVALID_STAGE, canonical_stage, evaluate_stages, stage_rank_key

Measures = Mapping[str, jax.Array]

#: Tolerance [rad] of the trunk band entrance (C_trunk = 0 inside the band, thesis 3.2).
TRUNK_TOLERANCE = 1e-6


def _upright(m: Measures) -> jax.Array:
    """1 if the rollout ended without a fall, else 0."""
    return 1.0 - jnp.asarray(m["fell"]).astype(m["distance_m"].dtype)


def _energy_per_m(m: Measures) -> jax.Array:
    """-E/d [J/m] (maximised), the measure ``energy_J_per_m`` (d floored at 1 mm)."""
    return -m["energy_J_per_m"]


def _upright_speed(m: Measures, *, v_desired: float) -> jax.Array:
    """C_speed = -|v* - v| [m/s] of a rollout that did not fall, 0 for one that fell."""
    return _upright(m) * crit.c_speed(m, v_desired=v_desired)


def _effort(m: Measures) -> jax.Array:
    """-(w_e) J_effort with w_e = 0.004 / mass (Wang et al. 2012 section 5): the effort term
    of Wang's return, maximised; the measure ``effort`` (J_M with the basal rate, J_L)."""
    return -WANG_EFFORT_SCALE * m["effort"] / jnp.maximum(m["mass_kg"], 1e-9)


def _no_double_stance(m: Measures) -> jax.Array:
    """-(double-stance fraction) of a rollout that did not fall, -1 for one that fell: a
    running task term (Wang's running controllers have no double support)."""
    up = _upright(m)
    return -(up * m["double_stance_fraction"] + (1.0 - up))


def _flight(m: Measures) -> jax.Array:
    """Flight fraction (neither foot in stance) of a rollout that did not fall, 0 for one that
    fell: the running task term that a gait without double stance can still miss."""
    return _upright(m) * m["flight_fraction"]


def _flight_time(m: Measures) -> jax.Array:
    """Time in flight [s] (flight fraction x duration), fallen or not: a graded running term
    that rewards a hop before the gait that carries it stays up."""
    return m["flight_fraction"] * m["duration_s"]


#: Bound [BW] above which the per-stance peak vertical GRF is penalised (``grf_peak``): the
#: human loading peak is about 1.1 BW at 1.3 m/s (Winter), 1.3 BW leaves room for speed.
GRF_PEAK_BOUND_BW = 1.3


def _grf_peak(m: Measures) -> jax.Array:
    """-(largest per-stance vertical-GRF peak above :data:`GRF_PEAK_BOUND_BW`) [BW]."""
    return -jnp.maximum(m["grf_peak_max_bw"] - GRF_PEAK_BOUND_BW, 0.0)


def _grf_peak_mean(m: Measures) -> jax.Array:
    """-(mean of the per-stance vertical-GRF peaks above :data:`GRF_PEAK_BOUND_BW`) [BW]: as
    ``grf_peak`` for every stance rather than the worst one (a runner's landings differ by
    a few BW from stance to stance, so the largest one is a noisy criterion)."""
    return -jnp.maximum(m["grf_peak_mean_bw"] - GRF_PEAK_BOUND_BW, 0.0)


#: Bound [BW/s] above which the largest one-step loading rate of the vertical GRF is penalised
#: (``grf_loading_rate``): a forefoot landing after the heel raises the GRF by most of a body
#: weight within one 0.5 ms step (about 2,000 BW/s) while the peak stays low; a heel landing
#: loads at tens to a few hundred BW/s.
GRF_RATE_BOUND_BW_S = 100.0


def _grf_loading_rate(m: Measures) -> jax.Array:
    """-(largest per-stance one-step loading rate above :data:`GRF_RATE_BOUND_BW_S`) per
    1000 BW/s of the vertical GRF, measured at the physics step."""
    return -jnp.maximum(m["grf_loading_rate_max_bw_s"] - GRF_RATE_BOUND_BW_S, 0.0) / 1000.0


#: Cap [SD] of the standard-score criteria: a rollout without a full cycle has the measures'
#: sentinel score (99), and a score above a few SD says no more about human-likeness.
STANDARD_SCORE_CAP = 5.0


def _standard_score(key: str):
    """-min(standard score, :data:`STANDARD_SCORE_CAP`) of measure ``key`` [SD]: Wang et al.
    2012 Table 1's score (mean over the cycle of |model - human mean| / human SD), which,
    unlike a correlation, also counts offsets (a knee still flexed at touchdown)."""
    return lambda m: -jnp.minimum(m[key], STANDARD_SCORE_CAP)


#: Floor of the ``corr_floor`` criterion: the human-likeness targets ask each joint's and the
#: vertical GRF's correlation with Winter to be at least 0.9; 0.915 leaves room for a 60 s
#: walk's last cycle to differ from a 20 s training rollout's (0.003-0.005 in the presets).
CORR_FLOOR = 0.915

#: The correlations held above :data:`CORR_FLOOR` by ``corr_floor``: the joints' of the mean
#: of the last cycles (one cycle's knee correlation moves by 0.02 under a 1e-6 change of the
#: parameters, which a heavy weight on it would let a search exploit) and the GRF's.
CORR_FLOOR_KEYS = (
    "mean_cycle_corr_hip",
    "mean_cycle_corr_knee",
    "mean_cycle_corr_ankle",
    "grf_corr",
)


def _corr_floor(m: Measures) -> jax.Array:
    """-sum over hip, knee, ankle (their mean cycle) and vertical GRF of (:data:`CORR_FLOOR`
    - correlation)^+: a hinge that is 0 while every correlation is above the floor, so a
    heavy weight holds them there as constraints while lighter terms (energy) trade freely
    above it."""
    return -sum(jnp.maximum(CORR_FLOOR - m[k], 0.0) for k in CORR_FLOOR_KEYS)


def _rom(m: Measures) -> jax.Array:
    """-(|knee| + |ankle| range-of-motion difference from the reference) / 10 deg."""
    return -(jnp.abs(m["rom_knee_diff_deg"]) + jnp.abs(m["rom_ankle_diff_deg"])) / 10.0


#: Criteria defined here in addition to :data:`jaxgait.analysis.criteria.CRITERIA` (maximised).
EXTRA_CRITERIA = {
    "upright": _upright,
    "energy_per_m": _energy_per_m,
    "upright_speed": _upright_speed,
    "effort": _effort,
    "no_double_stance": _no_double_stance,
    "flight": _flight,
    "flight_time": _flight_time,
    "grf_corr": lambda m: m["grf_corr"],
    "grf_peak": _grf_peak,
    "grf_peak_mean": _grf_peak_mean,
    "grf_loading_rate": _grf_loading_rate,
    "corr_hip": lambda m: m["corr_hip"],
    "corr_knee": lambda m: m["corr_knee"],
    "corr_ankle": lambda m: m["corr_ankle"],
    "mean_cycle_corr_hip": lambda m: m["mean_cycle_corr_hip"],
    "mean_cycle_corr_knee": lambda m: m["mean_cycle_corr_knee"],
    "mean_cycle_corr_ankle": lambda m: m["mean_cycle_corr_ankle"],
    "mean_cycle_standard_score": _standard_score("mean_cycle_standard_score"),
    "rom": _rom,
    "corr_floor": _corr_floor,
    "standard_score": _standard_score("standard_score"),
    "standard_score_hip": _standard_score("standard_score_hip"),
    "standard_score_knee": _standard_score("standard_score_knee"),
    "standard_score_ankle": _standard_score("standard_score_ankle"),
}
#: Targets the extra criteria need.
EXTRA_TARGETS = {"upright_speed": ("v_desired",)}

#: Table 2.8 condition for leaving a stage whose criterion is the key: a function of d_lim [m]
#: returning the threshold the criterion must exceed.
TABLE_2_8_EXIT = {
    "distance": lambda d_lim: 0.99 * d_lim,
    "angles": lambda d_lim: 0.8,
    "speed": lambda d_lim: -0.05,
    "steplengths": lambda d_lim: 6.0,
    "trunk": lambda d_lim: -TRUNK_TOLERANCE,
}

#: Typical magnitude of each criterion, used to squash a stage value when a stage objective is
#: given to a scalar optimiser (:func:`jaxgait.optim.stage_rank_key`).
CRITERION_SCALE = {
    "distance": 10.0,
    "angles": 0.1,
    "speed": 0.1,
    "steplengths": 1.0,
    "steplength": 0.1,
    "cot": 0.1,
    "left_right": 1.0,
    "trunk": 0.05,
    "energy": 1000.0,
    "upright": 1.0,
    "energy_per_m": 50.0,
    "upright_speed": 0.1,
    "effort": 0.5,
    "no_double_stance": 0.1,
    "flight": 0.1,
    "flight_time": 1.0,
    "grf_corr": 0.1,
    "grf_peak": 0.5,
    "grf_peak_mean": 0.5,
    "grf_loading_rate": 0.5,
    "corr_hip": 0.1,
    "corr_knee": 0.1,
    "corr_ankle": 0.1,
    "rom": 1.0,
    "corr_floor": 0.01,
    "mean_cycle_corr_hip": 0.1,
    "mean_cycle_corr_knee": 0.1,
    "mean_cycle_corr_ankle": 0.1,
    "mean_cycle_standard_score": 0.5,
    "standard_score": 0.5,
    "standard_score_hip": 0.5,
    "standard_score_knee": 0.5,
    "standard_score_ankle": 0.5,
}


class ObjectiveError(ValueError):
    """An objective specification is invalid (unknown criterion, missing threshold...)."""


def resolve_criterion(name: str) -> str:
    """Canonical name of a criterion of :mod:`jaxgait.analysis.criteria` or of
    :data:`EXTRA_CRITERIA`."""
    key = str(name).strip().lower()
    if key in EXTRA_CRITERIA:
        return key
    try:
        return crit.resolve_name(name)
    except ValueError:
        valid = sorted(set(crit.CRITERIA) | set(EXTRA_CRITERIA))
        raise ObjectiveError(f"unknown criterion {name!r}; valid criteria: {valid}") from None


def criterion_value(name: str, measures: Measures, targets: Mapping[str, float]) -> jax.Array:
    """Value (maximised) of criterion ``name`` for ``measures`` (single or batched)."""
    key = resolve_criterion(name)
    if key in EXTRA_CRITERIA:
        kw = {t: float(targets[t]) for t in EXTRA_TARGETS.get(key, ())}
        return EXTRA_CRITERIA[key](measures, **kw)
    return crit.criterion(key, measures, **dict(targets))


def _check_targets(names: Sequence[str], targets: Mapping[str, float]) -> None:
    known = {t for ts in crit.CRITERION_TARGETS.values() for t in ts}
    unknown = sorted(set(targets) - known)
    if unknown:
        raise ObjectiveError(f"unknown target(s) {unknown}; valid targets: {sorted(known)}")
    for n in names:
        if n in ("speed", "upright_speed") and "v_desired" not in targets:
            raise ObjectiveError(f"criterion {n!r} needs the target v_desired [m/s]")
        if n == "steplength" and "sl_desired" not in targets:
            raise ObjectiveError("criterion 'steplength' needs the target sl_desired [m]")


def rollout_valid(trace: Any, summary: Any) -> jax.Array:
    """() bool: the rollout stayed finite (works batched with a leading axis).

    :func:`jaxgait.sim.step` ends a rollout whose state turns non-finite as a fall and freezes
    its summary from the last finite step, so a blown-up simulation can look like an ordinary
    fall. A non-finite state persists, so it shows in the first trace row logged after the end;
    this checks every alive row and that row, plus the summary scalars.
    """
    alive = trace.alive.astype(bool)
    finite_rows = jnp.all(jnp.isfinite(trace.qpos), axis=-1)
    first_dead = jnp.argmax(~alive, axis=-1)
    any_dead = jnp.any(~alive, axis=-1)
    end_row = jnp.take_along_axis(finite_rows, first_dead[..., None], axis=-1)[..., 0]
    ok = jnp.all(finite_rows | ~alive, axis=-1) & (end_row | ~any_dead)
    for x in (summary.distance, summary.energy, summary.duration):
        ok = ok & jnp.isfinite(x)
    return ok


@dataclass(frozen=True)
class WeightedObjective:
    """F = sum_i w_i C_i (thesis eq. 2.47, 2.52, 2.55 and the final function of 2.2.3).

    Attributes:
      weights: ((criterion, weight), ...), criteria maximised (``energy`` is -E [J]).
      targets: ((name, value), ...), e.g. (("v_desired", 1.3),) [m/s].
    """

    weights: tuple[tuple[str, float], ...]
    targets: tuple[tuple[str, float], ...] = ()

    def __post_init__(self):
        if not self.weights:
            raise ObjectiveError("a weighted objective needs at least one (criterion, weight)")
        w = tuple((resolve_criterion(n), float(v)) for n, v in self.weights)
        for n, v in w:
            if not math.isfinite(v):
                raise ObjectiveError(f"weight of {n!r} must be finite, got {v}")
        object.__setattr__(self, "weights", w)
        object.__setattr__(self, "targets", tuple((str(k), float(v)) for k, v in self.targets))
        _check_targets([n for n, _ in w], dict(self.targets))

    kind = "weighted"

    @property
    def n_stages(self) -> int:
        return 1

    def score(self, measures: Measures, valid: jax.Array | None = None) -> jax.Array:
        """(...,) F, maximised; NaN where ``valid`` is False or F is not finite."""
        targets = dict(self.targets)
        total = 0.0
        for name, w in self.weights:
            total = total + w * criterion_value(name, measures, targets)
        total = jnp.asarray(total)
        ok = jnp.isfinite(total) if valid is None else valid & jnp.isfinite(total)
        return jnp.where(ok, total, jnp.nan)

    def fitness(self, measures: Measures, valid=None, max_stage=None):
        """``(stage, value)``: stage 0 everywhere (``-1`` if invalid), value = F."""
        del max_stage
        f = self.score(measures, valid)
        return canonical_stage(jnp.zeros(f.shape, jnp.int32), f)


@dataclass(frozen=True)
class StageObjective:
    """Stage fitness (thesis 2.2.1.2, Table 2.8, Table 3.1).

    Attributes:
      stages: ((criterion, entrance threshold or None), ...); see the module docstring.
      d_lim: distance limit [m] for the ``d > 0.99 d_lim`` condition.
      targets: ((name, value), ...), e.g. (("v_desired", 1.3),).
    """

    stages: tuple[tuple[str, float | None], ...]
    d_lim: float = math.inf
    targets: tuple[tuple[str, float], ...] = ()

    kind = "stage"

    def __post_init__(self):
        if not self.stages:
            raise ObjectiveError("a stage objective needs at least one stage")
        st = []
        for entry in self.stages:
            if isinstance(entry, str):
                entry = (entry, None)
            name, thr = entry
            st.append((resolve_criterion(name), None if thr is None else float(thr)))
        if st[0][1] is not None:
            raise ObjectiveError(
                f"stage 0 ({st[0][0]}) has no entrance condition; got threshold {st[0][1]}"
            )
        object.__setattr__(self, "stages", tuple(st))
        object.__setattr__(self, "targets", tuple((str(k), float(v)) for k, v in self.targets))
        _check_targets([n for n, _ in st], dict(self.targets))
        self.thresholds  # noqa: B018 - validates the defaults

    @property
    def criteria(self) -> tuple[str, ...]:
        """Criterion name of every stage."""
        return tuple(n for n, _ in self.stages)

    @property
    def n_stages(self) -> int:
        return len(self.stages)

    @property
    def thresholds(self) -> tuple[float, ...]:
        """(S-1,) entrance thresholds: stage s is entered when criterion s-1 > thresholds[s-1]."""
        out = []
        for s in range(1, len(self.stages)):
            prev, thr = self.stages[s - 1][0], self.stages[s][1]
            if thr is None:
                if prev not in TABLE_2_8_EXIT:
                    raise ObjectiveError(
                        f"stage {s} ({self.stages[s][0]}) needs an explicit entrance threshold "
                        f"on {prev!r}: Table 2.8 has conditions for "
                        f"{sorted(TABLE_2_8_EXIT)} only"
                    )
                if prev == "distance" and not math.isfinite(self.d_lim):
                    raise ObjectiveError(
                        f"stage {s}: the Table 2.8 condition d > 0.99 d_lim needs a finite d_lim"
                    )
                thr = TABLE_2_8_EXIT[prev](self.d_lim)
            out.append(float(thr))
        return tuple(out)

    def values(self, measures: Measures) -> jax.Array:
        """(..., S) criterion of every stage (maximised)."""
        targets = dict(self.targets)
        return jnp.stack([criterion_value(n, measures, targets) for n in self.criteria], -1)

    def fitness(self, measures: Measures, valid=None, max_stage=None):
        """``(stage int32 (...), value (...))``; ``(-1, -inf)`` for invalid rollouts.

        Args:
          measures: (batched) measures.
          valid: optional (...) bool from :func:`rollout_valid`.
          max_stage: optional (...) cap (thesis: a particle at stage N reaches N+1 at most).
        """
        c = self.values(measures)
        ok = jnp.all(jnp.isfinite(c), axis=-1)
        if valid is not None:
            ok = ok & valid
        thr = jnp.asarray(self.thresholds, c.dtype)
        entrance = c[..., :-1] > thr
        stage, value = evaluate_stages(c, entrance, max_stage)
        return canonical_stage(stage, jnp.where(ok, value, jnp.nan))

    def rank_scale(self) -> jax.Array:
        """(S,) value scale of every stage for :func:`to_tell` with scalar optimisers."""
        return jnp.asarray([CRITERION_SCALE.get(n, 1.0) for n in self.criteria])


Objective = WeightedObjective | StageObjective


def make_objective(
    *,
    stages: Sequence | None = None,
    weights: Mapping[str, float] | Sequence | None = None,
    targets: Mapping[str, float] | None = None,
    d_lim: float = math.inf,
) -> Objective:
    """A :class:`StageObjective` (``stages``) or a :class:`WeightedObjective` (``weights``)."""
    targets = tuple(sorted((targets or {}).items()))
    if (stages is None) == (weights is None) or (not stages and not weights):
        raise ObjectiveError("give either a non-empty stage list or non-empty weights")
    if stages:
        return StageObjective(tuple(stages), d_lim=float(d_lim), targets=targets)
    items = weights.items() if isinstance(weights, Mapping) else weights
    return WeightedObjective(tuple(items), targets=targets)


def worst_of_k(stage: jax.Array, value: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Worst of k evaluations per parameter set (thesis 3.2), by the stage order.

    Args:
      stage: (P, k) int stages; value: (P, k) values (maximised); NaN is the worst.

    Returns:
      ``(stage (P,), value (P,))``: the lowest stage and, within it, the lowest value. A
      parameter set with any failed (NaN) evaluation gets the worst pair ``(-1, -inf)``.
    """
    s, v = canonical_stage(stage, value)
    low = jnp.min(s, axis=-1)
    vmin = jnp.min(jnp.where(s == low[..., None], v, jnp.inf), axis=-1)
    return low, jnp.where(low == INVALID_STAGE, -jnp.inf, vmin)


def to_tell(optimiser: str, objective: Objective, stage: jax.Array, value: jax.Array):
    """The fitness a strategy's ``tell`` takes for per-particle ``(stage, value)``.

    * ``stage_pso``: the pair itself (value maximised);
    * ``pso`` / ``cmaes``: a lower-is-better scalar: ``-value`` for a weighted objective,
      :func:`jaxgait.optim.stage_rank_key` of the value divided by its stage's
      :data:`CRITERION_SCALE` for a stage objective; the worst pair maps to ``+inf``.
    """
    stage, value = canonical_stage(stage, value)
    if optimiser == "stage_pso":
        return stage, value
    if isinstance(objective, StageObjective):
        scale = objective.rank_scale().astype(value.dtype)[jnp.maximum(stage, 0)]
        return stage_rank_key(stage, value / scale)
    return jnp.where(stage == INVALID_STAGE, jnp.inf, -value)


def score_text(objective: Objective, stage, value) -> str:
    """Readable best score: ``"F 31.24"`` or ``"stage 2 (speed) -0.031"``."""
    stage, value = int(stage), float(value)
    if stage == INVALID_STAGE:
        return "none valid"
    if isinstance(objective, WeightedObjective):
        return f"F {value:.4g}"
    return f"stage {stage} ({objective.criteria[stage]}) {value:.4g}"
