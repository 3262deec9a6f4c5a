"""Joining a ``jax.distributed`` run: one Python process per host (or per accelerator).

Import this module and call :func:`init_distributed` before anything else of jaxgait (its
other modules create arrays at import, which starts JAX's backend and makes
``jax.distributed.initialize`` fail).  See ``docs/scaling.md``.
"""

from __future__ import annotations

import jax


def init_distributed(
    coordinator_address: str | None = None,
    num_processes: int | None = None,
    process_id: int | None = None,
) -> None:
    """Join this process to a ``jax.distributed`` run; the population evaluator then spreads
    each population over the devices of every process.

    Args:
      coordinator_address: ``"host:port"`` of process 0; num_processes, process_id: this
        run's size and this process's rank.  With none of them JAX reads a cluster
        scheduler's environment (SLURM, Open MPI, Cloud TPU).

    On CPUs the collectives go over gloo.  Each process's new arrays default to its own first
    device (JAX's default is the first global device, another process's).
    """
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address, num_processes, process_id)
    jax.config.update("jax_default_device", jax.local_devices()[0])
