"""The training loop: :func:`train` runs (or resumes) an experiment."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import numpy as np

from jaxgait.optim import stage_argbest
from jaxgait.train import objective as objective_mod
from jaxgait.train.checkpoint import RunCheckpoints, extension_difference
from jaxgait.train.evaluator import PopulationEvaluator
from jaxgait.train.experiments import (
    Experiment,
    resolve_experiment,
)
from jaxgait.train.results import (
    PERTURBED_RELATIVE,
    _atomic_write,
    _prepare_out,
    confirm_walk,
    final_evaluation,
    measures_text,
    plot_stage_progress,
    progress_line,
    save_best,
    write_history,
)
from jaxgait.train.setup import DEFAULT_RUNS, TrainError, config_document, get_model
from jaxgait.train.state import (
    TrainResult,
    ask_population,
    history_length,
    history_rows,
    initial_state,
    keep_best,
    resize_history,
    tell_population,
)

#: Iterations whose mean time gives the ETA.
ETA_WINDOW = 5


class _Run:
    """One run's files, checkpoints and state around the shared iterations."""

    def __init__(self, exp: Experiment, out: Path, evaluator: PopulationEvaluator, say, label=""):
        self.exp, self.out, self.say, self.label = exp, out, say, label
        self.table = get_model(exp.model, exp.init).table
        self.doc = config_document(exp)
        self.strategy = exp.strategy()
        self.objective = evaluator.objective
        # checks the init preset before anything is written
        self.state = initial_state(exp, self.strategy, self.table, self.objective.n_stages)
        self.ckpt: RunCheckpoints | None = None
        self.files: dict[str, Path] = {}
        self.start = 0
        #: (distance [m], time [s]) of the best's rollout (None before one is known)
        self.best_walk: tuple[float, float] | None = None

    def open(self, resume: bool, max_iterations: int | None) -> None:
        """Prepare the folder, restore the newest checkpoint (``resume``), write config.json."""
        exp, say = self.exp, self.say
        _prepare_out(self.out, resume)
        self.ckpt = RunCheckpoints(self.out / "checkpoints", self.doc, warn=say)
        if resume:
            self._restore()
        _atomic_write(self.out / "config.json", json.dumps(self.doc, indent=2) + "\n")
        self.files["config"] = self.out / "config.json"
        if resume:
            self.best_walk = _saved_walk(self.out / "best.json")
        self.start = int(self.state.iteration)
        self.stop = (
            exp.iterations
            if max_iterations is None
            else min(exp.iterations, self.start + max_iterations)
        )

    def _restore(self) -> None:
        """The newest checkpoint's state; a run saved with another number of iterations (and
        nothing else different) is extended, or shortened down to the iterations done."""
        from orbax.checkpoint.utils import to_shape_dtype_struct

        exp, say = self.exp, self.say
        abstract = lambda state: jax.tree.map(to_shape_dtype_struct, state)

        def accept(saved):
            n = extension_difference(saved, self.doc)
            return None if n is None else abstract(resize_history(self.state, n))

        restored = self.ckpt.restore(abstract(self.state), accept=accept)
        if restored is None:
            say(f"{exp.name}: no checkpoint in {self.ckpt.directory}; starting from iteration 0")
            return
        state = restored[1]
        done, saved_n = int(state.iteration), history_length(state)
        if saved_n != exp.iterations:
            if done > exp.iterations:
                raise TrainError(
                    f"{self.out} holds a run with {done} iterations done; it cannot be resumed "
                    f"with iterations={exp.iterations} (use at least {done})"
                )
            state = resize_history(state, exp.iterations)
            say(
                f"{exp.name}{self.label}: iterations {saved_n} -> {exp.iterations} "
                f"(the saved run had done {done})"
            )
        self.state = state
        say(f"{exp.name}{self.label}: resumed from iteration {done} in {self.ckpt.directory}")

    @property
    def pending(self) -> bool:
        return int(self.state.iteration) < self.stop and not self.target_reached

    @property
    def target_reached(self) -> bool:
        """The early stop (``exp.stop_speed_tol``): the best's rollout walked the whole
        duration without falling at a mean speed within the tolerance of v_desired."""
        return walk_reaches_target(self.exp, self.best_walk)

    def record(self, state, improved: bool) -> None:
        """Checkpoint the state of a finished iteration, write history and best, say progress."""
        exp, out = self.exp, self.out
        it = int(state.iteration) - 1
        self.state = state
        self.ckpt.save(it + 1, state)
        rows = history_rows(state, self.objective)
        write_history(out / "history.csv", rows)
        if improved or not (out / "best.json").exists():
            self.files.update(
                save_best(out, exp, self.table, state, self.objective, self.best_walk)
            )
        done_secs = [r["seconds"] for r in rows[self.start :]]
        # the first iteration of a call compiles; iterations get slower as more candidates
        # walk the whole rollout, so the recent ones predict the rest best
        steady = (done_secs[1:] or done_secs)[-ETA_WINDOW:]
        eta = (exp.iterations - (it + 1)) * float(np.mean(steady))
        first = it == self.start
        line = progress_line(exp, self.objective, state, eta, first, self.best_walk)
        line = line.replace(exp.name, exp.name + self.label, 1)
        tick = getattr(self.say, "iteration", None)  # a live progress bar (train.progress)
        if tick is not None:
            tick(it + 1, exp.iterations, line)
        else:
            self.say(line)
        if self.target_reached:
            d, t = self.best_walk
            self.say(
                f"{exp.name}{self.label}: target reached at iteration {it + 1}: the best walks "
                f"the whole {t:.1f} s at {d / t:.2f} m/s (within {exp.stop_speed_tol:g} m/s of "
                f"{dict(exp.targets)['v_desired']:g}); stopping"
            )

    def close(self) -> None:
        if self.ckpt is not None:
            self.ckpt.close()

    def finish(self, evaluator: PopulationEvaluator, plots: bool, video: bool) -> TrainResult:
        """Final files: history, best, and (when complete) the re-evaluation and plots."""
        exp, out, state, objective, files = (
            self.exp,
            self.out,
            self.state,
            self.objective,
            self.files,
        )
        say = self.say
        rows = history_rows(state, objective)
        files["history"] = out / "history.csv"
        if not (out / "best.json").exists():
            files.update(save_best(out, exp, self.table, state, objective, self.best_walk))
        files.setdefault("best", out / "best.json")
        files.setdefault("best_params", out / "best_params.txt")
        complete = int(state.iteration) >= exp.iterations or self.target_reached
        measures = None
        if complete:
            measures, f = final_evaluation(exp, evaluator, state, out, plots, video, say)
            files.update(f)
            if plots and objective.kind == "stage" and rows:
                (out / "plots").mkdir(exist_ok=True)
                files["plot_stage_progress"] = plot_stage_progress(
                    out / "plots" / "stage_progress.png", rows, objective.criteria
                )
            best = objective_mod.score_text(objective, state.best_stage, state.best_value)
            say(
                f"{exp.name}{self.label}: done; best {best}; re-evaluated (no stage cap): "
                f"{measures['score']}, {measures_text(measures)}; results in {out}"
            )
            if "video_file" in measures:
                say(f"{exp.name}{self.label}: video of the best: {measures['video_file']}")
            surv = measures.get("perturbed_survival")
            if surv is not None and surv < 1.0 and not measures.get("perturbed_reference_fell"):
                say(
                    f"warning: only {surv:.0%} of {measures['perturbed_copies']} copies of the "
                    f"best perturbed by {measures['perturbed_relative']:g} (relative) stay up; "
                    "this gait depends on rounding (train with --worst-of or a perturbed "
                    "environment)"
                )
        lo, hi = self.table.lower, self.table.upper
        return TrainResult(
            config=exp,
            out_dir=out,
            best_params=np.clip(np.asarray(state.best_params, np.float64), lo, hi),
            best_stage=int(state.best_stage),
            best_value=float(state.best_value),
            best_score=objective_mod.score_text(objective, state.best_stage, state.best_value),
            iterations_done=int(state.iteration),
            complete=complete,
            history=rows,
            measures=measures,
            files=files,
            state=state,
            best_walk=self.best_walk,
        )


