"""Execute the notebooks at small sizes and fail on any error (CI runs this after the tests).

    python notebooks/run_all.py [NAME ...] [--full] [--timeout S] [--keep DIR]

Every notebook has one code cell tagged ``parameters`` holding its sizes; a cell setting
:data:`SMALL` values is inserted after it (``--full`` keeps the notebook's own sizes).  The
notebooks run one after the other in a fresh kernel each (the ``python3`` kernel of this
interpreter), in a temporary working folder, with the XLA compilation cache of the test
suite (``JAXGAIT_CACHE_DIR``, default ``.jax_cache`` of the checkout), so the small sizes reuse
programs the tests compiled.  A notebook without a ``parameters`` cell, a cell that raises,
or a notebook missing from :data:`SMALL` is an error.  ``--keep DIR`` writes the executed
notebooks there.  The exit code is 0 when every notebook ran, else 1.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: The small sizes CI runs each notebook at (they match shapes the tests compile).
SMALL: dict[str, dict[str, object]] = {
    "quickstart": {
        "DURATION": 0.3,
        "VIDEO_FPS": 10,
        "BATCH": 2,
        "BATCH_SECONDS": 0.2,
        "GENERATIONS": 1,
    },
    "optimisation": {
        "PARTICLES": 4,
        "ITERATIONS": 2,
        "DURATION": 1.0,
        "BATCH_SIZE": 4,
    },
    "taga": {"DURATION": 4.0, "VIDEO_FPS": 5, "U0_SWEEP": (5.0, 5.5)},
    "spinal": {
        "DURATION": 1.0,
        "PROFILE": (1.2, 1.3),
        "SEGMENT": 2.0,
        "SETTLE": 1.0,
        "RANGE_TARGETS": (1.2,),
        "RANGE_SECONDS": 2.0,
        "VIDEO_FPS": 5,
    },
    "wang": {
        "DURATION": 1.0,
        "PRESETS": ("wang_walk_1p25",),
        "VIDEO_FPS": 5,
        "PARTICLES": 4,
        "ITERATIONS": 1,
        "TRAIN_SECONDS": 0.5,
    },
}


class NotebookError(RuntimeError):
    """A notebook cannot be run at its small size, or a cell failed."""


def parameter_cell(nb) -> int:
    """Index of the code cell tagged ``parameters``."""
    found = [
        i
        for i, c in enumerate(nb.cells)
        if c.cell_type == "code" and "parameters" in c.get("metadata", {}).get("tags", [])
    ]
    if len(found) != 1:
        raise NotebookError(f"need exactly one code cell tagged 'parameters', found {len(found)}")
    return found[0]


def with_parameters(nb, values: dict):
    """``nb`` with a cell setting ``values`` inserted after its parameters cell."""
    import nbformat

    i = parameter_cell(nb)
    names = set()
    for line in nb.cells[i].source.splitlines():
        name = line.split("=", 1)[0].strip()
        if "=" in line and name.isidentifier():
            names.add(name)
    unknown = sorted(set(values) - names)
    if unknown:
        raise NotebookError(f"overrides {unknown} are not set in the parameters cell")
    text = "# small sizes set by notebooks/run_all.py\n" + "\n".join(
        f"{k} = {v!r}" for k, v in values.items()
    )
    cell = nbformat.v4.new_code_cell(text)
    cell.metadata["tags"] = ["injected-parameters"]
    nb.cells.insert(i + 1, cell)
    return nb


def run_notebook(path: Path, values: dict | None, timeout: float, keep: Path | None) -> float:
    """Execute one notebook (``values``: parameter overrides, None for its own); seconds."""
    import nbformat
    from jupyter_client.manager import KernelManager
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError

    nb = nbformat.read(path, as_version=4)
    parameter_cell(nb)
    if values is not None:
        nb = with_parameters(nb, values)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix=f"nb-{path.stem}-") as work:
        # the kernel talks over local sockets in the working folder, not over TCP
        km = KernelManager(kernel_name="python3", transport="ipc", ip=str(Path(work) / "kernel"))
        client = NotebookClient(
            nb,
            km=km,
            timeout=timeout,
            kernel_name="python3",
            resources={"metadata": {"path": work}},
        )
        try:
            client.execute()
        except CellExecutionError as e:
            raise NotebookError(str(e)) from None
        finally:
            if km.has_kernel:
                km.shutdown_kernel(now=True)
            if keep is not None:
                keep.mkdir(parents=True, exist_ok=True)
                nbformat.write(nb, keep / path.name)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("names", nargs="*", help="notebooks to run (default: all in notebooks/)")
    p.add_argument("--full", action="store_true", help="run at the notebooks' own sizes")
    p.add_argument("--timeout", type=float, default=600.0, help="seconds per cell (600)")
    p.add_argument("--keep", type=Path, default=None, help="write executed notebooks here")
    a = p.parse_args(argv)
    paths = sorted(HERE.glob("*.ipynb"))
    if a.names:
        want = {n.removesuffix(".ipynb") for n in a.names}
        missing = sorted(want - {q.stem for q in paths})
        if missing:
            print(f"run_all: no notebook {missing} in {HERE}", file=sys.stderr)
            return 1
        paths = [q for q in paths if q.stem in want]
    os.environ.setdefault("JAXGAIT_CACHE_DIR", str(HERE.parent / ".jax_cache"))
    os.environ.setdefault("PYTHONWARNINGS", "ignore::DeprecationWarning")
    failed = []
    for path in paths:
        try:
            if not a.full and path.stem not in SMALL:
                raise NotebookError("no small sizes in notebooks/run_all.py SMALL")
            secs = run_notebook(path, None if a.full else SMALL[path.stem], a.timeout, a.keep)
            print(f"notebook {path.name}: ok in {secs:.1f} s", flush=True)
        except NotebookError as e:
            failed.append(path.name)
            print(f"notebook {path.name}: FAILED\n{e}", file=sys.stderr, flush=True)
    if failed:
        print(f"run_all: {len(failed)} notebook(s) failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    print(f"run_all: {len(paths)} notebook(s) ran without error")
    return 0


if __name__ == "__main__":
    sys.exit(main())
