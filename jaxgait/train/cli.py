"""``python -m jaxgait.train``: a thin command line over :func:`jaxgait.train.train`."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from jaxgait import models
from jaxgait.core.jsonio import parse_assignment
from jaxgait.presets import PresetError
from jaxgait.train.checkpoint import CheckpointError
from jaxgait.train.experiments import (
    Experiment,
    ExperimentError,
    describe_experiments,
    load_config,
    resolve_experiment,
)
from jaxgait.train.loop import train, train_seeds
from jaxgait.train.progress import Progress
from jaxgait.train.setup import DEFAULT_RUNS, TrainError

# ------------------------------------------------------------------------------- CLI


def parse_set(items: Sequence[str]) -> dict:
    """``["a=1", "targets.v_desired=1.5"]`` -> ``{"a": 1, "targets": {"v_desired": 1.5}}``.

    Values are JSON (``null``, ``true``, numbers, lists, strings in quotes); anything that is not
    JSON is taken as a string; ``inf`` is infinity.
    """
    out: dict = {}
    for item in items:
        parsed = parse_assignment(item)
        if parsed is None:
            if "=" not in item:
                raise ExperimentError(f"--set {item!r}: expected key=value")
            raise ExperimentError(f"--set {item!r}: empty key")
        key, value = parsed
        if "." in key:
            head, sub = key.split(".", 1)
            out.setdefault(head, {})
            if not isinstance(out[head], dict):
                raise ExperimentError(f"--set {item!r}: {head} was also set as a whole")
            out[head][sub] = value
        else:
            out[key] = value
    return out


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m jaxgait.train",
        description="Optimise a gait controller: run (or resume) a registered experiment.",
        epilog="experiments:\n" + describe_experiments(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    S = argparse.SUPPRESS
    p.add_argument("experiment", nargs="?", help="experiment name or config JSON file")
    p.add_argument(
        "--list", action="store_true", help="list the experiments and the models, and exit"
    )
    p.add_argument("--particles", type=int, default=S, help="population size")
    p.add_argument("--iterations", type=int, default=S, help="number of iterations")
    p.add_argument("--seed", type=int, default=S, help="seed of every random draw")
    p.add_argument("--duration", type=float, default=S, help="time limit of a rollout [s]")
    p.add_argument("--d-lim", dest="d_lim", type=float, default=S, help="distance limit [m]")
    p.add_argument(
        "--worst-of",
        dest="worst_of_k",
        type=int,
        default=S,
        help="environments per parameter set (worst kept)",
    )
    p.add_argument(
        "--lanes",
        type=int,
        default=S,
        help="queue the rollouts over this many lanes per device (0: direct calls; default: "
        "automatic, a queue over 12 lanes per CPU device holding more than 16 rollouts)",
    )
    p.add_argument(
        "--seeds",
        type=int,
        default=None,
        metavar="N",
        help="N independent runs (seeds SEED ... SEED+N-1) sharing one program, each in "
        "OUT/seed<S>",
    )
    p.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override any experiment field (repeatable; JSON values)",
    )
    p.add_argument("--out", type=Path, default=None, help="results folder (default runs/NAME)")
    p.add_argument("--resume", action="store_true", help="continue from the last checkpoint")
    p.add_argument("--no-plots", action="store_true", help="do not write figures")
    p.add_argument(
        "--no-video", action="store_true", help="do not write best.mp4 (a video of the best)"
    )
    return p


def _cli_experiment(a: argparse.Namespace) -> tuple[Experiment, Path]:
    overrides = parse_set(a.sets)
    for k in ("particles", "iterations", "seed", "duration", "d_lim", "worst_of_k", "lanes"):
        if k in vars(a):
            overrides[k] = getattr(a, k)
    base = resolve_experiment(a.experiment)
    out = a.out if a.out is not None else DEFAULT_RUNS / base.name
    saved_path = out / "config.json"
    if a.seeds is not None:  # the lowest seed's folder holds the runs' config
        found = [
            (int(p.parent.name[4:]), p)
            for p in out.glob("seed*/config.json")
            if p.parent.name[4:].isdigit()
        ]
        if found:
            saved_path = min(found)[1]
    if a.resume and saved_path.is_file():
        saved = load_config(saved_path)
        if saved.name != base.name:
            raise TrainError(
                f"{out} holds a run of experiment {saved.name!r}, not {base.name!r}; "
                "choose another --out or resume that experiment"
            )
        base = saved
    return base.replace(**overrides) if overrides else base, out


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit code (0 ok, 2 bad input, 130 interrupted)."""
    try:
        a = _parser().parse_args(argv)
    except SystemExit as e:
        return int(e.code) if isinstance(e.code, int) else 2
    if a.list or a.experiment is None:
        print("experiments (python -m jaxgait.train NAME):\n" + describe_experiments())
        print("\nmodels (--set model=NAME; planar models train):\n" + models.describe_models())
        return 0
    try:
        from jaxgait.core import compile_cache

        compile_cache.enable()  # later runs with the same shapes skip the compilation
    except ImportError:
        pass
    say = None
    try:
        exp, out = _cli_experiment(a)
        say = Progress()  # a live bar on a terminal, plain lines otherwise
        kw = dict(resume=a.resume, progress=say, plots=not a.no_plots, video=not a.no_video)
        if a.seeds is not None:
            results = train_seeds(exp, a.seeds, out, **kw)
            for r in results:
                print(f"seed {r.config.seed}: best {r.best_score}; results in {r.out_dir}")
            return 0
        result = train(exp, out, **kw)
    except KeyboardInterrupt:
        if say is not None:
            say.close()
        print("interrupted; continue with --resume (the last checkpoint is kept)", file=sys.stderr)
        return 130
    except (ExperimentError, TrainError, PresetError, CheckpointError) as e:
        print(f"jaxgait.train: error: {e}", file=sys.stderr)
        return 2
    print(f"best: {result.best_score}; results in {result.out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
