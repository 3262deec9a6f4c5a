"""Gait measures of one rollout, computed in JAX from its :class:`~jaxgait.sim.trace.Trace`,
:class:`~jaxgait.sim.trace.Events` and :class:`~jaxgait.sim.trace.Summary` (thesis 2.2.2-2.2.3).

Every function here has fixed output shapes and no Python branching on traced values, so a
batch of rollouts is measured with ``jax.vmap(compute_measures)`` inside ``jit``. Undefined
quantities (no steps, no full cycle, zero duration) give documented finite sentinels, never
NaN. :func:`compute_measures` and :func:`gait_cycle_curves` are jitted with their
configuration (``skip``, the reference curves, ``pct``, ``leg``, ``n_cycles``) static; bind
it with ``functools.partial`` before ``vmap``, which would otherwise map keyword arguments.

Conventions (see :mod:`jaxgait.sim.trace`): leg 0 = right, 1 = left; ``qpos`` columns 3, 4, 5
are the right hip flexion, knee flexion and ankle dorsiflexion [rad]. ``trace.alive`` is
assumed to be a prefix of the trace (the rollout runs, then stops).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.analysis import refdata
from jaxgait.muscles import energy as energy_mod
from jaxgait.sim.trace import Events, Summary, Trace

#: Gravitational acceleration used for body weights and the dimensionless cost [m/s^2].
G = 9.81
#: qpos columns of (hip, knee, ankle) per leg, leg 0 = right, 1 = left.
LEG_ANGLE_QPOS = ((3, 4, 5), (6, 7, 8))
#: Step-length variance floor in the SNR, eq. 2.53 [m^2] (SD of 1 mm).
VAR_FLOOR = 1e-6
#: Step-length mean floor in the SNR, eq. 2.53 [m] (keeps the log finite for mean <= 0).
MEAN_FLOOR = 1e-6
#: SNR reported when fewer than two steps are available: below the SNR of any run with two
#: or more steps shorter than 10 m (log(1e-6) - log(100) = -18.4).
SNR_UNDEFINED = -20.0
#: Correlation reported when the trace holds no full gait cycle.
CORR_UNDEFINED = 0.0
#: Standard score without a full cycle (a finite sentinel far above any real score).
SCORE_UNDEFINED = 99.0
_TINY = 1e-9

#: Every key returned by :func:`compute_measures` and its unit ("-" dimensionless,
#: "bool", "count"); E is the event capacity, N the reference curve length.
MEASURE_UNITS: dict[str, str] = {
    "distance_m": "m",
    "duration_s": "s",
    "fell": "bool",
    "mass_kg": "kg",
    "mean_speed_mps": "m/s",
    "n_steps": "count",
    "n_steps_used": "count",
    "n_cycles": "count",
    "step_lengths_m": "m, shape (E,)",
    "step_valid": "bool, shape (E,)",
    "step_length_mean_m": "m",
    "step_length_var_m2": "m^2",
    "step_length_sd_m": "m",
    "step_length_snr": "-",
    "step_length_right_mean_m": "m",
    "step_length_right_var_m2": "m^2",
    "n_steps_right": "count",
    "step_length_left_mean_m": "m",
    "step_length_left_var_m2": "m^2",
    "n_steps_left": "count",
    "double_stance_fraction": "-",
    "flight_fraction": "-",
    "cycle_frequency_hz": "Hz",
    "energy_J": "J",
    "energy_J_per_m": "J/m",
    "cost_of_transport": "J/(kg m)",
    "cost_of_transport_dimless": "-",
    "grf_peak_max_bw": "BW",
    "grf_peak_mean_bw": "BW",
    "grf_peak_time_mean_s": "s",
    "grf_loading_rate_max_bw_s": "BW/s",
    "n_stances_measured": "count",
    "grf_corr": "-",
    "rom_hip_deg": "deg",
    "rom_knee_deg": "deg",
    "rom_ankle_deg": "deg",
    "rom_hip_diff_deg": "deg",
    "rom_knee_diff_deg": "deg",
    "rom_ankle_diff_deg": "deg",
    "metabolic_power_W": "W",
    "effort_J_M_W": "W",
    "effort_J_L": "N^2 m^2",
    "effort": "-",
    "mean_trunk_lean_rad": "rad",
    "mean_trunk_lean_trace_rad": "rad",
    "corr_hip": "-",
    "corr_knee": "-",
    "corr_ankle": "-",
    "c_angles": "-",
    "standard_score_hip": "-",
    "standard_score_knee": "-",
    "standard_score_ankle": "-",
    "standard_score": "-",
    "mean_cycle_corr_hip": "-",
    "mean_cycle_corr_knee": "-",
    "mean_cycle_corr_ankle": "-",
    "mean_cycle_standard_score": "-",
    "n_mean_cycles": "-",
    "cycle_valid": "bool",
    "cycle_angles_deg": "deg, shape (N, 3)",
    "cycle_start_s": "s",
    "cycle_end_s": "s",
}


# ----------------------------------------------------------------------------- helpers


def _recorded(events: Events, skip: int = 0) -> jax.Array:
    """(E,) bool: event was recorded (index < min(n, E)) and is not among the first ``skip``."""
    e = events.t.shape[0]
    idx = jnp.arange(e)
    return (idx < jnp.minimum(events.n, e)) & (idx >= skip)


def masked_mean_var(x: jax.Array, mask: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Mean, population variance (eq. 2.50, 1/N) and count of ``x[mask]``; 0, 0, 0 if empty."""
    cnt = jnp.sum(mask.astype(jnp.int32))
    c = jnp.maximum(cnt, 1).astype(x.dtype)
    mean = jnp.sum(jnp.where(mask, x, 0.0)) / c
    var = jnp.sum(jnp.where(mask, (x - mean) ** 2, 0.0)) / c
    return mean, var, cnt


