"""CMA-ES search that produced the shipped ``fbl_walk`` preset.

Starts from the Geyer-Herr "G" gain family (``jaxgait.control.fbl.FBL`` initial values) and
maximises a walking score on flat ground:

    walk:    score = d + (not fell) (20 - 10 |v - v*|)                       (v* = 1.3 m/s)
    refine:  score = d + (not fell) (50 + 10 C_angles - 20 |v - v*| - 0.02 E/d)

with d the distance walked (centre of mass) before a fall or the end of the rollout,
C_angles the thesis joint-angle similarity (eq. 2.51) and E/d the metabolic energy per metre.
The runs that made the shipped preset, with their commands, are listed in
``experiments/fbl_walk/README.md``.

Writes ``best.json`` (a preset) and ``history.csv`` into ``--out`` after every generation.
"""

from __future__ import annotations

import argparse
import functools
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import models, sim
from jaxgait.analysis.measures import compute_measures
from jaxgait.core.params import save_preset
from jaxgait.optim import make_strategy
from jaxgait.world import envs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--generations", type=int, default=120)
    ap.add_argument("--popsize", type=int, default=24)
    ap.add_argument("--duration", type=float, default=15.0)
    ap.add_argument("--sigma", type=float, default=0.1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--v-target", type=float, default=1.3)
    ap.add_argument("--init", type=str, default=None, help="preset JSON to start from")
    ap.add_argument("--objective", choices=("walk", "refine"), default="walk")
    ap.add_argument(
        "--push",
        type=float,
        default=0.0,
        help="if > 0, each candidate is also scored with one push of this amplitude [N] at a "
        "random time (fresh every generation) and keeps its worse score",
    )
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "run")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)

    model = models.get_model("fbl")
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
    k_env = 2 if a.push > 0 else 1
    push_cfg = envs.get_env_config(
        "push", magnitude=max(a.push, 1.0), t_min=2.0, t_max=a.duration - 3.0
    )
    roll = sim.make_rollout(model, cfg)

    measure = jax.vmap(functools.partial(compute_measures, skip=2))

    @jax.jit
    def score(trace, events, summary):
        d = summary.distance
        v = d / jnp.maximum(summary.duration, 1e-6)
        alive = ~summary.fell
        if a.objective == "walk":
            return d + alive * (20.0 - 10.0 * jnp.abs(v - a.v_target))
        m = measure(trace, events, summary)
        bonus = 50.0 + 10.0 * m["c_angles"] - 20.0 * jnp.abs(v - a.v_target)
        return d + alive * (bonus - 0.02 * m["energy_J_per_m"])

    hist = open(a.out / "history.csv", "w")
    hist.write("generation,best_score,gen_best,gen_mean,n_alive,mean_speed_best,seconds\n")
    hist.flush()
    best = (-np.inf, None)
    for g in range(a.generations):
        t0 = time.time()
        key, k = jax.random.split(key)
        pop, state = strat.ask(k, state)
        env = envs.make_env_batch("flat", jax.random.split(k, a.popsize))
        if k_env == 2:  # worst of (flat, flat + one push at a random time)
            pushed = envs.make_env_batch(
                push_cfg, jax.random.split(jax.random.fold_in(k, 1), a.popsize)
            )
            env = jax.tree.map(lambda x, y: jnp.concatenate([x, y]), env, pushed)
        pop_k = jnp.concatenate([pop] * k_env)
        tr, ev, summ_k, _ = roll(pop_k, env)
        s_k = np.asarray(score(tr, ev, summ_k)).reshape(k_env, a.popsize)
        worst = np.argmin(s_k, axis=0)
        s = s_k[worst, np.arange(a.popsize)]
        pick = (worst, np.arange(a.popsize))
        summ = jax.tree.map(lambda x, p=pick: np.asarray(x).reshape(k_env, a.popsize)[p], summ_k)
        state = strat.tell(state, pop, -jnp.asarray(s))
        i = int(np.nanargmax(s))
        if s[i] > best[0]:
            best = (float(s[i]), np.asarray(pop[i]))
            dur = float(summ.duration[i])
            save_preset(
                a.out / "best.json",
                "fbl",
                table,
                best[1],
                description="CMA-ES walking search from the Geyer-Herr G gain family",
                score=best[0],
                distance_m=float(summ.distance[i]),
                duration_s=dur,
                fell=bool(summ.fell[i]),
                generation=g,
                seed=a.seed,
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
