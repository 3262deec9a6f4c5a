"""Figures of one rollout against human walking references (PNG files).

Every function draws on its own :class:`matplotlib.figure.Figure` rendered by the Agg
backend (pyplot and its global state are not used), saves a PNG and returns its path.

* :func:`plot_joint_angles`: right hip / knee / ankle angles over the gait cycle [deg],
  mean +- SD over the last ``n_cycles`` cycles, against Winter's mean +- SD band;
* :func:`plot_grf`: right vertical ground reaction force over the cycle [BW] vs Winter;
* :func:`plot_activations`: right-leg activations over the cycle vs walking EMG envelopes,
  each curve scaled to its own peak (shape and timing comparison only);
* :func:`plot_stick_figure`: the body every ~40 ms during the last full right-leg cycle;
* :func:`plot_all`: the four figures into one folder.

A gait cycle runs from a right touchdown to the next one (:mod:`jaxgait.analysis.measures`). A
rollout without a full cycle (e.g. an early fall) is still drawn: the cycle figures then
show the model against time on a secondary axis, the stick figure shows the last alive
second, and the title says so.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from jaxgait.analysis import refdata
from jaxgait.muscles.mtu import MUSCLES

G = 9.81
#: Colours of the right and left legs.
RIGHT, LEFT = "tab:red", "tab:blue"
MODEL_COLOR, REF_COLOR = "tab:red", "0.55"


# ------------------------------------------------------------------------------ helpers


def _np(x) -> np.ndarray:
    return np.asarray(x)


def _alive(trace) -> np.ndarray:
    return _np(trace.alive).astype(bool).reshape(-1)


def _end_text(trace) -> str:
    a = _alive(trace)
    if not a.any():
        return "no alive samples"
    return f"run ended at t = {float(_np(trace.t)[a][-1]):.2f} s"


def _touchdowns(events, leg: int = 0) -> np.ndarray:
    """Recorded touchdown times of ``leg`` in chronological order [s]."""
    t = _np(events.t).astype(float).reshape(-1)
    n = min(int(_np(events.n)), t.shape[0])
    legs = _np(events.leg).reshape(-1)[:n]
    return t[:n][legs == leg]


def _cycles(trace, events, n_cycles: int) -> list[tuple[float, float]]:
    """Last ``n_cycles`` full right-leg cycles (start, end) [s] inside the alive span, latest last.

    Same cycle definition as :func:`jaxgait.analysis.measures.gait_cycle_curves`; a cycle must also
    lie within the alive samples (touchdowns after a fall do not make a cycle).
    """
    alive = _alive(trace)
    if not alive.any():
        return []
    t = _np(trace.t).astype(float)[alive]
    tol = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    td = _touchdowns(events, 0)
    out = [
        (a, b)
        for a, b in zip(td[:-1], td[1:], strict=True)
        if b > a and a >= t[0] - tol and b <= t[-1] + tol
    ]
    return out[-max(int(n_cycles), 1) :]


def _cycle_stats(trace, events, channel, pct, n_cycles: int):
    """Mean, SD (N, ...) of ``channel`` over the last ``n_cycles`` right cycles and their number.

    Each cycle is resampled (linear interpolation in time) at ``pct`` percent of its span.
    """
    pct = np.asarray(pct, float) / 100.0
    ch = _np(channel).astype(float)
    shape = ch.shape[1:]
    cycles = _cycles(trace, events, n_cycles)
    if not cycles:
        z = np.zeros((pct.size,) + shape)
        return z, z, 0
    alive = _alive(trace)
    t = _np(trace.t).astype(float)[alive]
    fp = ch[alive].reshape(t.size, -1)
    curves = []
    for a, b in cycles:
        tq = np.clip(a + pct * (b - a), t[0], t[-1])
        curves.append(np.stack([np.interp(tq, t, fp[:, j]) for j in range(fp.shape[1])], -1))
    c = np.stack(curves).reshape((len(cycles), pct.size) + shape)
    return c.mean(0), c.std(0), len(cycles)


#: Public name of the cycle statistics used by the figures of other packages.
cycle_stats = _cycle_stats


def _pearson(x: np.ndarray, y: np.ndarray) -> float:
    """Pearson correlation of two curves (0 if either is constant), as in measures.pearson."""
    xm, ym = x - x.mean(), y - y.mean()
    den = float(np.sqrt(np.sum(xm**2) * np.sum(ym**2)))
    return float(np.clip(np.sum(xm * ym) / den, -1, 1)) if den > 1e-9 else 0.0


def _save(fig: Figure, path) -> Path:
    path = Path(path)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=100)
    return path


def _time_axis(ax, t, y, color, label=None):
    """Model samples against time on a top axis (used when there is no full cycle)."""
    ax2 = ax.twiny()
    if t.size:
        ax2.plot(t, y, color=color, lw=1.5, label=label)
    ax2.set_xlabel("model time [s]", fontsize=8, color=color)
    ax2.tick_params(axis="x", labelsize=7, colors=color)
    return ax2


def _cycle_span_note(n: int, n_req: int) -> str:
    return f"mean ± SD of last {n} cycle{'s' if n != 1 else ''}" + (
        f" (of {n_req} requested)" if n < n_req else ""
    )


# ------------------------------------------------------------------------------ angles


def plot_joint_angles(
    path,
    trace,
    events,
    *,
    n_cycles: int = 5,
    reference: refdata.Kinematics | None = None,
    correlations: dict | None = None,
) -> Path:
    """Right hip, knee and ankle angles [deg] over the gait cycle vs the human reference.

    Args:
      path: PNG file to write.
      trace, events: one rollout (NumPy or JAX arrays, no batch axis).
      n_cycles: number of last full right cycles averaged (mean +- SD).
      reference: human curves; default Winter normal walking (mean +- SD band).
      correlations: ``corr_hip``, ``corr_knee``, ``corr_ankle`` for the title (e.g. from
        :func:`~jaxgait.analysis.measures.compute_measures`); computed here (last full cycle)
        if None.

    Returns:
      The path written.
    """
    ref = refdata.winter_walking_kinematics() if reference is None else reference
    ang = np.rad2deg(_np(trace.qpos)[:, 3:6].astype(float))
    mean, sd, n = _cycle_stats(trace, events, ang, ref.gait_cycle_pct, n_cycles)
    if correlations is None:
        last, _, n_last = _cycle_stats(trace, events, ang, ref.gait_cycle_pct, 1)
        correlations = {
            f"corr_{name}": _pearson(last[:, j], ref.mean_deg[:, j]) if n_last else 0.0
            for j, name in enumerate(("hip", "knee", "ankle"))
        }
    r = [float(_np(correlations[f"corr_{j}"])) for j in ("hip", "knee", "ankle")]

    fig = Figure(figsize=(11, 3.6), layout="constrained")
    axes = fig.subplots(1, 3)
    alive = _alive(trace)
    t = _np(trace.t)[alive].astype(float)
    pct = ref.gait_cycle_pct
    for j, (ax, name) in enumerate(
        zip(axes, ("hip flexion", "knee flexion", "ankle dorsifl."), strict=True)
    ):
        m_ref, s_ref = ref.mean_deg[:, j], ref.sd_deg[:, j]
        ax.fill_between(pct, m_ref - s_ref, m_ref + s_ref, color=REF_COLOR, alpha=0.3, lw=0)
        ax.plot(pct, m_ref, color=REF_COLOR, lw=1.5, label="human mean ± SD")
        if n > 0:
            ax.fill_between(
                pct,
                mean[:, j] - sd[:, j],
                mean[:, j] + sd[:, j],
                color=MODEL_COLOR,
                alpha=0.25,
                lw=0,
            )
            ax.plot(pct, mean[:, j], color=MODEL_COLOR, lw=1.5, label="model mean ± SD")
        else:
            _time_axis(ax, t, ang[alive, j], MODEL_COLOR)
        ax.set_title(f"{name} (r = {r[j]:.2f})" if n > 0 else name, fontsize=10)
        ax.set_xlabel("gait cycle [%]")
        ax.set_ylabel("angle [deg]")
        ax.set_xlim(0, 100)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="best")
    if n > 0:
        title = (
            f"Right-leg joint angles, {_cycle_span_note(n, n_cycles)}, vs {ref.source}\n"
            f"correlation with the human mean (last cycle): hip {r[0]:.2f}, knee {r[1]:.2f}, "
            f"ankle {r[2]:.2f}, c_angles {min(r):.2f}"
        )
    else:
        title = f"Right-leg joint angles: no full gait cycle ({_end_text(trace)}); model vs time"
    fig.suptitle(title, fontsize=10)
    return _save(fig, path)


# ------------------------------------------------------------------------------ GRF


def plot_grf(
    path,
    trace,
    events,
    mass_kg: float,
    *,
    n_cycles: int = 5,
    reference: refdata.VerticalGRF | None = None,
) -> Path:
    """Right vertical ground reaction force [BW] over the gait cycle vs the human reference.

    Args:
      path: PNG file to write.
      trace, events: one rollout.
      mass_kg: body mass [kg] (1 BW = mass * 9.81 N).
      n_cycles: number of last full right cycles averaged.
      reference: default Winter normal walking (mean +- SD band).
    """
    ref = refdata.winter_walking_grf() if reference is None else reference
    fz = _np(trace.grf)[:, 0, 1].astype(float) / (float(mass_kg) * G)
    mean, sd, n = _cycle_stats(trace, events, fz, ref.gait_cycle_pct, n_cycles)
    pct = ref.gait_cycle_pct

    fig = Figure(figsize=(6.5, 4), layout="constrained")
    ax = fig.subplots()
    ax.fill_between(
        pct, ref.mean_bw - ref.sd_bw, ref.mean_bw + ref.sd_bw, color=REF_COLOR, alpha=0.3, lw=0
    )
    ax.plot(pct, ref.mean_bw, color=REF_COLOR, lw=1.5, label="human mean ± SD")
    if n > 0:
        ax.fill_between(pct, mean - sd, mean + sd, color=MODEL_COLOR, alpha=0.25, lw=0)
        ax.plot(pct, mean, color=MODEL_COLOR, lw=1.5, label="model mean ± SD")
        r = _pearson(mean, np.asarray(ref.mean_bw, float))
        title = f"Right vertical GRF, {_cycle_span_note(n, n_cycles)} (r = {r:.2f})"
        _stance_peak_marks(ax, events, float(mass_kg) * G, n_cycles)
    else:
        alive = _alive(trace)
        _time_axis(ax, _np(trace.t)[alive].astype(float), fz[alive], MODEL_COLOR)
        title = f"Right vertical GRF: no full gait cycle ({_end_text(trace)}); model vs time"
    ax.set_xlim(0, 100)
    ax.set_xlabel("gait cycle [%]")
    ax.set_ylabel("vertical GRF [BW]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=10)
    return _save(fig, path)


def _stance_peak_marks(ax, events, weight: float, n_cycles: int) -> None:
    """Mark the right leg's per-stance peaks measured at the physics step (events.peak_grf),
    which the decimated trace's curve can miss, at their time as % of the cycle."""
    if getattr(events, "peak_grf", None) is None:
        return
    n = min(int(_np(events.n)), _np(events.t).shape[0])
    t, leg = _np(events.t)[:n].astype(float), _np(events.leg)[:n]
    peak, peak_t = _np(events.peak_grf)[:n].astype(float), _np(events.peak_t)[:n].astype(float)
    right = np.flatnonzero(leg == 0)
    pts = [
        (100.0 * peak_t[i] / (t[j] - t[i]), peak[i] / weight)
        for i, j in zip(right[:-1], right[1:], strict=True)
        if t[j] > t[i]
    ][-n_cycles:]
    if pts:
        x, y = np.asarray(pts).T
        ax.plot(x, y, "v", color=MODEL_COLOR, ms=5, label="stance peaks at the physics step")


