"""Does unrolling the step loop pay on the CPU?  The bare FBL step scanned ``--steps`` times
at ``LANES`` lanes with ``scan``'s ``unroll`` 1, 2 and 4, alternated in one process (best of 3
per round, 3 rounds), in µs per physics step and env-steps/s::

    ./jg python benchmarks/step_unroll.py 12
"""

from __future__ import annotations

import argparse
import time

import jax
from throughput import _best_seconds, _setup

from jaxgait import sim


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("lanes", type=int, nargs="?", default=12)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--unroll", type=int, nargs="+", default=[1, 2, 4])
    a = ap.parse_args(argv)
    model, cfg, params, env, s0 = _setup(a.lanes)

    def program(unroll):
        def run(arg):
            s, p, e = arg
            f = jax.vmap(lambda p, e, s: sim.step(model, cfg, p, e, s))
            body = lambda s, _: (f(p, e, s), None)
            return jax.lax.scan(body, s, None, length=a.steps, unroll=unroll)[0]

        return jax.jit(run)

    arg = (s0, params, env)
    runs = {u: program(u) for u in a.unroll}
    for u, f in runs.items():
        t0 = time.perf_counter()
        jax.block_until_ready(f(arg))
        print(f"unroll {u}: compiled and ran once in {time.perf_counter() - t0:.1f} s")
    for _ in range(3):
        for u, f in runs.items():
            dt = _best_seconds(f, arg, 3)
            print(
                f"lanes {a.lanes} unroll {u}: {dt / a.steps * 1e6:.1f} us per step, "
                f"{a.lanes * a.steps / dt:,.0f} env-steps/s"
            )


if __name__ == "__main__":
    main()
