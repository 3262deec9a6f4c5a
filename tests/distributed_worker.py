"""One process of the ``jax.distributed`` test (``tests/test_distributed.py``).

``python tests/distributed_worker.py PORT N_PROCESSES PROCESS_ID OUT.json``: joins
``N_PROCESSES`` processes on localhost (:func:`jaxgait.core.distributed.init_distributed`,
CPU collectives over gloo) unless there is one, scores one fixed population of 8 perturbed
``fbl_walk`` candidates (1 s rollouts) with the population evaluator over every device of
every process, by direct calls and queued over 2 lanes per device, and writes the results.
"""

from __future__ import annotations

import json
import sys


def main() -> int:
    port, n_proc, pid, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    from jaxgait.core.distributed import init_distributed

    if n_proc > 1:
        init_distributed(f"localhost:{port}", n_proc, pid)
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxgait import presets
    from jaxgait.train import PopulationEvaluator, get_experiment

    doc = {"process_count": jax.process_count(), "devices": jax.device_count()}
    for label, lanes in (("direct", None), ("queued", 2)):
        ev = PopulationEvaluator(get_experiment("exp3", particles=8, duration=1.0, lanes=lanes))
        _, vec, _ = presets.load_preset("fbl_walk")
        table = ev.model.table
        rng = np.random.default_rng(0)
        pop = vec * (1 + 0.2 * rng.uniform(-1, 1, (8, vec.size)))
        pop = jnp.asarray(np.clip(pop, table.lower, table.upper), jnp.float32)
        stage, value, valid = ev.scores(pop, jax.random.split(jax.random.PRNGKey(1), 8))
        doc[label] = {
            "stage": np.asarray(stage).tolist(),
            "value": np.asarray(value).tolist(),
            "valid": np.asarray(valid).tolist(),
            "busy": int(ev.last_stats.busy),
        }
    with open(out, "w") as f:
        json.dump(doc, f)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
