"""One XLA host device per CPU core, for the training command.

On a CPU, JAX presents the whole host as one device by default, and XLA runs one program's
kernels on its threads.  A rollout step of a few lanes is hundreds of small kernels, so that
program leaves the cores partly idle.  Presented as one device per core, each core runs its
own device's share of the population (the evaluator shards over the devices; each runs its own
queue of rollouts), and on 2 cores one exp3 generation took 16-19 s against 31-35 s
(``benchmarks/train_throughput.py --compare-devices``).

XLA reads the device count once, when JAX's backend starts, so :func:`use_cpu_cores` must run
before anything creates an array (``jaxgait``'s own modules do at import).  The training
command (``python -m jaxgait.train``, ``jaxgait train``, ``./jg train``) calls it first thing;
the Python API and the other commands keep JAX's single host device.
``JAXGAIT_CPU_DEVICES`` overrides the count (``1``: JAX's single device); an ``XLA_FLAGS`` that
already sets ``--xla_force_host_platform_device_count`` is left alone.  Accelerators are not
affected (the flag only shapes the host platform, which then is not the default backend).
"""

from __future__ import annotations

import os

FLAG = "--xla_force_host_platform_device_count"
ENV = "JAXGAIT_CPU_DEVICES"


def cpu_cores() -> int:
    """Cores this process may run on (its affinity mask, else ``os.cpu_count()``)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def requested_devices(environ=None) -> int:
    """The host device count asked for: ``$JAXGAIT_CPU_DEVICES`` (a positive integer, or
    ``auto``) else one per core.  Raises ValueError on anything else, naming the variable."""
    environ = os.environ if environ is None else environ
    raw = environ.get(ENV, "auto").strip().lower()
    if raw in ("", "auto"):
        return cpu_cores()
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"{ENV}={environ.get(ENV)!r}: expected a positive integer or 'auto'")
    return n


def backend_started() -> bool:
    """Whether JAX's backends are already initialised (too late to change the flag)."""
    try:
        from jax._src import xla_bridge
    except ImportError:  # pragma: no cover - jax always ships it
        return False
    return bool(getattr(xla_bridge, "_backends", {}))


def is_module_command(orig_argv, module: str) -> bool:
    """Whether the interpreter was started as ``python [options] -m MODULE ...``
    (``sys.orig_argv``)."""
    args = list(orig_argv)
    return any(a == "-m" and b == module for a, b in zip(args, args[1:], strict=False))


def use_cpu_cores(environ=None) -> int | None:
    """Ask XLA for :func:`requested_devices` host devices (by adding the flag to
    ``XLA_FLAGS``).  Returns the count set, or None where nothing was changed: the flag was
    already given, the count is 1, or JAX's backend had started."""
    environ = os.environ if environ is None else environ
    flags = environ.get("XLA_FLAGS", "")
    if FLAG in flags:
        return None
    n = requested_devices(environ)
    if n <= 1 or backend_started():
        return None
    environ["XLA_FLAGS"] = f"{flags} {FLAG}={n}".strip()
    return n
