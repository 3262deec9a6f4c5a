"""How far a preset's gains can move: every combination of scaled parameters, one batch.

Each ``--scale NAME=F1,F2,...`` multiplies the preset's NAME by each factor, each
``--value NAME=V1,V2,...`` sets it to each value; every combination is rolled out on flat
ground at once (``vmap``) from the preset's own v0 and pose, and the script prints, per
setting, how long it ran and its speed over
successive windows; ``--out`` writes the rows as JSON (experiments/running/README.md, "A
speed regulator": how narrow the regulated runner's basin is).  Usage::

    ./jg python experiments/running/speed_lean/scale_grid.py fblplus_run_2p0 \
        --scale v_reg=1,1.12 --scale c_v=1,1.3,2 --scale c_d=1,2,4 --duration 30 --out FILE.json
    ./jg python experiments/running/speed_lean/scale_grid.py experiments/running/speed_lean/se_a \
        --value d_sw_end=0,0.1,0.2,0.3 --scale v_reg=1,1.1,1.2 --scale kp_VAS=1,1.5 --duration 20
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
    ap.add_argument("--scale", type=scale_arg, action="append", default=[])
    ap.add_argument("--value", type=scale_arg, action="append", default=[])
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--window", type=float, default=5.0)
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)

    _, base, doc = load_preset(a.preset)
    mdl = models.get_model(doc["model"])
    table = mdl.table
    p0 = dict(zip(table.names, np.asarray(base, float), strict=True))
    if not a.scale and not a.value:
        raise SystemExit("give at least one --scale or --value")
    axes = [(n, f, True) for n, f in a.scale] + [(n, v, False) for n, v in a.value]
    names = [n for n, _, _ in axes]
    unknown = [n for n in names if n not in p0]
    if unknown:
        raise SystemExit(f"{doc['model']} has no parameters {unknown}")
    combos = list(itertools.product(*[f for _, f, _ in axes]))
    vecs = []
    for c in combos:
        new = {n: p0[n] * x if scaled else x for (n, _, scaled), x in zip(axes, c, strict=True)}
        vec = table.pack({**p0, **new})
        table.check(vec, f"settings {dict(zip(names, c, strict=True))}")
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
            "scales": {n: x for (n, _, scaled), x in zip(axes, c, strict=True) if scaled},
            "values": {n: x for (n, _, scaled), x in zip(axes, c, strict=True) if not scaled},
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