def snr(mean: jax.Array, var: jax.Array, count: jax.Array) -> jax.Array:
    """Signal-to-noise ratio log(mean / var) of eq. 2.53, guarded.

    ``mean`` is floored at :data:`MEAN_FLOOR` and ``var`` at :data:`VAR_FLOOR`, so the value
    is finite and saturates at log(mean / 1e-6) for a perfectly regular gait. With fewer than
    two samples the SNR is :data:`SNR_UNDEFINED`.
    """
    val = jnp.log(jnp.maximum(mean, MEAN_FLOOR)) - jnp.log(jnp.maximum(var, VAR_FLOOR))
    return jnp.where(count >= 2, val, SNR_UNDEFINED).astype(jnp.result_type(mean))


def step_lengths(events: Events, skip: int = 2) -> tuple[jax.Array, jax.Array]:
    """Step length at each touchdown and which entries are usable.

    The step length of event k is ``x_td[k] - x_other[k]``: the horizontal distance from the
    trailing ankle to the ankle of the leg touching down [m].

    Args:
      events: touchdown events.
      skip: number of leading events ignored as start-up transients (static).

    Returns:
      (E,) step lengths [m] (0 where unusable) and (E,) bool mask of usable events
      (recorded, index < min(n, E), and index >= skip).
    """
    valid = _recorded(events, skip)
    return jnp.where(valid, events.x_td - events.x_other, 0.0), valid


def human_likeness(
    trace: Trace,
    events: Events,
    weight,
    cycle_angles_deg,
    cycle_valid,
    reference: refdata.Kinematics,
    grf_reference: refdata.VerticalGRF | None = None,
) -> dict[str, jax.Array]:
    """Gait measures against Winter's walking beyond the angle correlations: the right leg's
    vertical GRF over its last full cycle (the decimated trace, in body weights) correlated
    with Winter's (``grf_corr``), and the ranges of motion of hip, knee and ankle over that
    cycle minus the reference's (``rom_*_diff_deg``; ``rom_*_deg`` the model's).

    Without a full cycle ``grf_corr`` is :data:`CORR_UNDEFINED` and the ranges are 0.
    """
    ref_grf = refdata.winter_walking_grf() if grf_reference is None else grf_reference
    bw = jnp.maximum(jnp.asarray(weight, trace.t.dtype), _TINY)
    curves, valid = gait_cycle_curves(
        trace, events, trace.grf[:, 0, 1] / bw, ref_grf.gait_cycle_pct
    )
    r = pearson(curves[0], jnp.asarray(ref_grf.mean_bw, curves.dtype))
    ang = jnp.asarray(cycle_angles_deg)
    rom = jnp.max(ang, axis=0) - jnp.min(ang, axis=0)
    ref_mean = jnp.asarray(reference.mean_deg, ang.dtype)
    rom_ref = jnp.max(ref_mean, axis=0) - jnp.min(ref_mean, axis=0)
    ok = jnp.asarray(cycle_valid)
    out = {"grf_corr": jnp.where(valid[0], r, CORR_UNDEFINED)}
    for j, name in enumerate(("hip", "knee", "ankle")):
        out[f"rom_{name}_deg"] = jnp.where(ok, rom[j], 0.0)
        out[f"rom_{name}_diff_deg"] = jnp.where(ok, rom[j] - rom_ref[j], 0.0)
    return out


