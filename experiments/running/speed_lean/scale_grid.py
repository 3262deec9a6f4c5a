"""How far a preset's gains can move: every combination of scaled parameters, one batch.

Each ``--scale NAME=F1,F2,...`` multiplies the preset's NAME by each factor; every
combination of the factors is rolled out on flat ground at once (``vmap``) from the preset's
own v0 and pose, and the script prints, per setting, how long it ran and its speed over
successive windows; ``--out`` writes the rows as JSON (experiments/running/README.md, "A
speed regulator": how narrow the regulated runner's basin is).  Usage::

    ./jg python experiments/running/speed_lean/scale_grid.py fblplus_run_2p0 \
        --scale v_reg=1,1.12 --scale c_v=1,1.3,2 --scale c_d=1,2,4 --duration 30 --out FILE.json
"""

import argparse
import itertools
import json

import jax
import jax.numpy as jnp
import numpy as np
from grid import speed_windows  # this folder's grid.py (the script's folder is on sys.path)

from jaxgait import models, sim
from jaxgait.presets import load_preset
from jaxgait.world import envs


def scale_arg(s: str) -> tuple[str, list[float]]:
    name, _, factors = s.partition("=")
    if not name or not factors:
        raise argparse.ArgumentTypeError(f"--scale wants NAME=F1,F2,..., got {s!r}")
    return name, [float(f) for f in factors.split(",")]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("preset")
    ap.add_argument("--scale", type=scale_arg, action="append", required=True)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--window", type=float, default=5.0)
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)

    _, base, doc = load_preset(a.preset)
    mdl = models.get_model(doc["model"])
    table = mdl.table
    p0 = dict(zip(table.names, np.asarray(base, float), strict=True))
    names = [n for n, _ in a.scale]
    unknown = [n for n in names if n not in p0]
    if unknown:
        raise SystemExit(f"{doc['model']} has no parameters {unknown}")
    combos = list(itertools.product(*[f for _, f in a.scale]))
    vecs = []
    for c in combos:
        vec = table.pack({**p0, **{n: p0[n] * f for n, f in zip(names, c, strict=True)}})
        table.check(vec, f"scales {dict(zip(names, c, strict=True))}")
        vecs.append(vec)
    cfg = sim.SimConfig(duration=a.duration, v0=doc["v0"], pose=doc.get("pose", sim.SimConfig.pose))
    keys = jnp.tile(jax.random.PRNGKey(0), (len(vecs), 1))  # the same flat ground per lane
    envb = envs.make_env_batch("flat", keys)
    params = jnp.asarray(np.asarray(vecs, np.float32))
    trace, _, summary, _ = sim.make_rollout(mdl, cfg)(params, envb)
    vx = np.asarray(trace.com_vel[..., 0])
    rows = []
    for i, c in enumerate(combos):
        dur = float(summary.duration[i])
        r = {
            "scales": dict(zip(names, c, strict=True)),
            "duration_s": dur,
            "fell": bool(summary.fell[i]),
            "speed_windows": speed_windows(vx[i], dur, cfg.log_dt, a.window),
        }
        rows.append(r)
        print(json.dumps(r))
    if a.out:
        with open(a.out, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
