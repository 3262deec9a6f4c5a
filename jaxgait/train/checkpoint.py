"""Checkpoints of a training run: one pytree per iteration through orbax, config beside it.

:class:`RunCheckpoints` wraps an ``orbax.checkpoint.CheckpointManager`` whose every step holds

* ``state``: the train state pytree (optimiser state, PRNG key, iteration, best parameters and
  fitness, history arrays), saved with ``StandardSave`` and restored with
  ``StandardRestore(abstract_state)``;
* ``config``: the run's config JSON (experiment fields, jaxgait version, format number).

Guarantees:

* Atomic saves: on a local file system orbax writes a step into ``<step>.orbax-checkpoint-tmp-*``
  and renames it when complete (``AtomicRenameTemporaryPath``), so a save interrupted at any
  moment leaves no step folder; leftover temporary folders are ignored and cleaned up.
* The last ``keep`` steps are kept (older ones are deleted after a successful save).
* A failed save (full disk, read-only folder: ``OSError``, or the I/O errors the storage layer
  raises with the same meaning) is reported through ``warn`` and leaves the previous checkpoint
  in place; training goes on.
* :meth:`RunCheckpoints.restore` checks the saved config against the current one and raises
  :class:`CheckpointMismatchError` naming both experiments (or the differing fields), unless
  its ``accept`` callback takes the saved config (``train`` accepts a different number of
  iterations: :func:`extension_difference`). A step
  that cannot be read (corrupt, truncated) is reported and the previous readable step is used;
  if none is readable, :class:`CheckpointError` lists every step tried and why.
"""

from __future__ import annotations

import errno
import shutil
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import jax
import orbax.checkpoint as ocp

#: Default number of steps kept.
KEEP = 3
_IO_WORDS = ("no space left", "disk quota", "read-only file system", "permission denied", "errno")


class CheckpointError(RuntimeError):
    """A checkpoint folder cannot be used (nothing readable, not a checkpoint folder)."""


class CheckpointMismatchError(CheckpointError):
    """The checkpoint belongs to another experiment, config or jaxgait version."""


def _is_io_error(e: BaseException) -> bool:
    if isinstance(e, OSError):
        return True
    text = str(e).lower()
    return any(w in text for w in _IO_WORDS)


def config_differences(saved: Mapping, current: Mapping, prefix: str = "") -> list[str]:
    """``"field: saved -> current"`` for every differing (nested) key."""
    out = []
    for k in sorted(set(saved) | set(current)):
        a, b = saved.get(k, "<missing>"), current.get(k, "<missing>")
        if isinstance(a, Mapping) and isinstance(b, Mapping):
            out += config_differences(a, b, f"{prefix}{k}.")
        elif a != b:
            out.append(f"{prefix}{k}: {a!r} -> {b!r}")
    return out


#: Experiment fields a resumed run may change: it is extended (more iterations) or its
#: early stop changed or lifted, and it goes on from where it was.
EXTENSION_FIELDS = ("iterations", "stop_speed_tol")


def extension_difference(saved: Mapping, current: Mapping) -> int | None:
    """The saved ``experiment.iterations`` if the two config documents differ only in
    :data:`EXTENSION_FIELDS` (the number of iterations, the early stop), else None
    (identical documents, or any other difference)."""
    a, b = saved.get("experiment"), current.get("experiment")
    if not (isinstance(a, Mapping) and isinstance(b, Mapping)):
        return None
    n = a.get("iterations")
    if isinstance(n, bool) or not isinstance(n, int):
        return None
    if all(a.get(k) == b.get(k) for k in EXTENSION_FIELDS):
        return None
    rest = lambda doc, exp: {
        **doc,
        "experiment": {k: v for k, v in exp.items() if k not in EXTENSION_FIELDS},
    }
    return n if rest(saved, a) == rest(current, b) else None


def _label(cfg: Mapping) -> str:
    exp = cfg.get("experiment", {})
    name = exp.get("name", "?") if isinstance(exp, Mapping) else "?"
    return (
        f"experiment {name!r} (jaxgait {cfg.get('jaxgait_version', '?')}, "
        f"config format {cfg.get('format', '?')})"
    )


