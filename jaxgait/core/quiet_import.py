"""Keep MJX's optional-backend notices out of jaxgait's output.

``mujoco.mjx.warp`` (imported by ``mujoco.mjx``) tries to import NVIDIA Warp and prints
``Failed to import warp: ...`` and ``Failed to import mujoco_warp: ...`` to stdout when it is
not installed.  jaxgait never uses the Warp backend, so those two lines are noise in every
command's output (and would break ``--json`` output on stdout).

:func:`install` (called when the ``jaxgait`` package is imported) adds an import hook that
runs that one module with stdout captured and passes every other line through; nothing else
is filtered, and a module already imported is left alone.
"""

from __future__ import annotations

import contextlib
import importlib.abc
import importlib.machinery
import io
import sys

#: The module whose import prints the notices.
TARGET = "mujoco.mjx.warp"
#: Start of the lines dropped from that module's import output.
DROPPED = ("Failed to import warp:", "Failed to import mujoco_warp:")


def filter_lines(text: str) -> str:
    """``text`` without the lines that start with one of :data:`DROPPED`."""
    keep = [ln for ln in text.splitlines(keepends=True) if not ln.startswith(DROPPED)]
    return "".join(keep)


class _QuietLoader(importlib.abc.Loader):
    def __init__(self, loader):
        self._loader = loader

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        buf = io.StringIO()
        try:
            with contextlib.redirect_stdout(buf):
                self._loader.exec_module(module)
        finally:
            rest = filter_lines(buf.getvalue())
            if rest:
                sys.stdout.write(rest)


class _QuietFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path, target=None):
        if fullname != TARGET:
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return None
        spec.loader = _QuietLoader(spec.loader)
        return spec


def install() -> bool:
    """Add the import hook (idempotent); False if the module was imported already."""
    if TARGET in sys.modules:
        return False
    if not any(isinstance(f, _QuietFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _QuietFinder())
    return True
