"""Figures of the spinal-network chapter (thesis Fig. 7.1-7.4) as PNG files.

Each function draws on its own Agg :class:`~matplotlib.figure.Figure` and returns the path.

* :func:`plot_variability`: s, v_mu and v_sigma of every IN_SEN for one or more gaits
  (Fig. 7.1), the replaced IN marked with a star;
* :func:`plot_patterns`: the nominal patterns (right leg) of two gaits overlaid with their
  correlations (Fig. 7.3);
* :func:`plot_models`: joint angles over the cycle against Winter, their correlations and
  the vertical GRF of several models (Fig. 7.2);
* :func:`plot_robustness`: C_angles, max push and max slope change, mean +- SD (Fig. 7.4);
* :func:`plot_climb`: distance and grade reached on the increasing slope (Fig. 7.5);
* :func:`plot_speed_range`, :func:`plot_tuning`: constant targets held; CMA-ES progress;
* :func:`plot_walkrun`: commands, speed, double stance and flight of a walk-run rollout.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from jaxgait.analysis import refdata
from jaxgait.analysis.plots import cycle_stats
from jaxgait.analysis.variability import S_PERIODIC, pattern_correlation
from jaxgait.control.interneurons import IN_NAMES, IN_SEN
from jaxgait.spinal.record import Analysis

COLORS = ("tab:blue", "tab:green", "tab:orange", "tab:red", "tab:purple", "tab:brown")


def _save(fig: Figure, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=100)
    return path


def plot_variability(path, analyses: dict[str, Analysis], replaced=()) -> Path:
    """Fig. 7.1: grouped bars of s, v_mu, v_sigma per IN_SEN, one colour per gait."""
    fig = Figure(figsize=(12, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    x = np.arange(len(IN_NAMES))
    w = 0.8 / max(len(analyses), 1)
    for j, (label, an) in enumerate(analyses.items()):
        for ax, what in zip(axes, ("s", "v_mu", "v_sigma"), strict=True):
            vals = [an.factor(n, what) for n in IN_NAMES]
            ax.bar(x + (j - (len(analyses) - 1) / 2) * w, vals, w, color=COLORS[j % 6], label=label)
    axes[0].axhline(S_PERIODIC, color="0.4", ls="--", lw=1, label=f"s = {S_PERIODIC}")
    for ax, what, unit in zip(
        axes, ("s", "v_mu", "v_sigma"), ("[-]", "[stim]", "[stim]"), strict=True
    ):
        ax.set_ylabel(f"{what} {unit}")
        ax.grid(alpha=0.3, axis="y")
        ax.set_yscale("symlog", linthresh=1e-3)
    for k, n in enumerate(IN_NAMES):
        if n in replaced:
            axes[0].annotate("*", (k, 0), ha="center", va="bottom", color="red", fontsize=16)
    axes[0].legend(fontsize=8, ncol=4)
    axes[-1].set_xticks(x, IN_NAMES, rotation=60, ha="right", fontsize=8)
    fig.suptitle(
        "IN_SEN periodic variability (thesis Fig. 7.1): stability factor s (eq. 6.11), "
        "v_mu and v_sigma (eq. 6.14-6.15); * replaced",
        fontsize=10,
    )
    return _save(fig, path)


def plot_patterns(path, a: Analysis, b: Analysis, labels=("A", "B")) -> Path:
    """Fig. 7.3: right-leg nominal patterns of two gaits, with their correlations."""
    fig = Figure(figsize=(13, 9), layout="constrained")
    axes = fig.subplots(3, 5).ravel()
    ph = np.arange(a.per_leg[IN_NAMES[0]][0].pattern.size)
    ph = 100.0 * ph / ph.size
    for ax, i in zip(axes, IN_SEN, strict=True):
        pa, pb = a.per_leg[i.name][0].pattern, b.per_leg[i.name][0].pattern
        ax.plot(ph, pa, color="k", lw=1.3, label=labels[0])
        ax.plot(ph, pb, color="k", lw=1.3, ls="--", label=labels[1])
        ax.set_title(f"{i.name}  r = {pattern_correlation(pa, pb):.2f}", fontsize=8)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
    axes[0].legend(fontsize=7)
    for ax in axes[10:]:
        ax.set_xlabel("cycle from touchdown [%]", fontsize=8)
    fig.suptitle("Normalised IN_SEN nominal patterns (thesis Fig. 7.3), right leg", fontsize=10)
    return _save(fig, path)


def plot_models(path, runs: dict, n_cycles: int = 10) -> Path:
    """Fig. 7.2: joint angles vs Winter, their correlations and the vertical GRF of several
    evaluated models (``{label: jaxgait.evaluate.EvalRun}``)."""
    ref, grf_ref = refdata.winter_walking_kinematics(), refdata.winter_walking_grf()
    fig = Figure(figsize=(13, 7), layout="constrained")
    top = fig.subfigures(2, 1)
    axa = top[0].subplots(1, 3)
    axb = top[1].subplots(1, 2)
    names = ("hip", "knee", "ankle")
    for j in range(3):
        m, s = ref.mean_deg[:, j], ref.sd_deg[:, j]
        axa[j].fill_between(ref.gait_cycle_pct, m - s, m + s, color="0.8", lw=0)
        axa[j].plot(ref.gait_cycle_pct, m, color="0.5", label="human (Winter)")
    m, s = grf_ref.mean_bw, grf_ref.sd_bw
    axb[1].fill_between(grf_ref.gait_cycle_pct, m - s, m + s, color="0.8", lw=0)
    axb[1].plot(grf_ref.gait_cycle_pct, m, color="0.5", label="human (Winter)")
    width = 0.8 / max(len(runs), 1)
    for k, (label, r) in enumerate(runs.items()):
        c = COLORS[k % 6]
        ang = np.rad2deg(np.asarray(r.trace.qpos)[:, 3:6].astype(float))
        mean, _, n = cycle_stats(r.trace, r.events, ang, ref.gait_cycle_pct, n_cycles)
        speed = r.report.get("mean_speed_mps")
        lab = f"{label} ({speed:.2f} m/s)" if isinstance(speed, float) else label
        if n:
            for j in range(3):
                axa[j].plot(ref.gait_cycle_pct, mean[:, j], color=c, label=lab)
        corr = [float(r.measures.get(f"corr_{nm}", np.nan)) for nm in names]
        axb[0].bar(
            np.arange(3) + (k - (len(runs) - 1) / 2) * width, corr, width, color=c, label=label
        )
        fz = np.asarray(r.trace.grf)[:, 0, 1].astype(float) / (float(r.summary.mass) * 9.81)
        gm, _, n = cycle_stats(r.trace, r.events, fz, grf_ref.gait_cycle_pct, n_cycles)
        if n:
            axb[1].plot(grf_ref.gait_cycle_pct, gm, color=c, label=label)
    for j, name in enumerate(names):
        axa[j].set_title(f"{name} angle [deg]", fontsize=9)
        axa[j].set_xlabel("gait cycle [%]")
        axa[j].grid(alpha=0.3)
    axa[0].legend(fontsize=7)
    axb[0].set_xticks(range(3), names)
    axb[0].set_ylim(-1, 1)
    axb[0].set_title("correlation with the human mean", fontsize=9)
    axb[0].grid(alpha=0.3, axis="y")
    axb[1].set_title("right vertical GRF [BW]", fontsize=9)
    axb[1].set_xlabel("gait cycle [%]")
    axb[1].legend(fontsize=7)
    axb[1].grid(alpha=0.3)
    fig.suptitle("Models compared on flat ground (thesis Fig. 7.2)", fontsize=10)
    return _save(fig, path)


def _bar_panels(path, rows: dict[str, dict], panels, suptitle: str, rotate=0) -> Path:
    """One bar panel per (key, title) of ``panels``: ``rows[label][key] = (mean, sd)``."""
    fig = Figure(figsize=(3.7 * len(panels), 3.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    labels = list(rows)
    for ax, (key, title) in zip(axes, panels, strict=True):
        mean = [rows[lab][key][0] for lab in labels]
        sd = [rows[lab][key][1] for lab in labels]
        ax.bar(labels, mean, yerr=sd, color=[COLORS[k % 6] for k in range(len(labels))], capsize=4)
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3, axis="y")
        if rotate:
            ax.tick_params(axis="x", labelsize=7, rotation=rotate)
    fig.suptitle(suptitle, fontsize=10)
    return _save(fig, path)


def plot_robustness(path, rows: dict[str, dict]) -> Path:
    """Fig. 7.4: ``{label: {"c_angles": (mean, sd), "max_push_N": (mean, sd),
    "max_slope_pct": (mean, sd)}}`` as three bar panels."""
    panels = (
        ("c_angles", "joint-angle correlation C_angles"),
        ("max_push_N", "max push [N]"),
        ("max_slope_pct", "max slope change [%]"),
    )
    return _bar_panels(
        path, rows, panels, "Robustness of the models, default control vector (thesis Fig. 7.4)"
    )


def plot_search(path, res: dict, keys=None) -> Path:
    """Fig. 7.6-7.10: maps of gait measures over a systematic search (blank where it fell)."""
    keys = keys or ("speed_mps", "energy_J_per_m", "double_stance_s", "cycle_length_s")
    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(2, 2).ravel()
    xv, yv = np.asarray(res["x_values"]), np.asarray(res["y_values"])
    for ax, k in zip(axes, keys, strict=False):
        z = np.ma.masked_invalid(np.asarray(res["grid"][k], float))
        im = ax.imshow(z, origin="lower", aspect="auto", cmap="viridis")
        ax.set_xticks(range(xv.size), [f"{v:.3g}" for v in xv], fontsize=7)
        ax.set_yticks(range(yv.size), [f"{v:.3g}" for v in yv], fontsize=7)
        ax.set_xlabel(res["x"])
        ax.set_ylabel(res["y"])
        ax.set_title(k, fontsize=9)
        fig.colorbar(im, ax=ax)
    fixed = ", ".join(f"{k} = {v:g}" for k, v in res.get("fixed", {}).items()) or "defaults"
    fig.suptitle(
        f"{res['model']}: systematic search, C changed every {res['hold_s']:g} s, measured over "
        f"the last {res['measure_s']:g} s; others {fixed}; blank = fell",
        fontsize=9,
    )
    return _save(fig, path)


def plot_tracking(path, r: dict) -> Path:
    """Speed (1 s moving average) against the target profile over time."""
    fig = Figure(figsize=(9, 3.6), layout="constrained")
    ax = fig.subplots()
    ax.plot(r["t"], r["target"], color="0.4", lw=1.5, label="target")
    ax.plot(r["t"], r["speed"], color="tab:red", lw=1.0, label=f"{r['model']} (1 s average)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("speed [m/s]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    rms = ", ".join("-" if not np.isfinite(e) else f"{e:.3f}" for e in r["rms"])
    end = f"fell at {r['duration_s']:.1f} s" if r["fell"] else "no fall"
    ax.set_title(
        f"speed tracking, RMS error per segment after {r['settle_s']:g} s: {rms} m/s; {end}",
        fontsize=9,
    )
    return _save(fig, path)


def plot_speed_range(path, results: dict[str, dict]) -> Path:
    """Mean speed over the last seconds against the constant target, per model; the
    targets held (within the tolerance, no fall) filled, the others open, falls at 0."""
    fig = Figure(figsize=(5.5, 4.5), layout="constrained")
    ax = fig.subplots()
    lo = min(min(r["targets"]) for r in results.values())
    hi = max(max(r["targets"]) for r in results.values())
    ax.plot([lo, hi], [lo, hi], color="0.6", lw=1, label="target")
    for k, (lab, r) in enumerate(results.items()):
        tg, sp = np.asarray(r["targets"]), np.nan_to_num(np.asarray(r["speed_mps"], float))
        held = np.asarray(r["held"], bool)
        c = COLORS[k % 6]
        ax.plot(tg, sp, color=c, lw=0.8)
        ax.scatter(tg[held], sp[held], color=c, s=25, label=f"{lab} (held)")
        ax.scatter(tg[~held], sp[~held], facecolors="none", edgecolors=c, s=25)
    ax.set_xlabel("target speed [m/s]")
    ax.set_ylabel("speed over the last seconds [m/s] (0: fell)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("constant targets held for the whole walk", fontsize=9)
    return _save(fig, path)


def plot_climb(path, rows: dict[str, dict]) -> Path:
    """Thesis Fig. 7.5: distance walked and steepest grade reached on the increasing slope,
    ``{label: {"distance_m": (mean, sd), "grade_pct": (mean, sd)}}``."""
    panels = (
        ("distance_m", "distance on the increasing slope [m]"),
        ("grade_pct", "steepest grade reached [%]"),
    )
    title = "Increasing slope, 0 -> 30 % over 160 m (thesis Fig. 7.5)"
    return _bar_panels(path, rows, panels, title, rotate=20)


def plot_tuning(path, history: list[dict]) -> Path:
    """CMA-ES progress of a command-law training: best and mean fitness per generation."""
    fig = Figure(figsize=(6, 3.6), layout="constrained")
    ax = fig.subplots()
    g = [h["generation"] for h in history]
    ax.plot(g, [h["best"] for h in history], "o-", ms=3, label="best of the generation")
    ax.plot(g, [h["mean"] for h in history], "s-", ms=3, label="mean of the generation")
    ax.set_xlabel("generation")
    ax.set_ylabel("fitness (lower is better)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_maps(path, pairs: list[dict], measure: str) -> Path:
    """Thesis Fig. 7.9-7.10: one quadrant of the systematic searches, a map of ``measure``
    per (pair of commands: column, z value: row), on one colour scale; blank = fell.  A
    search without ``z`` (a model without omega: FBL, FBL-) is one row."""
    nz = len(pairs[0].get("z_values", ())) or 1
    fig = Figure(figsize=(2.0 * len(pairs) + 1.2, 1.7 * nz + 0.8), layout="constrained")
    axes = np.atleast_2d(fig.subplots(nz, len(pairs), squeeze=False))
    vals = np.concatenate([np.ravel(np.asarray(r["grid"][measure], float)) for r in pairs])
    vals = vals[np.isfinite(vals)]
    vmin, vmax = (float(vals.min()), float(vals.max())) if vals.size else (0.0, 1.0)
    im = None
    for c, r in enumerate(pairs):
        g = np.asarray(r["grid"][measure], float)
        g = g if "z" in r else g[None]
        for k in range(nz):
            ax = axes[k, c]
            im = ax.imshow(
                np.ma.masked_invalid(g[k]), origin="lower", aspect="auto", cmap="viridis",
                vmin=vmin, vmax=vmax,
            )  # fmt: skip
            ax.set_xticks([])
            ax.set_yticks([])
            if k == nz - 1:
                ax.set_xlabel(
                    f"{r['x']}\n[{r['x_values'][0]:g}, {r['x_values'][-1]:g}]", fontsize=7
                )
            if c == 0 and "z" in r:
                ax.set_ylabel(f"{r['z']} {r['z_values'][k]:.2f}", fontsize=7)
            if k == 0:
                ax.set_title(
                    f"y: {r['y']} [{r['y_values'][0]:g}, {r['y_values'][-1]:g}]", fontsize=7
                )
    if im is not None:
        fig.colorbar(im, ax=axes, shrink=0.6, label=measure)
    fig.suptitle(f"{pairs[0]['model']}: systematic search, {measure} (blank = fell)", fontsize=9)
    return _save(fig, path)


def plot_walkrun(path, r: dict) -> Path:
    """A walk-run rollout (:mod:`jaxgait.spinal.walkrun`): the driven commands, the speed and
    the double-stance and flight fractions per window over time, the phases shaded."""
    w = r["windows"]
    t = np.asarray(w["t_end_s"]) - 0.5 * r["window_s"]
    fig = Figure(figsize=(9, 6), layout="constrained")
    axs = fig.subplots(3, 1, sharex=True)
    for name, vals in w["commands"].items():
        axs[0].plot(t, vals, lw=1.5, label=name)
    axs[0].set_ylabel("command")
    axs[1].plot(t, np.asarray(w["speed_mps"], float), "o-", color="tab:red", ms=3)
    axs[1].set_ylabel("speed [m/s]")
    for key, c in (("double_stance_fraction", "tab:blue"), ("flight_fraction", "tab:orange")):
        axs[2].plot(t, np.asarray(w[key], float), "o-", color=c, ms=3, label=key.split("_f")[0])
    axs[2].set_ylabel("fraction of time")
    axs[2].set_xlabel("time [s]")
    edges = np.cumsum([0.0] + list(r["phases_s"].values()))
    for ax in axs:
        for k in range(1, len(edges) - 1, 2):
            ax.axvspan(edges[k], edges[k + 1], color="0.9", zorder=0)
        if r["fell"]:
            ax.axvline(r["fell_at_s"], color="k", ls="--", lw=1)
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=8)
    axs[2].legend(fontsize=8)
    end = f"fell at {r['fell_at_s']:.1f} s ({r['fell_in']})" if r["fell"] else "no fall"
    axs[0].set_title(f"{r['model']} on {r['env']}: driven commands, ramps shaded; {end}")
    return _save(fig, path)