def stance_grf_peaks(events: Events, weight, skip: int = 2) -> dict[str, jax.Array]:
    """Per-stance vertical-GRF peaks measured at the physics step (``Events.peak_grf``,
    ``peak_t``, ``loading_rate``), over the recorded stances after the first ``skip``.

    Args:
      events: touchdown events of a planar rollout.
      weight: body weight m g [N]; forces are reported in body weights (BW).
      skip: leading stances ignored as start-up transients (static).

    Returns:
      ``grf_peak_max_bw`` (the largest stance peak), ``grf_peak_mean_bw`` [BW],
      ``grf_peak_time_mean_s`` [s] (mean time of the peak after touchdown),
      ``grf_loading_rate_max_bw_s`` [BW/s] (largest one-step rise of any stance) and
      ``n_stances_measured``; all 0 without a measured stance or when the buffer has no peaks.
    """
    valid = _recorded(events, skip)
    n = jnp.sum(valid.astype(jnp.int32))
    if events.peak_grf is None:  # a hand-made buffer without the per-stance fields
        z = jnp.zeros((), events.t.dtype)
        return {
            "grf_peak_max_bw": z,
            "grf_peak_mean_bw": z,
            "grf_peak_time_mean_s": z,
            "grf_loading_rate_max_bw_s": z,
            "n_stances_measured": jnp.zeros((), jnp.int32),
        }
    bw = jnp.maximum(jnp.asarray(weight, events.t.dtype), _TINY)
    peak = jnp.where(valid, events.peak_grf, 0.0) / bw
    mean_peak, _, _ = masked_mean_var(peak, valid)
    mean_t, _, _ = masked_mean_var(jnp.where(valid, events.peak_t, 0.0), valid)
    rate = jnp.where(valid, events.loading_rate, 0.0) / bw
    return {
        "grf_peak_max_bw": jnp.max(peak),
        "grf_peak_mean_bw": mean_peak,
        "grf_peak_time_mean_s": mean_t,
        "grf_loading_rate_max_bw_s": jnp.where(n > 0, jnp.max(rate), 0.0),
        "n_stances_measured": n,
    }


def last_touchdowns(events: Events, leg: int, k: int) -> tuple[jax.Array, jax.Array]:
    """Times of the last ``k`` recorded touchdowns of ``leg``, latest first.

    Returns:
      (k,) times [s] (0 where missing) and (k,) bool, that touchdown exists.
    """
    mask = _recorded(events) & (events.leg == leg)
    rank = jnp.cumsum(mask.astype(jnp.int32)) - 1
    want = jnp.sum(mask.astype(jnp.int32)) - 1 - jnp.arange(k)
    hit = mask[None, :] & (rank[None, :] == want[:, None])
    times = jnp.sum(jnp.where(hit, events.t[None, :], 0.0), axis=1)
    return times, want >= 0