class RunCheckpoints:
    """Per-iteration checkpoints of one run in ``directory``.

    Args:
      directory: checkpoint folder (created if missing).
      config: the run's config document (JSON-ready dict with ``experiment``,
        ``jaxgait_version``, ``format``), saved beside every step and checked on restore.
      keep: number of most recent steps kept.
      warn: callable receiving warning lines (default: print).
    """

    def __init__(
        self,
        directory: str | Path,
        config: Mapping,
        keep: int = KEEP,
        warn: Callable[[str], Any] = print,
    ):
        self.directory = Path(directory).absolute()
        self.config = dict(config)
        self.warn = warn
        if self.directory.exists() and not self.directory.is_dir():
            raise CheckpointError(f"{self.directory}: exists and is not a folder")
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise CheckpointError(f"{self.directory}: cannot create folder ({e})") from None
        self._keep = keep
        self._manager = self._open()

    def _open(self) -> ocp.CheckpointManager:
        options = ocp.CheckpointManagerOptions(
            max_to_keep=self._keep,
            create=True,
            enable_async_checkpointing=False,
            cleanup_tmp_directories=True,
        )
        return ocp.CheckpointManager(self.directory, options=options)

    # ---------------------------------------------------------------- queries
    def steps(self) -> list[int]:
        """Finalised steps present, ascending (temporary folders are not steps)."""
        self._manager.reload()
        return sorted(self._manager.all_steps())

    def latest_step(self) -> int | None:
        """Most recent finalised step, or None."""
        s = self.steps()
        return s[-1] if s else None

    # ---------------------------------------------------------------- save
    def save(self, step: int, state: Any) -> bool:
        """Save ``state`` as ``step`` (blocking). Returns False if the save failed on I/O.

        On failure the partial step is removed, the previous steps are untouched and the
        failure is reported through ``warn``.
        """
        args = ocp.args.Composite(
            state=ocp.args.StandardSave(state), config=ocp.args.JsonSave(self.config)
        )
        try:
            self._manager.save(int(step), args=args, force=True)
            self._manager.wait_until_finished()
            return True
        except Exception as e:  # noqa: BLE001 - filtered just below
            if not _is_io_error(e):
                raise
            self._cleanup_failed(int(step))
            last = self.latest_step()
            kept = f"the last good checkpoint is step {last}" if last is not None else "none kept"
            what = "disk full" if getattr(e, "errno", None) == errno.ENOSPC else "I/O error"
            self.warn(
                f"warning: checkpoint of iteration {step} not saved in {self.directory} "
                f"({what}: {e}); {kept}; training continues"
            )
            return False

    def _cleanup_failed(self, step: int) -> None:
        for p in self.directory.glob(f"{step}.orbax-checkpoint-tmp*"):
            shutil.rmtree(p, ignore_errors=True)
        final = self.directory / str(step)
        if final.exists() and not (final / "_CHECKPOINT_METADATA").exists():
            shutil.rmtree(final, ignore_errors=True)
        try:
            self._manager.close()
        except Exception:  # noqa: BLE001 - best effort before reopening
            pass
        self._manager = self._open()

    # ---------------------------------------------------------------- restore
    def read_config(self, step: int) -> dict:
        """The config document saved with ``step``."""
        out = self._manager.restore(step, args=ocp.args.Composite(config=ocp.args.JsonRestore()))
        return dict(out.config)

    def check_config(self, saved: Mapping) -> None:
        """Raise :class:`CheckpointMismatchError` if ``saved`` differs from this run's config."""
        if saved == self.config:
            return
        a, b = _label(saved), _label(self.config)
        if a != b:
            raise CheckpointMismatchError(
                f"checkpoint in {self.directory} was written by {a}; this run is {b}. "
                "Use another output folder, or resume with the saved experiment."
            )
        diff = config_differences(saved, self.config)
        raise CheckpointMismatchError(
            f"checkpoint in {self.directory} ({a}) has a different config: "
            + "; ".join(diff)
            + ". Resume with the same settings, or use another output folder."
        )

    def restore(
        self, abstract_state: Any, accept: Callable[[Mapping], Any] | None = None
    ) -> tuple[int, Any] | None:
        """``(step, state)`` of the newest readable step, or None if there are no steps.

        Args:
          abstract_state: a pytree of ``jax.ShapeDtypeStruct`` (e.g. ``jax.eval_shape`` of the
            initial state) with the structure of the saved state.
          accept: optional ``saved config -> abstract state or None``, asked about a step whose
            config differs from this run's: an abstract state (the saved state's structure)
            restores the step anyway, None refuses it as a mismatch.  ``train`` accepts a
            run that differs in its number of iterations only.

        Raises:
          CheckpointMismatchError: the newest readable step was written by another config.
          CheckpointError: steps exist but none can be read.
        """
        steps = self.steps()
        if not steps:
            return None
        failures = []
        for step in reversed(steps):
            try:
                saved = self.read_config(step)
            except Exception as e:  # noqa: BLE001 - a corrupt step, try the previous one
                failures.append(f"step {step}: config unreadable ({type(e).__name__}: {e})")
                self.warn(
                    f"warning: checkpoint step {step} in {self.directory} is unreadable; "
                    "trying the previous one"
                )
                continue
            abstract = abstract_state
            if saved != self.config:
                abstract = accept(saved) if accept is not None else None
                if abstract is None:
                    self.check_config(saved)  # the configs differ: raises, naming them
            try:
                out = self._manager.restore(
                    step,
                    args=ocp.args.Composite(state=ocp.args.StandardRestore(abstract)),
                )
                state = out.state
                jax.block_until_ready(state)
            except Exception as e:  # noqa: BLE001 - a corrupt step, try the previous one
                failures.append(f"step {step}: state unreadable ({type(e).__name__}: {e})")
                self.warn(
                    f"warning: checkpoint step {step} in {self.directory} is corrupt; "
                    "trying the previous one"
                )
                continue
            return step, state
        raise CheckpointError(
            f"no readable checkpoint in {self.directory}: " + " | ".join(failures)
        )

    def close(self) -> None:
        """Release the manager (waits for nothing: saves are synchronous)."""
        self._manager.close()
