"""Results folder: history, best preset and table, progress lines, plots, the final
re-evaluation and the perturbation check."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.core.jsonio import json_safe
from jaxgait.presets import defining_entries
from jaxgait.train import objective as objective_mod
from jaxgait.train.evaluator import PopulationEvaluator
from jaxgait.train.experiments import (
    Experiment,
)
from jaxgait.train.setup import _EVAL_TAG, TrainError
from jaxgait.train.state import TrainState


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)


def write_history(path: Path, rows: list[dict]) -> None:
    """Write ``history.csv`` (atomically)."""
    if not rows:
        return
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    _atomic_write(path, buf.getvalue())


def _fmt_time(s: float) -> str:
    if not math.isfinite(s):
        return "?"
    s = int(round(s))
    h, r = divmod(s, 3600)
    m, sec = divmod(r, 60)
    return f"{h}h{m:02d}m" if h else (f"{m}m{sec:02d}s" if m else f"{sec}s")


def walk_text(walk: tuple[float, float] | None) -> str:
    """``" (walks 20.0 s, 25.9 m, 1.30 m/s)"``: time, distance and mean speed of a rollout."""
    if walk is None:
        return ""
    d, t = walk
    v = d / t if t > 0 else float("nan")
    return f" (walks {t:.1f} s, {d:.1f} m, {v:.2f} m/s)"


def progress_line(
    exp: Experiment,
    objective,
    state: TrainState,
    eta_s: float,
    first: bool,
    walk: tuple[float, float] | None = None,
) -> str:
    """``exp3 it 12/150 | stages 0:10 1:30 2:20 | best stage 2 (...) (walks 20.0 s, 25.9 m,
    1.30 m/s) | 95 rollouts/s | ETA``; ``walk``: (distance, time) of the best's rollout."""
    it = int(state.iteration) - 1
    counts = np.asarray(state.hist_stage_counts[it])
    if objective.kind == "stage":
        parts = [f"{s}:{int(counts[s + 1])}" for s in range(objective.n_stages) if counts[s + 1]]
        if counts[0]:
            parts.append(f"failed:{int(counts[0])}")
        pop = "stages " + " ".join(parts)
    else:
        pop = f"valid {int(exp.particles - counts[0])}/{exp.particles}"
    secs = float(state.hist_seconds[it])
    rate = int(state.hist_rollouts[it]) / max(secs, 1e-9)
    best = objective_mod.score_text(objective, state.best_stage, state.best_value)
    note = " (incl. compile)" if first else ""
    util = 100 * float(state.hist_utilisation[it])
    return (
        f"{exp.name} it {it + 1}/{exp.iterations} | {pop} | best {best}{walk_text(walk)} | "
        f"{rate:.1f} rollouts/s{note} | lanes {util:.0f}% busy | ETA {_fmt_time(eta_s)}"
    )


def measures_text(m: dict) -> str:
    """``"walks 20.00 s (no fall), 26.10 m at 1.31 m/s, 320 J/m"`` of a measures dict."""

    def num(key, fmt):
        v = m.get(key)
        return format(v, fmt) if isinstance(v, (int, float)) else "n/a"

    fell = "falls" if m.get("fell") else "no fall"
    return (
        f"walks {num('duration_s', '.2f')} s ({fell}), {num('distance_m', '.2f')} m at "
        f"{num('mean_speed_mps', '.2f')} m/s, {num('energy_J_per_m', '.0f')} J/m"
    )


def save_best(
    out: Path,
    exp: Experiment,
    table,
    state: TrainState,
    objective,
    walk: tuple[float, float] | None = None,
) -> dict[str, Path]:
    """Write ``best.json`` (preset) and ``best_params.txt``; returns their paths.

    ``walk``: (distance [m], time [s]) of the best's rollout, kept in ``best.json`` as
    ``distance_m`` and ``duration_s``."""
    from jaxgait.core.params import save_preset

    vec = np.clip(np.asarray(state.best_params, np.float64), table.lower, table.upper)
    text = objective_mod.score_text(objective, state.best_stage, state.best_value)
    extra = defining_entries(exp.model)  # a model a preset defines: best.json re-creates it
    if walk is not None:
        extra.update(distance_m=float(walk[0]), duration_s=float(walk[1]))
    p_json, p_txt = out / "best.json", out / "best_params.txt"
    save_preset(
        p_json,
        exp.model,
        table,
        vec,
        description=f"best of experiment {exp.name}: {exp.description}",
        experiment=exp.name,
        seed=exp.seed,
        iteration=int(state.iteration),
        score=text,
        stage=int(state.best_stage),
        value=float(state.best_value),
        v0=float(exp.v0),
        **({} if exp.pose == "geyer" else {"pose": exp.pose}),
        **({} if exp.dynamics == "mjx" else {"dynamics": exp.dynamics}),
        **extra,
    )
    _atomic_write(
        p_txt,
        f"# experiment {exp.name}, iteration {int(state.iteration)}: {text}\n"
        + table.to_table(vec),
    )
    return {"best": p_json, "best_params": p_txt}


