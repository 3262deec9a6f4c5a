"""The ``jaxgait`` command: one entry point for the command-line tools.

::

    jaxgait train [EXPERIMENT] [ARGS...]    python -m jaxgait.train       optimise a gait
    jaxgait evaluate PRESET [ARGS...]       python -m jaxgait.evaluate    gait measures
    jaxgait robustness PRESET [ARGS...]     python -m jaxgait.robustness  push, wavy, slope
    jaxgait render PRESET [ARGS...]         python -m jaxgait.render      video of a walk
    jaxgait list [--json]                   experiments, models and shipped presets

Each subcommand takes exactly the arguments of its ``python -m`` form (``jaxgait SUB --help``)
and returns its exit code; ``python -m jaxgait`` is the same command.  ``jaxgait list
--json`` prints one object with the keys ``experiments`` (name -> model, environment,
optimiser, particles, iterations, description), ``models`` (name -> family, parameters,
description) and ``presets`` (names).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence

#: Subcommand -> (its python -m module, one line).
COMMANDS = {
    "train": ("jaxgait.train", "optimise a gait controller: run or resume an experiment"),
    "evaluate": ("jaxgait.evaluate", "simulate a preset and report its gait measures"),
    "robustness": ("jaxgait.robustness", "largest push, wavy-ground slope, slope distance"),
    "render": ("jaxgait.render", "simulate a preset and write a video of its walk"),
    "list": ("", "the registered experiments and models, and the shipped presets"),
}


def _train(argv):
    from jaxgait.train.cli import main

    return main(argv)


def _evaluate(argv):
    from jaxgait.evaluate import main

    return main(argv)


def _robustness(argv):
    from jaxgait.robustness import main

    return main(argv)


def _render(argv):
    from jaxgait.render import main

    return main(argv)


def listing() -> dict:
    """The ``list --json`` object: experiments, models and presets."""
    from jaxgait import models
    from jaxgait.presets import list_presets
    from jaxgait.train.experiments import EXPERIMENTS

    exps = {
        n: {
            "model": e.model,
            "env": e.env,
            "optimiser": e.optimiser,
            "particles": e.particles,
            "iterations": e.iterations,
            "description": e.description,
        }
        for n, e in EXPERIMENTS.items()
    }
    mods = {}
    for n in models.model_names():
        s = models.get_spec(n)
        size = None if s.table is None else s.table.size
        mods[n] = {"family": s.family, "parameters": size, "description": s.description}
    return {"experiments": exps, "models": mods, "presets": list_presets()}


def _list(argv) -> int:
    if argv and argv != ["--json"]:
        print(f"jaxgait list: error: unknown arguments {argv}; usage: jaxgait list [--json]")
        return 2
    if argv == ["--json"]:
        print(json.dumps(listing()))
        return 0
    from jaxgait import models
    from jaxgait.presets import list_presets
    from jaxgait.train.experiments import describe_experiments

    print("experiments (jaxgait train NAME):\n" + describe_experiments())
    print("\nmodels:\n" + models.describe_models())
    print("\npresets (jaxgait evaluate NAME, jaxgait render NAME):\n  " + " ".join(list_presets()))
    return 0


_RUN = {
    "train": _train,
    "evaluate": _evaluate,
    "robustness": _robustness,
    "render": _render,
    "list": _list,
}


def usage() -> str:
    lines = ["usage: jaxgait COMMAND [ARGS...]   (jaxgait COMMAND --help for its arguments)", ""]
    for name, (module, text) in COMMANDS.items():
        form = f"(python -m {module})" if module else ""
        lines.append(f"  {name:<11} {text} {form}".rstrip())
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Dispatch ``argv`` (default ``sys.argv[1:]``) to a subcommand; its exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help", "help"):
        print(usage())
        return 0
    if args[0] == "--version":
        from jaxgait.train.setup import jaxgait_version

        print(f"jaxgait {jaxgait_version()}")
        return 0
    cmd, rest = args[0], args[1:]
    if cmd not in _RUN:
        print(
            f"jaxgait: error: unknown command {cmd!r}; choose one of {', '.join(_RUN)}\n" + usage(),
            file=sys.stderr,
        )
        return 2
    return int(_RUN[cmd](rest) or 0)


def console_main(argv: Sequence[str] | None = None) -> int:
    """The ``jaxgait`` command (and ``python -m jaxgait``): :func:`main`, with the training
    command's host devices set first (one per CPU core, :mod:`jaxgait.core.host_devices`).
    Called in a Python session, :func:`main` leaves JAX's devices as they are."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] == ["train"]:
        from jaxgait.core import host_devices

        try:  # before anything starts JAX's backend
            host_devices.use_cpu_cores()
        except ValueError as e:
            print(f"jaxgait train: error: {e}", file=sys.stderr)
            return 2
    return main(args)


if __name__ == "__main__":
    sys.exit(console_main())
