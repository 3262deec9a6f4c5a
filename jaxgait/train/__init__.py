"""Layer 11, training: population rollouts, fitness, optimiser, checkpoints, results.

Python API (notebooks)::

    from jaxgait.train import train
    result = train("quickstart", out_dir="runs/quickstart")      # or an Experiment / config.json
    result.best_params, result.best_score, result.measures

Command line (a thin layer over :func:`train`)::

    python -m jaxgait.train                      # list the experiments
    python -m jaxgait.train exp7a [--particles N] [--iterations N] [--seed S] [--out DIR]
        [--resume] [--duration S] [--d-lim M] [--worst-of K] [--lanes L] [--seeds N]
        [--set key=value ...] [--no-plots] [--no-video]

Only flags actually given override the experiment (:mod:`jaxgait.train.experiments`). ``--set``
takes any experiment field, values as JSON (``--set init=null``, ``--set targets.v_desired=1.5``,
``--set optimiser_options.sigma_init=0.05``; dotted keys merge into mapping fields).

One iteration (thesis 2.2.1, 3.2): ask the optimiser for P parameter sets; draw P x k fresh
environments (keys from the seed and the iteration); roll all P x k out as one population,
sharded over the local devices (:func:`population_mesh`); measure each rollout
(:func:`~jaxgait.analysis.measures.compute_measures`), score it
(:mod:`~jaxgait.train.objective`), keep the worst of the k scores per parameter set and tell the
optimiser. Every random key is
``fold_in(PRNGKey(seed), iteration)``, so a run killed at any moment and resumed from its last
checkpoint ends exactly as an uninterrupted run.

Results folder (``out_dir``, default ``runs/<experiment>``):

* ``config.json``: the experiment and the jaxgait version;
* ``checkpoints/``: orbax checkpoints of the train state, every iteration, last 3 kept;
* ``history.csv``: one row per iteration (best so far, best of the iteration, particles per
  stage, rollouts/s), rewritten after every iteration;
* ``best.json`` (a preset: ``python -m jaxgait.evaluate runs/exp3``) and ``best_params.txt``
  (readable table), rewritten whenever the best improves;
* at the end: ``measures.json`` (the best re-evaluated on the experiment environment),
  ``plots/`` (joint angles vs Winter, GRF, activations vs EMG, stick figure and, for stage
  objectives, ``stage_progress.png``) and ``best.mp4`` (the last seconds of the best's walk,
  :func:`~jaxgait.train.results.best_video`).

``--resume`` with a different ``--iterations`` (only) extends a finished run or shortens an
unfinished one (down to the iterations done); the result is that of one run of the new
length.  Progress goes to a :class:`~jaxgait.train.progress.Progress`: a live bar on a
terminal, plain lines otherwise.

Modules: :mod:`~jaxgait.train.experiments` (the registry), :mod:`~jaxgait.train.objective`
(fitness and stages), :mod:`~jaxgait.train.setup` (config document, model, start),
:mod:`~jaxgait.train.evaluator` (sharded population rollouts), :mod:`~jaxgait.train.state`
(the checkpointed iteration state, one iteration), :mod:`~jaxgait.train.results` (files,
plots, the final re-evaluation), :mod:`~jaxgait.train.checkpoint` (orbax),
:mod:`~jaxgait.train.loop` (:func:`train`) and :mod:`~jaxgait.train.cli`.
"""

import sys as _sys

from jaxgait.core import host_devices as _host_devices

# ``python -m jaxgait.train`` imports this package before its ``__main__``, and the imports
# below start JAX's backend: the training command's host devices are set here, first.
if _host_devices.is_module_command(_sys.orig_argv, "jaxgait.train"):
    try:
        _host_devices.use_cpu_cores()
    except ValueError as _e:
        print(f"jaxgait.train: error: {_e}", file=_sys.stderr)
        raise SystemExit(2) from None

from jaxgait.train.cli import main, parse_set  # noqa: E402
from jaxgait.train.evaluator import (
    PopulationEvaluator,
    padded_size,
    population_mesh,
    shard_population,
)
from jaxgait.train.experiments import EXPERIMENTS, Experiment, get_experiment, list_experiments
from jaxgait.train.loop import seed_dirs, train, train_seeds, walk_reaches_target
from jaxgait.train.results import final_evaluation, perturbation_check, perturbed_copies
from jaxgait.train.setup import TrainError, config_document, get_model, resolve_init
from jaxgait.train.state import (
    TrainResult,
    TrainState,
    ask_population,
    history_rows,
    run_iteration,
    tell_population,
)

__all__ = [
    "EXPERIMENTS",
    "Experiment",
    "PopulationEvaluator",
    "TrainError",
    "TrainResult",
    "TrainState",
    "ask_population",
    "config_document",
    "final_evaluation",
    "get_experiment",
    "get_model",
    "history_rows",
    "list_experiments",
    "main",
    "padded_size",
    "parse_set",
    "perturbation_check",
    "perturbed_copies",
    "population_mesh",
    "resolve_init",
    "run_iteration",
    "shard_population",
    "tell_population",
    "seed_dirs",
    "train",
    "train_seeds",
    "walk_reaches_target",
]