def plot_stage_progress(path: Path, rows: list[dict], criteria: Sequence[str]) -> Path:
    """Particles per stage (stacked) and the best stage over the iterations (PNG)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    it = np.array([r["iteration"] for r in rows])
    fig = Figure(figsize=(8, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    stacks = [np.array([r["n_failed"] for r in rows])]
    labels = ["failed"]
    for s, c in enumerate(criteria):
        stacks.append(np.array([r[f"stage_{s}"] for r in rows]))
        labels.append(f"stage {s}: {c}")
    ax.stackplot(it, *stacks, labels=labels, alpha=0.8)
    ax.set_xlabel("iteration")
    ax.set_ylabel("parameter sets per stage")
    ax2 = ax.twinx()
    ax2.step(it, [r["best_stage"] for r in rows], "k-", where="post", label="best stage")
    ax2.set_ylabel("best stage")
    ax2.set_ylim(-1.2, len(criteria) - 0.5)
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title("stage PSO progress")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path


def perturbed_copies(best, key, n: int, rel: float):
    """``n`` copies of the parameter vector ``best``, each scaled by (1 + rel N(0, 1))."""
    noise = jax.random.normal(key, (n, best.shape[0]))
    return best[None] * (1.0 + rel * noise.astype(best.dtype))


#: Copies of the best, perturbed by :data:`PERTURBED_RELATIVE`, walked by the final evaluation.
PERTURBED_COPIES = 8
PERTURBED_RELATIVE = 1e-6


def perturbation_check(
    evaluator: PopulationEvaluator,
    best,
    env_key,
    key,
    n: int = PERTURBED_COPIES,
    rel: float = PERTURBED_RELATIVE,
) -> dict:
    """How many of ``n`` copies of ``best``, each scaled by (1 + rel N(0, 1)), do not fall.

    Run on the first evaluation environment.  A gait found by optimising one deterministic
    rollout can owe its success to rounding: when the best itself stays up there
    (``perturbed_reference_fell`` false), a fraction below 1 says it falls under changes as
    small as float32 rounding (use worst-of-k or a perturbed environment to train).
    (:func:`final_evaluation` runs the same copies in the call that re-evaluates the best.)
    """
    params = perturbed_copies(best, jax.random.fold_in(key, _EVAL_TAG + 1), n, rel)
    keys = jnp.repeat(env_key[None], n, axis=0)
    fell, dist = np.zeros(n, bool), np.zeros(n)
    for real, _, _, summary in evaluator.run(params, keys):
        fell[real] = np.asarray(summary.fell)[: real.size]
        dist[real] = np.asarray(summary.distance)[: real.size]
    return perturbation_report(fell, dist, rel)


def perturbation_report(fell: np.ndarray, dist: np.ndarray, rel: float) -> dict:
    """The ``perturbed_*`` measures of copies that fell (``fell``) or walked ``dist`` [m]."""
    return {
        "perturbed_relative": rel,
        "perturbed_copies": int(fell.size),
        "perturbed_survival": float(1.0 - np.mean(fell)),
        "perturbed_distance_min_m": float(np.min(dist)),
    }


#: The video ``train`` writes of its best: the last seconds of the re-evaluated walk.
BEST_VIDEO = {"name": "best.mp4", "seconds": 6.0, "fps": 10.0, "width": 480, "height": 270}


def best_video(out: Path, exp: Experiment, trace, env, mass: float, backend: str = "auto"):
    """Write ``out/best.mp4``: the last :data:`BEST_VIDEO` seconds of the best's rollout;
    returns the :class:`~jaxgait.analysis.video.VideoInfo`."""
    from jaxgait.analysis.video import motion_from_trace, write_video

    title = f"{exp.name}: best"
    motion = motion_from_trace(trace, env, title=title, mass=mass)
    v = BEST_VIDEO
    start = max(float(motion.t[0]), float(motion.t[-1]) - v["seconds"])
    return write_video(
        out / v["name"],
        motion,
        backend=backend,
        fps=v["fps"],
        width=v["width"],
        height=v["height"],
        start=start,
    )


def evaluation_keys(exp: Experiment, key) -> jax.Array:
    """The ``worst_of_k`` environment keys of the final evaluation of a run with ``key``."""
    return jax.random.split(jax.random.fold_in(key, _EVAL_TAG), exp.worst_of_k)


def evaluation_batch(exp: Experiment, evaluator: PopulationEvaluator, params, key):
    """The final evaluation's one call: ``params`` on its k environments
    (:func:`evaluation_keys`), then :data:`PERTURBED_COPIES` copies of it perturbed by
    :data:`PERTURBED_RELATIVE` on the first.  Returns ``(stage, value, valid, first)`` of all
    k + n rollouts (``first``: the trace of row 0); their falls and walks are left in
    ``evaluator.last_fell`` and ``evaluator.last_walk``.  The same batch in the same rows
    gives the same rollouts, so a confirmation (:func:`confirm_walk`) is what the final
    evaluation will find."""
    k, n = exp.worst_of_k, PERTURBED_COPIES
    keys = evaluation_keys(exp, key)
    copies = perturbed_copies(params, jax.random.fold_in(key, _EVAL_TAG + 1), n, PERTURBED_RELATIVE)
    batch = jnp.concatenate([jnp.repeat(params[None], k, axis=0), copies])
    env_keys = jnp.concatenate([keys, jnp.repeat(keys[0][None], n, axis=0)])
    return evaluator.scores(batch, env_keys, keep_first=True)


def confirm_walk(exp: Experiment, evaluator: PopulationEvaluator, params, key) -> bool:
    """Whether ``params`` and its perturbed copies all stay up in :func:`evaluation_batch`
    (the check of ``exp.confirm_best``): a gait that does not owe its walk to rounding."""
    evaluation_batch(exp, evaluator, params, key)
    return not bool(np.any(evaluator.last_fell))


def final_evaluation(
    exp: Experiment,
    evaluator: PopulationEvaluator,
    state: TrainState,
    out: Path,
    plots: bool,
    video: bool = False,
    warn=print,
) -> tuple[dict, dict[str, Path]]:
    """Re-evaluate the best on the experiment environment; write measures.json, plots and
    (``video``) ``best.mp4`` (:func:`best_video`; a failure to write it is reported through
    ``warn`` and leaves the other results).

    The best is rolled out on ``worst_of_k`` environments drawn from ``fold_in(seed key,
    EVAL)``; the measures are those of the first draw, the score is the worst of all draws
    (without the stage cap of the stage PSO).
    """
    from jaxgait.analysis.measures import MEASURE_UNITS, compute_measures
    from jaxgait.analysis.refdata import gait_reference

    k = exp.worst_of_k
    keys = evaluation_keys(exp, state.key)
    stages, values, _, first = evaluation_batch(exp, evaluator, state.best_params, state.key)
    fell, dist = evaluator.last_fell[k:], evaluator.last_walk[0][k:]
    stages, values = stages[:k], values[:k]
    ws, wv = objective_mod.worst_of_k(jnp.asarray(stages)[None], jnp.asarray(values)[None])
    trace, events, summary = first
    kin, grf = gait_reference(exp.reference)
    meas = compute_measures(trace, events, summary, reference=kin, grf_reference=grf)
    meas = jax.tree.map(np.asarray, meas)
    report = {k_: json_safe(v) for k_, v in meas.items() if np.ndim(v) == 0}
    report["units"] = {k_: MEASURE_UNITS.get(k_, "") for k_ in report}
    report.update(
        experiment=exp.name,
        env=exp.env,
        duration_requested_s=exp.duration,
        d_lim_m=exp.d_lim if math.isfinite(exp.d_lim) else None,
        score=objective_mod.score_text(evaluator.objective, ws[0], wv[0]),
        stage=int(ws[0]),
        value=json_safe(float(wv[0])),
        worst_of=k,
    )
    report.update(perturbation_report(fell, dist, PERTURBED_RELATIVE))
    report["perturbed_reference_fell"] = bool(np.asarray(summary.fell))
    files = {}
    if video:
        from jaxgait.analysis.video import VideoError
        from jaxgait.world.envs import make_env

        env = make_env(evaluator.env_cfg, keys[0])
        try:
            info = best_video(out, exp, trace, env, float(np.asarray(summary.mass)))
            files["video"] = info.path
            report["video_file"] = str(info.path)
        except (VideoError, OSError) as e:
            warn(f"warning: no video of the best written ({e})")
    files["measures"] = out / "measures.json"
    _atomic_write(
        files["measures"], json.dumps(json_safe(report), indent=2, allow_nan=False) + "\n"
    )
    if plots:
        from jaxgait.analysis.plots import plot_all
        from jaxgait.world.envs import make_env

        env = make_env(evaluator.env_cfg, keys[0])
        figs = plot_all(
            out / "plots",
            trace,
            events,
            summary,
            evaluator.model,
            terrain=jax.tree.map(np.asarray, env.terrain),
            measures_dict=meas,
            reference=kin,
            grf_reference=grf,
        )
        files.update({f"plot_{n}": p for n, p in figs.items()})
    return report, files


def _prepare_out(out: Path, resume: bool) -> None:
    if out.exists() and not out.is_dir():
        raise TrainError(f"results folder {out} exists and is not a folder")
    ck = out / "checkpoints"
    if not resume and ck.is_dir() and any(p.name.isdigit() for p in ck.iterdir()):
        raise TrainError(
            f"{out} already holds checkpoints of a run; resume it with --resume "
            "(resume=True) or choose another output folder (nothing was overwritten)"
        )
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise TrainError(f"cannot create results folder {out}: {e}") from None