def _time_base(trace: Trace) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Strictly increasing sample times and the alive time span.

    Rows after the end of the rollout get times t_end + 1 s, t_end + 2 s, ... so that
    interpolation inside the alive span never reads them.
    """
    t, alive = trace.t, trace.alive.astype(bool)
    idx = jnp.arange(t.shape[0])
    i_last = jnp.max(jnp.where(alive, idx, -1))
    any_alive = i_last >= 0
    t_last = jnp.where(any_alive, jnp.max(jnp.where(alive, t, -jnp.inf)), 0.0)
    t_first = jnp.where(any_alive, jnp.min(jnp.where(alive, t, jnp.inf)), 0.0)
    xp = jnp.where(alive, t, t_last + (idx - i_last).astype(t.dtype))
    return xp, t_first.astype(t.dtype), t_last.astype(t.dtype)


def _pct_array(pct) -> np.ndarray:
    if isinstance(pct, int):
        return np.linspace(0.0, 100.0, pct)
    return np.asarray(pct, dtype=np.float64)


# ----------------------------------------------------------------------------- cycles


def _interp_rows(tq: jax.Array, xp: jax.Array, fp: jax.Array) -> jax.Array:
    """Linear interpolation of every column of ``fp`` (T, F) at times ``tq`` (...,) -> (..., F).

    ``xp`` must increase strictly and ``tq`` lie within it; one index search serves all
    columns.
    """
    if xp.shape[0] == 1:
        return jnp.broadcast_to(fp[0], tq.shape + fp.shape[1:])
    i = jnp.clip(jnp.searchsorted(xp, tq, side="right"), 1, xp.shape[0] - 1)
    x0, x1 = xp[i - 1], xp[i]
    w = jnp.clip((tq - x0) / jnp.maximum(x1 - x0, _TINY), 0.0, 1.0)[..., None]
    return fp[i - 1] * (1.0 - w) + fp[i] * w


def gait_cycle_curves(
    trace: Trace,
    events: Events,
    channel: jax.Array,
    pct,
    *,
    leg: int = 0,
    n_cycles: int = 1,
) -> tuple[jax.Array, jax.Array]:
    """Resample any trace channel over the last full gait cycles of ``leg``.

    A cycle runs from one recorded touchdown of ``leg`` to its next one; cycle 0 is the last
    full cycle. Each is sampled (linear interpolation in time) at the instants ``pct``
    percent of the way through it, e.g. the ``gait_cycle_pct`` of a :mod:`jaxgait.analysis.refdata`
    curve, so that model and human curves have the same length (thesis 2.2.3,
    eq. 2.48-2.51). Times are clamped to the alive span of the trace.

    Args:
      trace: the rollout trace (T rows).
      events: touchdown events.
      channel: (T, ...) any per-sample quantity, e.g. ``trace.qpos[:, 3]``,
        ``trace.grf[:, 0, 1]`` or ``trace.act[:, 0, :]``.
      pct: (N,) percentages of the cycle (static), or an int N for N points over 0..100.
      leg: 0 right, 1 left (static).
      n_cycles: number of cycles, counted back from the last (static).

    Returns:
      (n_cycles, N, ...) curves (0 for a cycle that does not exist) and (n_cycles,) bool,
      the cycle exists.
    """
    pct_t = tuple(float(x) for x in _pct_array(pct))
    return _gait_cycle_curves(trace, events, channel, pct_t, leg, n_cycles)


@functools.partial(jax.jit, static_argnums=(3, 4, 5))
def _gait_cycle_curves(trace, events, channel, pct, leg, n_cycles):
    p = jnp.asarray(pct, dtype=trace.t.dtype) / 100.0
    times, exists = last_touchdowns(events, leg, n_cycles + 1)
    start, end = times[1:], times[:-1]
    valid = exists[1:] & (end > start)
    xp, t_first, t_last = _time_base(trace)
    tq = jnp.clip(start[:, None] + p[None, :] * (end - start)[:, None], t_first, t_last)

    shape = channel.shape
    fp = jnp.where(trace.alive.astype(bool)[:, None], channel.reshape(shape[0], -1), 0.0)
    curves = _interp_rows(tq, xp, fp)  # (n_cycles, N, F)
    curves = jnp.where(valid[:, None, None], curves, 0.0)
    return curves.reshape((n_cycles, p.shape[0]) + shape[1:]), valid


def mean_gait_cycle(
    trace: Trace,
    events: Events,
    channel: jax.Array,
    pct,
    *,
    leg: int = 0,
    n_cycles: int = 1,
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Mean and SD across the last ``n_cycles`` full cycles of a channel (for plots).

    With the default ``n_cycles=1`` this is the last full cycle itself (SD 0).

    Returns:
      (N, ...) mean, (N, ...) SD (population) over existing cycles (0 if none) and () int
      number of cycles used.
    """
    pct_t = tuple(float(x) for x in _pct_array(pct))
    return _mean_gait_cycle(trace, events, channel, pct_t, leg, n_cycles)


