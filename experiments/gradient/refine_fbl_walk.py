"""Gradient refinement of the ``fbl_walk`` gait: the figures of experiments/README.md.

Adam (optax, clip_by_global_norm(1) + adam(0.002), box coordinates, float64) on the cost of
transport plus (v - 1.3)^2 over a 1 s window after 3 s of walking on flat ground (20
checkpointed segments of 0.05 s), 10 updates, each checked by a 10 s no-fall rollout::

    python experiments/gradient/refine_fbl_walk.py
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait.optim import gradient as gr
from jaxgait.train import get_model, resolve_init
from jaxgait.world.envs import make_env


def main():
    with jax.enable_x64(True):
        model = get_model("fbl")
        vec = jnp.asarray(resolve_init("fbl_walk", model.table), jnp.float64)
        env = make_env("flat", jax.random.PRNGKey(0))
        cfg = gr.WindowConfig(window_s=1.0, segment_s=0.05, warmup_s=3.0, objective="energy")
        t0 = time.perf_counter()
        res = gr.refine(
            model, vec, env, cfg, steps=10, learning_rate=0.002, check_s=10.0, progress=print
        )
    span = np.asarray(model.table.upper) - np.asarray(model.table.lower)
    change = np.abs(res.params - res.initial_params) / span
    print(f"wall time {time.perf_counter() - t0:.0f} s")
    print("objective per update:", " ".join(f"{x:.4f}" for x in res.losses))
    print("first / last window:", res.aux[0], res.aux[-1])
    print("accepted step fractions:", res.step_scales)
    print(f"walks 10 s: start {not res.fell_initial}, end {not res.fell_final}")
    print(f"largest parameter change: {100 * change.max():.2f} % of its range")


if __name__ == "__main__":
    main()
