"""The training loop: :func:`train` runs (or resumes) an experiment."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np

from jaxgait.train import objective as objective_mod
from jaxgait.train.checkpoint import RunCheckpoints
from jaxgait.train.evaluator import PopulationEvaluator
from jaxgait.train.experiments import (
    Experiment,
    resolve_experiment,
)
from jaxgait.train.results import (
    _atomic_write,
    _prepare_out,
    final_evaluation,
    plot_stage_progress,
    progress_line,
    save_best,
    write_history,
)
from jaxgait.train.setup import DEFAULT_RUNS, TrainError, config_document, get_model
from jaxgait.train.state import TrainResult, history_rows, initial_state, run_iteration


def train(
    config: Experiment | str | Path,
    out_dir: str | Path | None = None,
    resume: bool = False,
    progress: Callable[[str], Any] | None = print,
    max_iterations: int | None = None,
    *,
    devices: Sequence | None = None,
    plots: bool = True,
) -> TrainResult:
    """Run (or resume) an experiment.

    Args:
      config: an :class:`~jaxgait.train.experiments.Experiment`, a registry name or a config JSON.
      out_dir: results folder (default ``runs/<name>``).
      resume: continue from the newest readable checkpoint in ``out_dir/checkpoints`` (its
        config must equal this one); without a checkpoint, start from scratch.
      progress: callable receiving one line per iteration and notices (None: silent).
      max_iterations: stop after this many iterations in this call (the run stays resumable).
      devices: devices the population is sharded over (default all local devices).
      plots: write the figures at the end.

    Returns:
      :class:`TrainResult`.

    Raises:
      ExperimentError, TrainError, PresetError, CheckpointError (all with a message saying what
      and where). Nothing saved before is overwritten by a failed start.
    """
    say = progress or (lambda s: None)
    exp = resolve_experiment(config)
    if max_iterations is not None and (isinstance(max_iterations, bool) or max_iterations < 1):
        raise TrainError(f"max_iterations must be a positive integer, got {max_iterations!r}")
    model = get_model(exp.model)
    table = model.table
    out = Path(out_dir) if out_dir is not None else DEFAULT_RUNS / exp.name
    doc = config_document(exp)
    strategy = exp.strategy()
    evaluator = PopulationEvaluator(exp, devices)
    objective = evaluator.objective
    state = initial_state(exp, strategy, table, objective.n_stages)  # checks the init preset
    _prepare_out(out, resume)

    ckpt = RunCheckpoints(out / "checkpoints", doc, warn=say)
    files: dict[str, Path] = {}
    try:
        if resume:
            from orbax.checkpoint.utils import to_shape_dtype_struct

            restored = ckpt.restore(jax.tree.map(to_shape_dtype_struct, state))
            if restored is None:
                say(f"{exp.name}: no checkpoint in {ckpt.directory}; starting from iteration 0")
            else:
                state = restored[1]
                say(
                    f"{exp.name}: resumed from iteration {int(state.iteration)} in {ckpt.directory}"
                )
        _atomic_write(out / "config.json", json.dumps(doc, indent=2) + "\n")
        files["config"] = out / "config.json"
        start = int(state.iteration)
        stop = (
            exp.iterations
            if max_iterations is None
            else min(exp.iterations, start + max_iterations)
        )
        if start < stop:
            say(
                f"{exp.name}: {exp.particles} x {exp.worst_of_k} rollouts of {exp.duration:g} s "
                f"per iteration on {evaluator.n_devices} device(s); the first iteration compiles"
            )
        for it in range(start, stop):
            state, improved = run_iteration(exp, strategy, evaluator, state)
            ckpt.save(it + 1, state)
            rows = history_rows(state, objective)
            write_history(out / "history.csv", rows)
            if improved or not (out / "best.json").exists():
                files.update(save_best(out, exp, table, state, objective))
            done_secs = [r["seconds"] for r in rows[start:]]
            steady = done_secs[1:] or done_secs
            eta = (exp.iterations - (it + 1)) * float(np.mean(steady))
            say(progress_line(exp, objective, state, eta, first=(it == start)))
    finally:
        ckpt.close()

    rows = history_rows(state, objective)
    files["history"] = out / "history.csv"
    if not (out / "best.json").exists():
        files.update(save_best(out, exp, table, state, objective))
    files.setdefault("best", out / "best.json")
    files.setdefault("best_params", out / "best_params.txt")
    complete = int(state.iteration) >= exp.iterations
    measures = None
    if complete:
        measures, f = final_evaluation(exp, evaluator, state, out, plots)
        files.update(f)
        if plots and objective.kind == "stage" and rows:
            (out / "plots").mkdir(exist_ok=True)
            files["plot_stage_progress"] = plot_stage_progress(
                out / "plots" / "stage_progress.png", rows, objective.criteria
            )
        best = objective_mod.score_text(objective, state.best_stage, state.best_value)
        d, epm = measures.get("distance_m"), measures.get("energy_J_per_m")
        d = f"{d:.2f} m" if d is not None else "n/a"
        epm = f"{epm:.0f} J/m" if epm is not None else "n/a"
        say(
            f"{exp.name}: done; best {best}; re-evaluated (no stage cap): {measures['score']}, "
            f"distance {d}, {epm}; results in {out}"
        )
        surv = measures.get("perturbed_survival")
        if surv is not None and surv < 1.0 and not measures.get("perturbed_reference_fell"):
            say(
                f"warning: only {surv:.0%} of {measures['perturbed_copies']} copies of the best "
                f"perturbed by {measures['perturbed_relative']:g} (relative) stay up; this gait "
                "depends on rounding (train with --worst-of or a perturbed environment)"
            )
    return TrainResult(
        config=exp,
        out_dir=out,
        best_params=np.clip(np.asarray(state.best_params, np.float64), table.lower, table.upper),
        best_stage=int(state.best_stage),
        best_value=float(state.best_value),
        best_score=objective_mod.score_text(objective, state.best_stage, state.best_value),
        iterations_done=int(state.iteration),
        complete=complete,
        history=rows,
        measures=measures,
        files=files,
        state=state,
    )