@functools.partial(jax.jit, static_argnums=(3, 4, 5))
def _mean_gait_cycle(trace, events, channel, pct, leg, n_cycles):
    curves, valid = _gait_cycle_curves(trace, events, channel, pct, leg, n_cycles)
    w = valid.reshape((-1,) + (1,) * (curves.ndim - 1)).astype(curves.dtype)
    n = jnp.sum(valid.astype(jnp.int32))
    c = jnp.maximum(n, 1).astype(curves.dtype)
    mean = jnp.sum(w * curves, axis=0) / c
    var = jnp.sum(w * (curves - mean) ** 2, axis=0) / c
    return mean, jnp.sqrt(var), n


def pearson(x: jax.Array, y: jax.Array) -> jax.Array:
    """Pearson correlation along axis 0 (eq. 2.48), in [-1, 1]; 0 if either is constant.

    Eq. 2.49 and 2.50 normalise covariance and variance by N-1 and N; that would make a
    perfect match score N/(N-1) > 1, so the same normalisation is used for both.
    """
    xm = x - jnp.mean(x, axis=0)
    ym = y - jnp.mean(y, axis=0)
    cov = jnp.sum(xm * ym, axis=0)
    den = jnp.sqrt(jnp.sum(xm**2, axis=0) * jnp.sum(ym**2, axis=0))
    r = jnp.where(den > _TINY, cov / jnp.maximum(den, _TINY), 0.0)
    return jnp.clip(r, -1.0, 1.0)


def standard_scores(curves_deg, reference: refdata.Kinematics) -> jax.Array:
    """Wang et al. 2012 Table 1's standard score per joint: the mean over the cycle's samples
    of |model - human mean| / human SD, (..., 3) for (hip, knee, ankle).

    ``curves_deg`` (..., N, 3) [deg] sampled at ``reference.gait_cycle_pct`` (N = 51 for
    Winter's walking data at 2 % steps, Wang uses 100 points of the same curves: the mean of a
    smooth curve's deviation differs little).  A score of 1 means one SD off on average.
    """
    mean = jnp.asarray(reference.mean_deg, jnp.asarray(curves_deg).dtype)
    sd = jnp.stack(
        [
            jnp.asarray(getattr(reference, f"{j}_sd_deg"), mean.dtype)
            for j in ("hip", "knee", "ankle")
        ],
        -1,
    )
    return jnp.mean(jnp.abs(jnp.asarray(curves_deg) - mean) / sd, axis=-2)


#: Cycles averaged by the ``mean_cycle_*`` measures (:func:`joint_angle_correlations`).
MEAN_CYCLES = 5


