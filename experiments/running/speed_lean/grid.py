"""A grid of the lean speed regulator's gains on a running preset, in one batch.

Lifts a ``fblplus_bal_run`` preset to ``fblplus_bal_run_sr`` (the same gains plus the
regulator's v_reg, k_vp, k_vi, tau_vr), rolls every combination out on flat ground at once
(``vmap``) and prints, per setting, how long it ran, its speed over successive windows and
its flight fraction; writes the table as JSON (experiments/running/README.md, "A speed
regulator").  Usage::

    ./jg python experiments/running/speed_lean/grid.py PRESET --duration 40 \
        --v-reg 2.0,2.5 --k-vp 0,0.01,0.02,0.05 --k-vi 0,0.005,0.01 --out FILE.json
"""

import argparse
import itertools
import json

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import models, sim
from jaxgait.control.speed_lean import REGULATOR_NAMES, speed_regulated
from jaxgait.presets import load_preset
from jaxgait.world import envs


def speed_windows(vx, duration: float, log_dt: float, window: float) -> list[float]:
    """Mean forward speed [m/s] of one rollout's logged ``vx`` over successive windows of
    ``window`` s up to ``duration`` (a last window less than half full is left out)."""
    n = int(round(window / log_dt))
    alive = int(duration / log_dt)
    return [
        round(float(vx[k : min(k + n, alive)].mean()), 3)
        for k in range(0, alive, n)
        if k + n // 2 < alive
    ]


def floats(s):
    return [float(x) for x in s.split(",")]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("preset")
    ap.add_argument("--model", default="fblplus_bal_run_sr")
    ap.add_argument("--duration", type=float, default=40.0)
    ap.add_argument("--v0", type=float, default=None)
    ap.add_argument("--v-reg", type=floats, default=[2.5])
    ap.add_argument("--k-vp", type=floats, default=[0.0, 0.01, 0.02, 0.05])
    ap.add_argument("--k-vi", type=floats, default=[0.0, 0.005, 0.01])
    ap.add_argument("--tau", type=floats, default=[1.0])
    ap.add_argument("--i-max", type=floats, default=[2.0])
    ap.add_argument("--window", type=float, default=5.0)
    ap.add_argument("--wrap", default=None, help="wrap this model with one more regulator")
    ap.add_argument("--command", default="hip_target_offset", help="the --wrap regulator's")
    ap.add_argument("--suffix", default="_h", help="of the --wrap regulator's names")
    ap.add_argument(
        "--vary-suffix",
        default=None,
        help="vary --model's regulator gains with this suffix (_h of fblplus_bal_run_sr2)",
    )
    ap.add_argument("--base-set", action="append", default=[], help="NAME=VALUE (repeatable)")
    ap.add_argument(
        "--unchecked", action="store_true", help="allow gains outside the table's ranges"
    )
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)

    _, _, doc = load_preset(a.preset)
    names = REGULATOR_NAMES
    if a.wrap:
        inner = models.get_model(a.wrap).controller
        ctrl = speed_regulated(inner, a.wrap + a.suffix, command=a.command, suffix=a.suffix)
        models.register(models.planar_spec(ctrl), replace=True)
        a.model, names = ctrl.name, tuple(n + a.suffix for n in REGULATOR_NAMES)
    elif a.vary_suffix:
        names = tuple(n + a.vary_suffix for n in REGULATOR_NAMES)
    mdl = models.get_model(a.model)
    base = dict(doc["params"])
    for kv in a.base_set:
        k, v = kv.split("=")
        base[k] = float(v)
    combos = list(itertools.product(a.v_reg, a.k_vp, a.k_vi, a.tau, a.i_max))
    vecs = []
    for c in combos:
        p = {**base, **dict(zip(names, c, strict=True))}
        vec = mdl.table.pack(p)
        if not a.unchecked:
            mdl.table.check(vec, f"setting {dict(zip(names, c, strict=True))}")
        vecs.append(vec)
    params = jnp.asarray(np.asarray(vecs, np.float32))
    v0 = a.v0 if a.v0 is not None else doc.get("v0", 1.3)
    cfg = sim.SimConfig(duration=a.duration, v0=float(v0), pose=doc.get("pose", sim.SimConfig.pose))
    keys = jnp.tile(jax.random.PRNGKey(0), (len(vecs), 1))  # the same flat ground per lane
    envb = envs.make_env_batch("flat", keys)
    trace, events, summary, _ = sim.make_rollout(mdl, cfg)(params, envb)
    vx = np.asarray(trace.com_vel[..., 0])
    rows = []
    for i, c in enumerate(combos):
        dur = float(summary.duration[i])
        r = dict(
            zip(names, c, strict=True),
            duration_s=dur,
            distance_m=float(summary.distance[i]),
            fell=bool(summary.fell[i]),
        )
        r["speed_windows"] = speed_windows(vx[i], dur, cfg.log_dt, a.window)
        rows.append(r)
        print(json.dumps(r))
    if a.out:
        json.dump(rows, open(a.out, "w"), indent=1)


if __name__ == "__main__":
    main()
