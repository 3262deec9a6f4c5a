"""Evaluation criteria (thesis 2.2.3, Table 2.7-2.8) and stopping criteria (thesis 2.2.2).

Each criterion is a pure JAX function of the measures dict of
:func:`jaxgait.analysis.measures.compute_measures` (optionally with targets such as a desired speed)
and is **maximised**. Criteria work unchanged on a batch of measures (leading population
axis), since they only combine the dict's entries elementwise.

Readings chosen where the thesis is ambiguous:

* C_left_right (eq. 2.59-2.60): as printed, log|x/var(x) - y/var(y)| grows as the two legs
  differ, against the stated aim (maximise symmetry). Implemented as its negation with
  log1p, -log(1 + |x/var(x) - y/var(y)|): 0 for identical mean/variance ratios, and for a
  large mismatch equal to minus the printed form.
* C_trunk (eq. 2.61): the text says the criterion is maximised when the mean trunk lean is
  in (0, 0.105) rad; the printed |theta - 0.105| would instead reward leaning far forward.
  Implemented as minus the distance of the mean lean to [0, 0.105] rad: 0 inside the band
  (the maximum), negative outside, so "C_trunk >= 0" means an upright-enough gait.
* C_cot (eq. 2.58) = d^2 / E, written d |d| / E so that walking backwards is not rewarded;
  the "alpha = 0.001" mentioned beside it has no place in the printed formula and is not
  used.
* C_speed (eq. 2.56) uses the mean speed distance / duration (the text's "mean of the step
  lengths" there is a copy of eq. 2.57's sentence).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import jax
import jax.numpy as jnp
from flax import struct

from jaxgait.analysis.measures import MEAN_FLOOR, VAR_FLOOR

Measures = Mapping[str, jax.Array]

#: C_left_right when either leg has fewer than two usable steps: below any attainable value
#: for steps shorter than 10 m (-log(1 + 10 / 1e-6) = -16.1).
LEFT_RIGHT_UNDEFINED = -20.0
#: Upper edge of the trunk-lean band of eq. 2.61 [rad] (6 deg).
TRUNK_LEAN_MAX = 0.105
#: Metabolic cost of human walking at 1.3 m/s used for the energy limit (thesis 2.2.2) [J/m].
HUMAN_WALKING_J_PER_M = 210.0
_E_FLOOR = 1e-6


# ----------------------------------------------------------------------------- criteria


def c_distance(m: Measures) -> jax.Array:
    """d: distance travelled [m] (Table 2.8, stage 0)."""
    return m["distance_m"]


def c_angles(m: Measures) -> jax.Array:
    """C_angles: min of the hip, knee, ankle correlations with human angles (eq. 2.51)."""
    return m["c_angles"]


def c_steplengths(m: Measures) -> jax.Array:
    """C_steplengths = SNR of all step lengths, log(mean / var) (eq. 2.53-2.54)."""
    return m["step_length_snr"]


def c_speed(m: Measures, *, v_desired: float) -> jax.Array:
    """C_speed = -|v_desired - v| [m/s], v the mean speed (eq. 2.56)."""
    return -jnp.abs(v_desired - m["mean_speed_mps"])


def c_steplength(m: Measures, *, sl_desired: float) -> jax.Array:
    """C_steplength = -|sl_desired - sl| [m], sl the mean step length (eq. 2.57)."""
    return -jnp.abs(sl_desired - m["step_length_mean_m"])


def c_cot(m: Measures) -> jax.Array:
    """C_cot = d^2 / E [m^2/J] (eq. 2.58), as d |d| / E with E floored at 1e-6 J."""
    d = m["distance_m"]
    return d * jnp.abs(d) / jnp.maximum(m["energy_J"], _E_FLOOR)


def c_left_right(m: Measures) -> jax.Array:
    """C_left_right: left/right step-length similarity (eq. 2.59-2.60), maximal (0) if equal.

    -log(1 + |x/var(x) - y/var(y)|) with x, y the left and right step lengths (variances
    floored as in the SNR); :data:`LEFT_RIGHT_UNDEFINED` if a leg has fewer than 2 steps.
    """
    ratios = []
    for side in ("left", "right"):
        mean = jnp.maximum(m[f"step_length_{side}_mean_m"], MEAN_FLOOR)
        ratios.append(mean / jnp.maximum(m[f"step_length_{side}_var_m2"], VAR_FLOOR))
    val = -jnp.log1p(jnp.abs(ratios[0] - ratios[1]))
    ok = (m["n_steps_left"] >= 2) & (m["n_steps_right"] >= 2)
    return jnp.where(ok, val, LEFT_RIGHT_UNDEFINED)


def c_trunk(m: Measures, *, trunk_lo: float = 0.0, trunk_hi: float = TRUNK_LEAN_MAX) -> jax.Array:
    """C_trunk: minus the distance [rad] of the mean trunk lean to [trunk_lo, trunk_hi].

    Eq. 2.61's stated intent: maximal (0) when the mean forward lean is within
    (0, 0.105) rad, decreasing linearly as the trunk leans further forward or backward.
    """
    lean = m["mean_trunk_lean_rad"]
    return -(jnp.maximum(trunk_lo - lean, 0.0) + jnp.maximum(lean - trunk_hi, 0.0))


def c_energy(m: Measures) -> jax.Array:
    """-E: minus the metabolic energy spent [J] (Table 2.8, stage 4)."""
    return -m["energy_J"]


#: Criterion name -> function of (measures, **targets).
CRITERIA: dict[str, Callable[..., jax.Array]] = {
    "distance": c_distance,
    "angles": c_angles,
    "steplengths": c_steplengths,
    "speed": c_speed,
    "steplength": c_steplength,
    "cot": c_cot,
    "left_right": c_left_right,
    "trunk": c_trunk,
    "energy": c_energy,
}

#: Targets each criterion takes; a target without a default must be given.
CRITERION_TARGETS: dict[str, tuple[str, ...]] = {
    "speed": ("v_desired",),
    "steplength": ("sl_desired",),
    "trunk": ("trunk_lo", "trunk_hi"),
}
_REQUIRED = {"speed": ("v_desired", "m/s"), "steplength": ("sl_desired", "m")}
_ALIASES = {"d": "distance", "-e": "energy"}


def resolve_name(name: str) -> str:
    """Canonical criterion name for ``name``.

    Accepts the registry names, the thesis spellings (``"C_speed"``, ``"d"``, ``"-E"``)
    and any case. Raises ValueError for an unknown name, listing the valid ones.
    """
    key = name.strip().lower()
    if key.startswith("c_"):
        key = key[2:]
    key = _ALIASES.get(key, key)
    if key not in CRITERIA:
        raise ValueError(
            f"unknown criterion {name!r}; valid criteria: {sorted(CRITERIA)} "
            f"(also accepted: C_<name>, 'd', '-E')"
        )
    return key


def criterion(name: str, measures: Measures, **targets: float) -> jax.Array:
    """Value of criterion ``name`` (maximised) for ``measures``.

    Args:
      name: a key of :data:`CRITERIA` (or a thesis spelling, see :func:`resolve_name`).
      measures: dict from :func:`jaxgait.analysis.measures.compute_measures` (single or batched).
      **targets: ``v_desired`` [m/s], ``sl_desired`` [m], ``trunk_lo``/``trunk_hi`` [rad].
        Targets the criterion does not use are ignored, so one set of targets can be
        passed to every criterion of a stage list; unknown target names are an error.
    """
    key = resolve_name(name)
    known = {t for ts in CRITERION_TARGETS.values() for t in ts}
    unknown = sorted(set(targets) - known)
    if unknown:
        raise TypeError(f"unknown criterion target(s) {unknown}; valid targets: {sorted(known)}")
    if key in _REQUIRED and _REQUIRED[key][0] not in targets:
        t, unit = _REQUIRED[key]
        raise ValueError(f"criterion {key!r} needs the target {t}=... [{unit}]")
    used = {k: v for k, v in targets.items() if k in CRITERION_TARGETS.get(key, ())}
    return CRITERIA[key](measures, **used)


def weighted_sum(measures: Measures, weights: Mapping[str, float], **targets: float) -> jax.Array:
    """Multi-objective fitness sum_i w_i C_i (eq. 2.47, 2.52, 2.55), maximised.

    E.g. ``{"distance": 1, "energy": alpha, "angles": beta}`` is F = d - alpha E +
    beta C_angles (the energy criterion is already -E).
    """
    total = 0.0
    for name, w in weights.items():
        total = total + w * criterion(name, measures, **targets)
    return jnp.asarray(total)


# ----------------------------------------------------------------------------- stopping


@struct.dataclass
class StopCriteria:
    """Stopping criteria of a rollout (thesis 2.2.2); a limit of ``inf`` is disabled.

    A pytree, so it can be closed over as constants or passed (and vmapped) as an argument.

    Attributes:
      d_lim: distance limit [m] (stop once the distance reaches it).
      t_lim: time limit [s].
      e_lim: metabolic energy limit [J].
    """

    d_lim: float = math.inf
    t_lim: float = math.inf
    e_lim: float = math.inf

    def __post_init__(self):
        # Only plain numbers are checked: leaves may also be arrays, tracers or vmap specs.
        for name in ("d_lim", "t_lim", "e_lim"):
            v = getattr(self, name)
            if isinstance(v, (int, float)) and not v >= 0:
                raise ValueError(f"StopCriteria.{name} must be >= 0 (inf to disable), got {v}")

    @classmethod
    def human_energy(cls, distance_m: float, j_per_m: float = HUMAN_WALKING_J_PER_M):
        """Energy limit of a human covering ``distance_m`` (210 J/m, 70 kg at 1.3 m/s)."""
        return cls(e_lim=float(distance_m) * j_per_m)


def should_stop(
    stop: StopCriteria, distance: jax.Array, time: jax.Array, energy: jax.Array
) -> jax.Array:
    """() bool: any limit reached (distance >= d_lim, time >= t_lim or energy >= e_lim)."""
    return (
        (jnp.asarray(distance) >= stop.d_lim)
        | (jnp.asarray(time) >= stop.t_lim)
        | (jnp.asarray(energy) >= stop.e_lim)
    )