def joint_angle_correlations(
    trace: Trace,
    events: Events,
    reference: refdata.Kinematics | None = None,
    *,
    leg: int = 0,
) -> dict[str, jax.Array]:
    """Correlation of the last full cycle's joint angles with a human reference (eq. 2.48-2.51).

    The hip, knee and ankle angles of ``leg`` (``qpos`` columns 3-5 for the right leg,
    converted to degrees) are sampled over the last full cycle at the reference's
    ``gait_cycle_pct`` and correlated with the reference mean.

    Args:
      trace, events: the rollout.
      reference: human curves (static); default Winter normal walking.
      leg: 0 right (default), 1 left (static).

    Returns:
      ``corr_hip``, ``corr_knee``, ``corr_ankle`` (Pearson, in [-1, 1]), ``c_angles`` = their
      minimum (eq. 2.51), ``standard_score_hip``, ``_knee``, ``_ankle`` and their mean
      ``standard_score`` (:func:`standard_scores`; :data:`SCORE_UNDEFINED` without a full
      cycle), ``cycle_valid`` (bool), ``cycle_angles_deg`` (N, 3) the resampled
      model angles [deg], ``cycle_start_s``, ``cycle_end_s`` [s]. Without a full cycle the
      correlations and ``c_angles`` are :data:`CORR_UNDEFINED` (0).  The same of the mean
      curve of the last :data:`MEAN_CYCLES` full cycles (``n_mean_cycles`` of them exist):
      ``mean_cycle_corr_hip``, ``_knee``, ``_ankle`` and ``mean_cycle_standard_score``; a
      gait whose cycles differ has a last cycle that scores by chance, the mean less so.
    """
    ref = refdata.winter_walking_kinematics() if reference is None else reference
    ang = jnp.rad2deg(trace.qpos[:, jnp.array(LEG_ANGLE_QPOS[leg])])
    curves, valid = gait_cycle_curves(trace, events, ang, ref.gait_cycle_pct, leg=leg)
    model = curves[0]
    human = jnp.asarray(ref.mean_deg, dtype=model.dtype)
    r = jnp.where(valid[0], pearson(model, human), CORR_UNDEFINED)
    times, _ = last_touchdowns(events, leg, 2)
    z = standard_scores(model, ref)
    z = jnp.where(valid[0], z, SCORE_UNDEFINED)
    # the mean cycle of the last MEAN_CYCLES (those that exist), as a gait lab averages strides
    many, ok = gait_cycle_curves(
        trace, events, ang, ref.gait_cycle_pct, leg=leg, n_cycles=MEAN_CYCLES
    )
    w = ok.astype(many.dtype)[:, None, None]
    mean_curve = jnp.sum(many * w, axis=0) / jnp.maximum(jnp.sum(w, axis=0), 1.0)
    r_mc = jnp.where(valid[0], pearson(mean_curve, human), CORR_UNDEFINED)
    z_mc = jnp.where(valid[0], standard_scores(mean_curve, ref), SCORE_UNDEFINED)
    return {
        "mean_cycle_corr_hip": r_mc[0],
        "mean_cycle_corr_knee": r_mc[1],
        "mean_cycle_corr_ankle": r_mc[2],
        "mean_cycle_standard_score": jnp.mean(z_mc),
        "n_mean_cycles": jnp.sum(ok.astype(jnp.int32)),
        "standard_score_hip": z[0],
        "standard_score_knee": z[1],
        "standard_score_ankle": z[2],
        "standard_score": jnp.mean(z),
        "corr_hip": r[0],
        "corr_knee": r[1],
        "corr_ankle": r[2],
        "c_angles": jnp.min(r),
        "cycle_valid": valid[0],
        "cycle_angles_deg": model,
        "cycle_start_s": jnp.where(valid[0], times[1], 0.0),
        "cycle_end_s": jnp.where(valid[0], times[0], 0.0),
    }


# ----------------------------------------------------------------------------- all measures