def _shared_iteration(runs: Sequence[_Run], evaluator: PopulationEvaluator) -> None:
    """One iteration of every pending run, their rollouts evaluated together."""
    t0 = time.perf_counter()
    todo = [r for r in runs if r.pending]
    asked = [ask_population(r.exp, r.strategy, r.objective, r.state) for r in todo]
    scored = evaluator.evaluate_many([(a.population, a.env_key, a.max_stage) for a in asked])
    jax.block_until_ready([s for s, _, _ in scored])
    secs = time.perf_counter() - t0
    walks, stats = evaluator.last_walks, evaluator.last_stats  # before any confirmation
    for r, a, (stage, value, _), walk in zip(todo, asked, scored, walks, strict=True):
        state, improved = tell_population(
            r.exp, r.strategy, r.objective, r.state, a, stage, value, secs, stats
        )
        if improved:  # the parameter set tell_population took as the new best
            i = int(stage_argbest(stage, value))
            w = (float(walk[0][i]), float(walk[1][i]))
            if r.exp.confirm_best and walked_whole(r.exp, w):
                if not confirm_walk(r.exp, evaluator, state.best_params, state.key):
                    r.say(
                        f"{r.exp.name}{r.label} it {int(state.iteration)}: the candidate that "
                        f"walked {w[1]:.1f} s falls with a perturbation of "
                        f"{PERTURBED_RELATIVE:g}; the best stays the previous one"
                    )
                    state, improved = keep_best(state, r.state), False
        if improved:
            r.best_walk = w
        r.record(state, improved)