# ------------------------------------------------------------------------------ activations


def _peak_scale(x: np.ndarray) -> float:
    p = float(np.max(x)) if x.size else 0.0
    return p if p > 1e-9 else 1.0


def plot_activations(
    path,
    trace,
    events,
    muscle_names=MUSCLES,
    *,
    n_cycles: int = 5,
    emg: refdata.Emg | None = None,
) -> Path:
    """Right-leg muscle activations over the gait cycle vs human EMG envelopes.

    Model (mean +- SD over the last ``n_cycles`` cycles) and EMG are each divided by their own
    peak: the comparison is of shape and timing, not amplitude. Muscles without an EMG
    reference (e.g. HFL) show the model only.

    Args:
      path: PNG file to write.
      trace, events: one rollout.
      muscle_names: names of the ``trace.act`` columns.
      n_cycles: number of last full right cycles averaged.
      emg: default :func:`jaxgait.analysis.refdata.walking_emg`.
    """
    ref = refdata.walking_emg() if emg is None else emg
    act = _np(trace.act)[:, 0, :].astype(float)
    names = tuple(muscle_names)
    if len(names) != act.shape[1]:
        raise ValueError(f"trace has {act.shape[1]} muscles, {len(names)} names given")
    mean, sd, n = _cycle_stats(trace, events, act, ref.gait_cycle_pct, n_cycles)
    pct = ref.gait_cycle_pct
    alive = _alive(trace)
    t = _np(trace.t)[alive].astype(float)

    ncol = (len(names) + 1) // 2
    fig = Figure(figsize=(3.0 * ncol, 5.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(2, ncol)).reshape(-1)
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    for j, (ax, m) in enumerate(zip(axes[: len(names)], names, strict=True)):
        if m in ref.muscles:
            e = ref.curve(m)
            ax.fill_between(
                pct, 0, e / _peak_scale(e), color=REF_COLOR, alpha=0.35, lw=0, label="EMG / peak"
            )
        if n > 0:
            s = _peak_scale(mean[:, j])
            lo, hi = (mean[:, j] - sd[:, j]) / s, (mean[:, j] + sd[:, j]) / s
            ax.fill_between(pct, lo, hi, color=MODEL_COLOR, alpha=0.25, lw=0)
            ax.plot(
                pct, mean[:, j] / s, color=MODEL_COLOR, lw=1.5, label=f"activation / peak ({s:.2f})"
            )
        else:
            a = act[alive, j]
            _time_axis(ax, t, a / _peak_scale(a), MODEL_COLOR)
        ax.set_title(m + ("" if m in ref.muscles else " (no EMG)"), fontsize=10)
        ax.set_xlim(0, 100)
        ax.set_ylim(-0.05, 1.15)
        ax.set_xlabel("gait cycle [%]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=6, loc="upper right")
    if n > 0:
        title = (
            f"Right-leg activations, {_cycle_span_note(n, n_cycles)}, vs EMG ({ref.source}); "
            "each curve scaled to its peak"
        )
    else:
        title = f"Right-leg activations: no full gait cycle ({_end_text(trace)}); model vs time"
    fig.suptitle(title, fontsize=10)
    return _save(fig, path)


# ------------------------------------------------------------------------------ stick figure


def _stick_rows(trace, events, window_s: float = 1.2) -> tuple[np.ndarray, str]:
    """Row indices of the last full right cycle (else the last ``window_s`` alive) and a note."""
    alive = _alive(trace)
    t = _np(trace.t).astype(float)
    idx = np.flatnonzero(alive)
    if idx.size == 0:
        return idx, "no alive samples"
    cycles = _cycles(trace, events, 1)
    if cycles:
        a, b = cycles[-1]
        sel = idx[(t[idx] >= a - 1e-6) & (t[idx] <= b + 1e-6)]
        if sel.size >= 2:
            return sel, f"last full right-leg cycle, t = {a:.2f} to {b:.2f} s"
    sel = idx[t[idx] >= t[idx[-1]] - window_s]
    return sel, (
        f"no full right-leg cycle ({_end_text(trace)}): last {t[sel[-1]] - t[sel[0]]:.2f} s shown"
    )


def _segment_geometry(model):
    """Body ids and local segment end points of the planar FBL body."""
    body = model.body
    mj = body.mj_model
    bid = {
        n: mj.body(n).id
        for n in ("trunk", "thigh_r", "shank_r", "foot_r", "thigh_l", "shank_l", "foot_l")
    }
    try:
        g = mj.geom("hat")
        top = float(g.pos[2] + g.size[1])
    except KeyError:
        top = 0.8
    feet = {}
    for side in ("r", "l"):
        feet[side] = [body.site_pos[body.site_id(f"{s}_{side}")] for s in ("heel", "ball")]
    return bid, top, feet


_FRAMES: dict = {}


def _frames(model):
    """jit(vmap(model.body.frames)), cached per model: (R, nq) -> origins, angles."""
    key = id(model.body)
    if key not in _FRAMES:
        import jax

        _FRAMES[key] = (model.body, jax.jit(jax.vmap(model.body.frames)))
    return _FRAMES[key][1]


def _to_world(o, a, local):
    c, s = np.cos(a), np.sin(a)
    return np.stack(
        [o[..., 0] + local[0] * c + local[1] * s, o[..., 1] - local[0] * s + local[1] * c], -1
    )


def plot_stick_figure(
    path,
    trace,
    events,
    model,
    *,
    terrain=None,
    every_s: float = 0.04,
) -> Path:
    """Stick figure of one stride: trunk, thighs, shanks and feet every ``every_s`` seconds.

    The stride is the last full right-leg cycle (from a right touchdown to the next); later
    poses are drawn more opaque. Right leg red, left leg blue, trunk black; the ground line
    is the profile of ``terrain`` under the drawn poses (its exact polyline,
    :func:`jaxgait.world.terrain.terrain_polyline`; flat z = 0 if None).

    Args:
      path: PNG file to write.
      trace, events: one rollout.
      model: the :class:`~jaxgait.sim.Model` (its ``body.frames`` gives the segment poses).
      terrain: :class:`~jaxgait.world.terrain.Terrain` the rollout ran on, or its
        :class:`~jaxgait.world.envs.Env` (whose ``terrain`` is drawn).
      every_s: time between drawn poses [s].
    """
    terrain = getattr(terrain, "terrain", terrain)  # an Env gives its terrain
    rows, note = _stick_rows(trace, events)
    t = _np(trace.t).astype(float)
    if rows.size:
        dt = float(np.median(np.diff(t[rows]))) if rows.size > 1 else every_s
        k = max(1, int(round(every_s / max(dt, 1e-9))))
        rows = rows[::-1][::k][::-1]  # keep the last pose
    lines = []  # (points (n, 2), colour, alpha, width)
    if rows.size:
        q = np.asarray(_np(trace.qpos)[rows], np.float32)
        o, a = _frames(model)(q)
        o, a = _np(o).astype(float), _np(a).astype(float)
        bid, top, feet = _segment_geometry(model)
        tr = bid["trunk"]
        for i, al in enumerate(np.linspace(0.15, 1.0, len(rows))):
            hip = o[i, tr]
            lines.append((np.stack([hip, _to_world(hip, a[i, tr], (0.0, top))]), "k", al, 2.0))
            for side, col in (("l", LEFT), ("r", RIGHT)):
                th, sh, ft = bid[f"thigh_{side}"], bid[f"shank_{side}"], bid[f"foot_{side}"]
                heel = _to_world(o[i, ft], a[i, ft], feet[side][0])
                ball = _to_world(o[i, ft], a[i, ft], feet[side][1])
                pts = np.stack([o[i, th], o[i, sh], o[i, ft], heel, ball, o[i, ft]])
                lines.append((pts, col, al, 1.5))
    allpts = np.concatenate([p for p, *_ in lines]) if lines else np.zeros((1, 2))
    x0, x1 = float(allpts[:, 0].min()) - 0.3, float(allpts[:, 0].max()) + 0.3
    if terrain is not None:
        from jaxgait.world.terrain import terrain_polyline

        g = terrain_polyline(terrain, x0, x1)
    else:
        g = np.array([[x0, 0.0], [x1, 0.0]])
    z0 = min(float(g[:, 1].min()), float(allpts[:, 1].min())) - 0.1
    z1 = max(float(allpts[:, 1].max()), float(g[:, 1].max()) + 1.0) + 0.1
    height = 4.5
    width = float(np.clip(height * (x1 - x0) / (z1 - z0) + 1.2, 5.0, 16.0))
    fig = Figure(figsize=(width, height), layout="constrained")
    ax = fig.subplots()
    for pts, col, al, lw in lines:
        ax.plot(pts[:, 0], pts[:, 1], color=col, alpha=al, lw=lw)
    ax.plot(g[:, 0], g[:, 1], color="0.3", lw=1.2)
    ax.fill_between(g[:, 0], g[:, 1], z0, color="0.85", lw=0)
    ax.plot([], [], color=RIGHT, label="right leg")
    ax.plot([], [], color=LEFT, label="left leg")
    ax.legend(fontsize=8, loc="upper right")
    ax.set_aspect("equal")
    ax.set_xlim(x0, x1)
    ax.set_ylim(z0, z1)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.grid(alpha=0.2)
    ax.set_title(f"Stick figure every {every_s * 1000:.0f} ms\n{note}", fontsize=10)
    return _save(fig, path)


# ------------------------------------------------------------------------------ all


def plot_all(
    out_dir,
    trace,
    events,
    summary,
    model,
    *,
    terrain=None,
    measures_dict: dict | None = None,
    n_cycles: int = 5,
    reference: refdata.Kinematics | None = None,
    grf_reference: refdata.VerticalGRF | None = None,
) -> dict[str, Path]:
    """Write ``joint_angles.png``, ``grf.png``, ``activations.png`` and ``stick_figure.png``.

    Args:
      out_dir: folder (created if missing).
      trace, events, summary: one rollout.
      model: the :class:`~jaxgait.sim.Model` (muscle names, body geometry).
      terrain: the rollout's :class:`~jaxgait.world.terrain.Terrain` or
        :class:`~jaxgait.world.envs.Env` (stick-figure ground line; flat z = 0 if None).
      measures_dict: output of :func:`~jaxgait.analysis.measures.compute_measures`
        (correlations in the joint-angle title); computed if None.
      n_cycles: number of last cycles averaged in the cycle figures.
      reference: human joint angles drawn in ``joint_angles.png`` (default Winter's walking);
        pass the reference ``measures_dict``'s correlations were computed against.
      grf_reference: human vertical GRF drawn in ``grf.png`` (default Winter's walking).

    Returns:
      Figure name -> path written.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    mass = float(_np(summary.mass))
    names = tuple(getattr(getattr(model, "muscles", None), "names", MUSCLES))
    return {
        "joint_angles": plot_joint_angles(
            out / "joint_angles.png",
            trace,
            events,
            n_cycles=n_cycles,
            correlations=measures_dict,
            reference=reference,
        ),
        "grf": plot_grf(
            out / "grf.png", trace, events, mass, n_cycles=n_cycles, reference=grf_reference
        ),
        "activations": plot_activations(
            out / "activations.png", trace, events, names, n_cycles=n_cycles
        ),
        "stick_figure": plot_stick_figure(
            out / "stick_figure.png", trace, events, model, terrain=terrain
        ),
    }