def compute_measures(
    trace: Trace,
    events: Events,
    summary: Summary,
    *,
    reference: refdata.Kinematics | None = None,
    grf_reference: refdata.VerticalGRF | None = None,
    skip: int = 2,
) -> dict[str, jax.Array]:
    """All gait measures of one rollout (SPEC §3; thesis 2.2.2, Table 2.7).

    Args:
      trace, events, summary: the rollout record (one individual; ``vmap`` for a batch).
      reference: human joint-angle curves for the correlations (static); default Winter
        normal walking (:func:`jaxgait.analysis.refdata.winter_walking_kinematics`).
      grf_reference: human vertical GRF for ``grf_corr`` (static); default Winter's walking
        (:func:`jaxgait.analysis.refdata.gait_reference` gives both of one gait).
      skip: leading touchdown events ignored as start-up transients for the step-length,
        cycle-frequency and double-stance measures (static).

    Returns:
      A dict of arrays (scalars unless noted; keys and units also in
      :data:`MEASURE_UNITS`):

      * ``distance_m`` [m]: forward displacement of the centre of mass (d).
      * ``duration_s`` [s]: time simulated before the end (t).
      * ``fell`` (bool): the rollout ended by a fall.
      * ``mass_kg`` [kg]: body mass.
      * ``mean_speed_mps`` [m/s]: distance / duration (v).
      * ``n_steps`` (int): touchdowns of either leg during the whole run (``events.n``).
      * ``n_steps_used`` (int): recorded touchdowns after the first ``skip``.
      * ``n_cycles`` (int): full right-leg cycles among the recorded events (c).
      * ``step_lengths_m`` (E,) [m]: x_td - x_other per event (0 where unusable).
      * ``step_valid`` (E,) bool: the event enters the step-length statistics.
      * ``step_length_mean_m`` [m], ``step_length_var_m2`` [m^2] (eq. 2.50, 1/N),
        ``step_length_sd_m`` [m]: over usable steps of both legs (0 if none).
      * ``step_length_snr`` [-]: log(mean / var), eq. 2.53-2.54, guarded (see :func:`snr`);
        :data:`SNR_UNDEFINED` with fewer than 2 usable steps.
      * ``step_length_left_mean_m``, ``step_length_right_mean_m`` [m],
        ``step_length_left_var_m2``, ``step_length_right_var_m2`` [m^2],
        ``n_steps_left``, ``n_steps_right`` (int): the same per touching-down leg.
      * ``double_stance_fraction`` [-]: fraction of alive samples, from the touchdown of
        event ``skip`` on (all alive samples if there is none), with both legs in stance.
      * ``flight_fraction`` [-]: fraction of the same samples with neither leg in stance
        (the flight phases of running; 0 in walking).
      * ``cycle_frequency_hz`` [Hz]: right-leg touchdowns per second, (k - 1) / (t_k - t_1)
        over the k usable right touchdowns; 0 if k < 2.
      * ``energy_J`` [J]: metabolic energy spent (E).
      * ``energy_J_per_m`` [J/m]: energy / distance (distance floored at 1 mm).
      * ``cost_of_transport`` [J/(kg m)]: energy / (mass distance).
      * ``cost_of_transport_dimless`` [-]: energy / (mass g distance), g = 9.81 m/s^2.
      * ``metabolic_power_W`` [W]: energy / duration, the mean metabolic power of the muscles
        (the rollout's metabolic model, :attr:`jaxgait.sim.model.Model.metabolic`).
      * ``effort_J_M_W`` [W], ``effort_J_L`` [N^2 m^2], ``effort`` [-]: Wang et al. 2012
        section 5.1: J_M = 1.51 W/kg x mass + metabolic power, J_L the mean summed squared
        soft-limit torque, and J_effort = 100 J_M + 0.5 J_L (J_R = 0 in the planar model),
        :func:`jaxgait.muscles.energy.wang_effort` over the rollout.
      * ``grf_peak_max_bw``, ``grf_peak_mean_bw`` [BW], ``grf_peak_time_mean_s`` [s],
        ``grf_loading_rate_max_bw_s`` [BW/s], ``n_stances_measured``: per-stance vertical
        GRF peaks at the physics step, :func:`stance_grf_peaks`.
      * ``grf_corr`` [-]: the right vertical GRF over the last full cycle against ``grf_reference``;
        ``rom_hip_deg``, ``rom_knee_deg``, ``rom_ankle_deg`` [deg] the ranges of motion over
        that cycle and ``rom_hip_diff_deg``, ``rom_knee_diff_deg``, ``rom_ankle_diff_deg``
        [deg] minus the reference's (:func:`human_likeness`).
      * ``mean_trunk_lean_rad`` [rad]: ``trunk_lean_sum / duration`` (forward lean +).
      * ``mean_trunk_lean_trace_rad`` [rad]: mean of ``qpos[:, 2]`` over alive samples.
      * ``standard_score_hip``, ``standard_score_knee``, ``standard_score_ankle``,
        ``standard_score`` [-]: Wang 2012 Table 1's standard scores (:func:`standard_scores`)
        of the same cycle.
      * ``c_angles``, ``corr_hip``, ``corr_knee``, ``corr_ankle`` [-], ``cycle_valid``,
        ``cycle_angles_deg`` (N, 3) [deg], ``cycle_start_s``, ``cycle_end_s`` [s]: see
        :func:`joint_angle_correlations` (right leg, last full cycle).
      * ``mean_cycle_corr_hip``, ``mean_cycle_corr_knee``, ``mean_cycle_corr_ankle``,
        ``mean_cycle_standard_score`` [-], ``n_mean_cycles``: the same of the mean curve of
        the last :data:`MEAN_CYCLES` full cycles (:func:`joint_angle_correlations`).
    """
    ref = refdata.winter_walking_kinematics() if reference is None else reference
    grf = refdata.winter_walking_grf() if grf_reference is None else grf_reference
    return _compute_measures(trace, events, summary, ref, grf, int(skip))


