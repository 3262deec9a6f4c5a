"""MJX's passes against the planar tree for the step's mass matrix and bias forces
(``SimConfig.dynamics``): the full FBL step at each lane count with either, compiled side by
side and timed alternately in one process (best of ``--rounds`` rounds of 2 calls), and how
far the two float32 programs drift apart over the timed steps::

    ./jg python benchmarks/dynamics_ab.py 1 12 64 512
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
from throughput import _best_seconds, _full_program, _setup


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("lanes", type=int, nargs="*", default=[1, 12, 64])
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args(argv)
    progs = {}
    for lanes in a.lanes:
        for dyn in ("mjx", "planar"):
            model, cfg, params, env, s0 = _setup(lanes, dyn)
            arg = (s0, params, env)
            f = jax.jit(_full_program(model, cfg, a.steps)).lower(arg).compile()
            progs[lanes, dyn] = (f, arg)
        end = {d: progs[lanes, d][0](progs[lanes, d][1]) for d in ("mjx", "planar")}
        dq = float(jnp.max(jnp.abs(end["mjx"].qpos - end["planar"].qpos)))
        print(f"lanes {lanes}: max |q_mjx - q_planar| after {a.steps} steps {dq:.1e}", flush=True)
    best = {k: float("inf") for k in progs}
    for _ in range(a.rounds):
        for k, (f, arg) in progs.items():
            best[k] = min(best[k], _best_seconds(f, arg, 2))
    for lanes in a.lanes:
        m, p = best[lanes, "mjx"], best[lanes, "planar"]
        print(
            f"lanes {lanes:4d}: mjx {1e6 * m / a.steps:7.1f} us/step, planar "
            f"{1e6 * p / a.steps:7.1f} us/step, planar {m / p:.2f}x as fast"
        )


if __name__ == "__main__":
    main()
