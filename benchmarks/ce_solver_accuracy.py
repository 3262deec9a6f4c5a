"""Accuracy of the implicit CE solve per step against the exact backward-Euler root (a benchmark).

Each muscle step solves l' = l_ce + h v_ce(A, l', l_mtu) for the normalised velocity v_n
(``jaxgait.muscles.mtu.muscle_step``).  This script takes muscle states from three sources and, in
float64, compares the step with k = 0, 1, 2, 3 solver iterations after the first
intersection against the root found by 100 bisections
(``jaxgait.muscles.mtu.backward_euler_velocity``).  It prints the CE-length error of one step,
|v_n,k - v_n,root| h v_max [l_opt], as maximum and the fraction of muscle steps above 1e-6
and 1e-5 l_opt:

* ``walk``: every step of 3 s of the ``fbl_walk`` preset walking (float32 rollout, 14 muscles);
* ``drive``: the seven Geyer muscles of one leg driven with 1.2 s of gait-like joint motion
  and stimulation;
* ``random``: 50,000 states, A in [0.01, 1] (log-uniform), l_ce in [0.4, 1.7] l_opt, l_mtu
  within 20 % of l_opt + l_slack (the range of the property test in tests/test_muscle.py).

Usage::

    python benchmarks/ce_solver_accuracy.py [--walk-seconds 3]
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import models, presets, sim
from jaxgait.muscles import mtu as mu
from jaxgait.muscles.mtu import GEYER7
from jaxgait.world import envs

DT = 5e-4
KS = (0, 1, 2, 3)


def walk_states(seconds: float):
    """(act, l_ce, l_mtu at the step's end) of every muscle step of fbl_walk, (n, 14) each."""
    model = models.get_model("fbl")
    params = jnp.asarray(presets.load_preset("fbl_walk")[1], jnp.float32)
    rec = []
    inner = mu.muscle_step

    def recording(table, state, stim, l_mtu, dt, *args, **kw):
        jax.debug.callback(
            lambda *x: rec.append([np.asarray(v) for v in x]), state.act, state.l_ce, l_mtu
        )
        return inner(table, state, stim, l_mtu, dt, *args, **kw)

    env = jax.tree.map(lambda x: x[0], envs.make_env_batch("flat", jax.random.PRNGKey(0)[None]))
    cfg = sim.SimConfig(duration=seconds, chunk_s=seconds)
    mu.muscle_step = recording
    try:
        summary = sim.make_rollout(model, cfg, batched=False)(params, env)[2]
        jax.block_until_ready(summary)
    finally:
        mu.muscle_step = inner
    if bool(summary.fell):
        raise RuntimeError("fbl_walk fell in the recorded rollout")
    act, l_ce, l_mtu = (np.stack([r[i] for r in rec]).reshape(len(rec), -1) for i in range(3))
    return act, l_ce, l_mtu, model.muscles.tiled(2)


def drive_states():
    """The states of the seven muscles of one leg under a gait-like drive, (n, 7) each."""
    table, n = GEYER7, 2400
    t = np.arange(n) * DT
    w = 2 * np.pi / 1.1
    phi_deg = np.stack(
        [165 + 20 * np.sin(w * t), 160 + 25 * np.sin(w * t + 1.0), 90 + 12 * np.sin(w * t + 2.0)],
        -1,
    )
    l_mtu = mu.mtu_length(table, jnp.asarray(np.radians(phi_deg)))
    phase = w * t[:, None] + np.arange(7)[None] * 0.9
    stim = jnp.asarray(0.01 + 0.99 * np.clip(np.sin(phase), 0, 1) ** 3)

    def f(s, x):
        s1, _ = mu.muscle_step(table, s, x[0], x[1], DT, solve_iters=12)
        return s1, (s.act, s.l_ce)

    s0 = mu.init_muscle_state(table, l_mtu[0])
    _, (act, l_ce) = jax.jit(lambda s: jax.lax.scan(f, s, (stim, l_mtu)))(s0)
    return np.asarray(act), np.asarray(l_ce), np.asarray(l_mtu), table


def random_states(n: int = 50_000, seed: int = 0):
    table = GEYER7
    rng = np.random.default_rng(seed)
    rows = n // 7
    act = 10.0 ** rng.uniform(-2.0, 0.0, (rows, 7))
    l_ce = rng.uniform(0.4, 1.7, (rows, 7)) * table.l_opt
    l_mtu = rng.uniform(0.8, 1.2, (rows, 7)) * (table.l_opt + table.l_slack)
    return act, l_ce, l_mtu, table


def errors(act, l_ce, l_mtu, table):
    """({k: (n, M) one-step CE-length error [l_opt]}, root v_n (n, M)) against bisection."""
    args = tuple(jnp.asarray(x, jnp.float64) for x in (act, l_ce, l_mtu))
    ref = jax.jit(mu.backward_euler_velocity, static_argnums=(0, 5))(table, *args, DT, 100)
    scale = DT * np.asarray(table.v_max)  # l_opt per unit v_n over one step
    out = {}
    for k in KS:

        @jax.jit
        def v_n(a, lc, lm, k=k):
            _, info = mu.muscle_step(table, mu.MuscleState(a, lc), a, lm, DT, solve_iters=k)
            return info["v_ce"] / jnp.asarray(table.v_max * table.l_opt)

        out[k] = np.abs(np.asarray(v_n(*args) - ref)) * scale
    return out, np.asarray(ref)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--walk-seconds", type=float, default=3.0)
    a = ap.parse_args(argv)
    walk = walk_states(a.walk_seconds)  # float32, as the rollouts run
    with jax.enable_x64(True):
        sets = {"walk": walk, "drive": drive_states(), "random": random_states()}
        print(f"one-step CE-length error vs the bisection root, h = {DT * 1e3:g} ms [l_opt]")
        for name, states in sets.items():
            errs, root = errors(*states)
            names = np.asarray(states[3].names)[None].repeat(root.shape[0], 0)
            subsets = [(name, np.ones(root.shape, bool))]
            if name == "random":  # and the range of eq. 2.16's first two branches
                subsets.append(("random, |v_n| <= 1", np.abs(root) <= 1.0))
            for label, keep in subsets:
                for k, e in errs.items():
                    e, worst = e[keep], names[keep][np.argmax(e[keep])]
                    print(
                        f"{label} ({e.size} muscle steps) k = {k}: max {e.max():.1e} ({worst}), "
                        f"> 1e-6: {100 * (e > 1e-6).mean():.3f} %, "
                        f"> 1e-5: {100 * (e > 1e-5).mean():.3f} %"
                    )


if __name__ == "__main__":
    main()