@functools.partial(jax.jit, static_argnums=(3, 4, 5))
def _compute_measures(trace, events, summary, reference, grf_reference, skip):
    f = trace.t.dtype
    duration = summary.duration.astype(f)
    distance = summary.distance.astype(f)
    energy = summary.energy.astype(f)
    mass = summary.mass.astype(f)
    dur = jnp.maximum(duration, _TINY)
    dist = jnp.maximum(distance, 1e-3)

    sl, valid = step_lengths(events, skip)
    sl = sl.astype(f)
    mean, var, cnt = masked_mean_var(sl, valid)
    side = {}
    for leg, name in ((0, "right"), (1, "left")):
        m, v, c = masked_mean_var(sl, valid & (events.leg == leg))
        side[f"step_length_{name}_mean_m"] = m
        side[f"step_length_{name}_var_m2"] = v
        side[f"n_steps_{name}"] = c

    # Right-leg cycle frequency over the usable events.
    right = valid & (events.leg == 0)
    k = jnp.sum(right.astype(jnp.int32))
    t_lo = jnp.min(jnp.where(right, events.t, jnp.inf))
    t_hi = jnp.max(jnp.where(right, events.t, -jnp.inf))
    span = jnp.where(k >= 2, t_hi - t_lo, 1.0)
    freq = jnp.where((k >= 2) & (span > 0), (k - 1) / jnp.maximum(span, _TINY), 0.0).astype(f)
    n_right = jnp.sum((_recorded(events) & (events.leg == 0)).astype(jnp.int32))

    # Double stance from the first usable touchdown on.
    e = events.t.shape[0]
    has_start = (skip < e) & (skip < events.n)
    t_start = jnp.where(has_start, events.t[min(skip, e - 1)], -jnp.inf)
    alive = trace.alive.astype(bool)
    stance = trace.stance.astype(bool)
    window = alive & (trace.t >= t_start)
    both = stance[:, 0] & stance[:, 1]
    n_win = jnp.sum(window.astype(jnp.int32))
    ds = jnp.sum((window & both).astype(jnp.int32)) / jnp.maximum(n_win, 1)
    neither = ~stance[:, 0] & ~stance[:, 1]
    flight = jnp.sum((window & neither).astype(jnp.int32)) / jnp.maximum(n_win, 1)

    n_alive = jnp.sum(alive.astype(jnp.int32))
    lean_trace = jnp.sum(jnp.where(alive, trace.qpos[:, 2], 0.0)) / jnp.maximum(n_alive, 1)

    # Wang's effort terms from the rollout's integrals (section 5.1; J_R = 0 here)
    w_m, _, w_l = energy_mod.WANG_WEIGHTS
    power = jnp.where(duration > 0, energy / dur, 0.0)
    j_m = energy_mod.basal_rate(mass) + power
    j_l = jnp.where(duration > 0, jnp.asarray(summary.limit_torque_sq, f) / dur, 0.0)

    out = {
        "distance_m": distance,
        "duration_s": duration,
        "fell": summary.fell.astype(bool),
        "mass_kg": mass,
        "mean_speed_mps": jnp.where(duration > 0, distance / dur, 0.0),
        "n_steps": events.n.astype(jnp.int32),
        "n_steps_used": cnt,
        "n_cycles": jnp.maximum(n_right - 1, 0),
        "step_lengths_m": sl,
        "step_valid": valid,
        "step_length_mean_m": mean,
        "step_length_var_m2": var,
        "step_length_sd_m": jnp.sqrt(var),
        "step_length_snr": snr(mean, var, cnt),
        **side,
        "double_stance_fraction": ds.astype(f),
        "flight_fraction": flight.astype(f),
        "cycle_frequency_hz": freq,
        "energy_J": energy,
        "energy_J_per_m": energy / dist,
        "cost_of_transport": energy / (jnp.maximum(mass, _TINY) * dist),
        "cost_of_transport_dimless": energy / (jnp.maximum(mass, _TINY) * G * dist),
        "metabolic_power_W": power,
        "effort_J_M_W": j_m,
        "effort_J_L": j_l,
        "effort": w_m * j_m + w_l * j_l,
        "mean_trunk_lean_rad": jnp.where(duration > 0, summary.trunk_lean_sum.astype(f) / dur, 0.0),
        "mean_trunk_lean_trace_rad": lean_trace.astype(f),
    }
    out.update(joint_angle_correlations(trace, events, reference))
    out.update(stance_grf_peaks(events, mass * G, skip))
    out.update(
        human_likeness(
            trace,
            events,
            mass * G,
            out["cycle_angles_deg"],
            out["cycle_valid"],
            reference,
            grf_reference,
        )
    )
    return out
