"""CMA-ES search that produced the shipped ``fbl_walk`` preset.

Starts from the Geyer-Herr "G" gain family (``jaxgait.params.FBL`` initial values) and
maximises a walking score on flat ground:

    score = d + (not fell) * (20 - 10 |v - v*|)         (v* = 1.3 m/s)

with d the distance walked (centre of mass) before a fall or the end of the rollout.
Usage (from the repository root):

    python experiments/fbl_walk/search.py --generations 120 --popsize 24 --duration 15

Writes ``best.json`` (a preset) and ``history.csv`` into ``--out`` after every generation.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import envs, sim
from jaxgait.optim import make_strategy
from jaxgait.params import save_preset


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--generations", type=int, default=120)
    ap.add_argument("--popsize", type=int, default=24)
    ap.add_argument("--duration", type=float, default=15.0)
    ap.add_argument("--sigma", type=float, default=0.1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--v-target", type=float, default=1.3)
    ap.add_argument("--init", type=str, default=None, help="preset JSON to start from")
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "run")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)

    model = sim.make_model()
    table = model.table
    cfg = sim.SimConfig(duration=a.duration, chunk_s=1.0)
    init = table.init
    if a.init:
        init = table.pack(json.loads(Path(a.init).read_text())["params"])
    strat = make_strategy("cmaes", a.popsize, sigma_init=a.sigma)
    key = jax.random.PRNGKey(a.seed)
    lower = jnp.asarray(table.lower, jnp.float32)
    upper = jnp.asarray(table.upper, jnp.float32)
    state = strat.init(key, (lower, upper), jnp.asarray(init, jnp.float32))
    env = envs.make_env_batch("flat", jax.random.split(key, a.popsize))
    roll = sim.make_rollout(model, cfg)

    @jax.jit
    def score(summary):
        d = summary.distance
        v = d / jnp.maximum(summary.duration, 1e-6)
        alive = ~summary.fell
        return d + alive * (20.0 - 10.0 * jnp.abs(v - a.v_target))

    hist = open(a.out / "history.csv", "w")
    hist.write("generation,best_score,gen_best,gen_mean,n_alive,mean_speed_best,seconds\n")
    best = (-np.inf, None)
    for g in range(a.generations):
        t0 = time.time()
        key, k = jax.random.split(key)
        pop, state = strat.ask(k, state)
        _, _, summ, _ = roll(pop, env)
        s = np.asarray(score(summ))
        state = strat.tell(state, pop, -jnp.asarray(s))
        i = int(np.nanargmax(s))
        if s[i] > best[0]:
            best = (float(s[i]), np.asarray(pop[i]))
            dur = float(summ.duration[i])
            save_preset(
                a.out / "best.json", "fbl", table, best[1],
                description="CMA-ES walking search from the Geyer-Herr G gain family",
                score=best[0], distance_m=float(summ.distance[i]), duration_s=dur,
                fell=bool(summ.fell[i]), generation=g, seed=a.seed,
            )
        v = float(summ.distance[i] / max(float(summ.duration[i]), 1e-6))
        line = (
            f"{g},{best[0]:.3f},{s[i]:.3f},{np.nanmean(s):.3f},{int((~np.asarray(summ.fell)).sum())},"
            f"{v:.3f},{time.time() - t0:.1f}"
        )
        hist.write(line + "\n")
        hist.flush()
        print(line, flush=True)


if __name__ == "__main__":
    main()
