"""Persistent XLA compilation cache for the command-line tools and the tests.

A full-model rollout takes tens of seconds to compile on a CPU; with the cache, a second
``python -m jaxgait.evaluate`` (or a second test process) with the same shapes starts at once.
The cache lives in ``$JAXGAIT_CACHE_DIR`` (default ``~/.cache/jaxgait/xla``); set
``JAXGAIT_CACHE_DIR=off`` to disable it.
"""

from __future__ import annotations

import os
from pathlib import Path


def enable(path: str | os.PathLike | None = None) -> Path | None:
    """Turn on JAX's persistent compilation cache (idempotent); returns the folder or None."""
    import jax

    where = path or os.environ.get("JAXGAIT_CACHE_DIR") or Path.home() / ".cache/jaxgait/xla"
    if str(where).lower() == "off":
        return None
    where = Path(where)
    try:
        where.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None  # read-only home etc.: run without a cache
    jax.config.update("jax_compilation_cache_dir", str(where))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return where