def _run_all(
    runs: Sequence[_Run],
    evaluator: PopulationEvaluator,
    resume: bool,
    max_iterations: int | None,
    say,
    plots: bool,
    video: bool = True,
) -> list[TrainResult]:
    exp = runs[0].exp
    try:
        for r in runs:
            r.open(resume, max_iterations)
        if any(r.pending for r in runs):
            what = f"{len(runs)} runs x " if len(runs) > 1 else ""
            say(
                f"{exp.name}: {what}{exp.particles} x {exp.worst_of_k} rollouts of "
                f"{exp.duration:g} s per iteration on {evaluator.n_devices} device(s); the first "
                "iteration compiles"
            )
        while any(r.pending for r in runs):
            _shared_iteration(runs, evaluator)
    finally:
        for r in runs:
            r.close()
    results = [r.finish(evaluator, plots, video) for r in runs]
    close = getattr(say, "close", None)
    if close is not None:
        close()
    return results


def train(
    config: Experiment | str | Path,
    out_dir: str | Path | None = None,
    resume: bool = False,
    progress: Callable[[str], Any] | None = print,
    max_iterations: int | None = None,
    *,
    devices: Sequence | None = None,
    plots: bool = True,
    video: bool = True,
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
      video: write ``best.mp4``, a few seconds of the best's walk, at the end.

    Returns:
      :class:`TrainResult`.

    Raises:
      ExperimentError, TrainError, PresetError, CheckpointError (all with a message saying what
      and where). Nothing saved before is overwritten by a failed start.
    """
    say = progress or (lambda s: None)
    exp = resolve_experiment(config)
    _check_max_iterations(max_iterations)
    out = Path(out_dir) if out_dir is not None else DEFAULT_RUNS / exp.name
    evaluator = PopulationEvaluator(exp, devices)
    run = _Run(exp, out, evaluator, say)
    return _run_all([run], evaluator, resume, max_iterations, say, plots, video)[0]


def seed_dirs(out: Path, seeds: Sequence[int]) -> list[Path]:
    """The results folder of each seed of :func:`train_seeds`: ``out/seed<S>``."""
    return [Path(out) / f"seed{s}" for s in seeds]


def train_seeds(
    config: Experiment | str | Path,
    seeds: int | Sequence[int],
    out_dir: str | Path | None = None,
    resume: bool = False,
    progress: Callable[[str], Any] | None = print,
    max_iterations: int | None = None,
    *,
    devices: Sequence | None = None,
    plots: bool = True,
    video: bool = True,
) -> list[TrainResult]:
    """Independent runs of one experiment with different seeds, sharing one program.

    Each iteration asks every run's optimiser, evaluates all their rollouts together (one
    call or one queue, so the lanes are wider and busier) and tells each run its own scores.
    A run's result is the one :func:`train` gives with that seed alone, up to the rounding
    of a different batch; each has its own results folder (``out_dir/seed<S>``, default
    ``runs/<name>/seed<S>``), checkpoints and resume.  In ``history.csv`` the seconds are
    those of the shared iteration, and the lane figures those of the shared evaluation.

    Args:
      seeds: a number N (seeds ``exp.seed`` ... ``exp.seed + N - 1``) or a list of seeds.
      the rest: as :func:`train`.

    Returns one :class:`TrainResult` per seed, in order.
    """
    say = progress or (lambda s: None)
    exp = resolve_experiment(config)
    _check_max_iterations(max_iterations)
    if isinstance(seeds, (bool, str, bytes)) or not isinstance(seeds, (int, Sequence)):
        raise TrainError(f"seeds must be a positive number or a list of seeds, got {seeds!r}")
    if isinstance(seeds, int):
        if seeds < 1:
            raise TrainError(f"seeds must be at least 1, got {seeds}")
        seeds = [exp.seed + i for i in range(seeds)]
    seeds = [int(s) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise TrainError(f"seeds must be distinct and not empty, got {seeds}")
    out = Path(out_dir) if out_dir is not None else DEFAULT_RUNS / exp.name
    evaluator = PopulationEvaluator(exp, devices, n_runs=len(seeds))
    runs = [
        _Run(exp.replace(seed=s), d, evaluator, say, label=f" seed {s}")
        for s, d in zip(seeds, seed_dirs(out, seeds), strict=True)
    ]
    return _run_all(runs, evaluator, resume, max_iterations, say, plots, video)


def walk_reaches_target(exp: Experiment, walk: tuple[float, float] | None) -> bool:
    """Whether a rollout that walked ``walk`` = (distance [m], time [s]) meets the early stop
    of ``exp``: it lasted the whole ``exp.duration`` (to 1 ms: no fall) at a mean speed
    within ``exp.stop_speed_tol`` of ``v_desired``.  False without an early stop."""
    if exp.stop_speed_tol is None or not walked_whole(exp, walk):
        return False
    d, t = walk
    return abs(d / t - dict(exp.targets)["v_desired"]) <= exp.stop_speed_tol


def walked_whole(exp: Experiment, walk: tuple[float, float] | None) -> bool:
    """Whether a rollout that walked ``walk`` = (distance [m], time [s]) lasted the whole
    ``exp.duration`` (to 1 ms: it did not fall)."""
    return walk is not None and walk[1] > 0 and walk[1] >= exp.duration - 1e-3


def _saved_walk(best_json: Path) -> tuple[float, float] | None:
    """(distance, time) of the best's rollout kept in a results folder's ``best.json``."""
    try:
        doc = json.loads(best_json.read_text())
        return float(doc["distance_m"]), float(doc["duration_s"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _check_max_iterations(max_iterations) -> None:
    if max_iterations is not None and (isinstance(max_iterations, bool) or max_iterations < 1):
        raise TrainError(f"max_iterations must be a positive integer, got {max_iterations!r}")
