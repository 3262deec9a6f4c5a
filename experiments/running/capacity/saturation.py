"""How close a gait runs to its muscles' capacity: per muscle, the fraction of each phase
(swing, stance) with activation above a threshold, and its largest activation.

Each preset (and each ``--scale NAME=F`` variant of the first one) is rolled out on flat
ground from its own v0 and pose, one lane each, and the right leg's activations are split by
the filtered ground contact into stance and swing over the rollout (after ``--skip`` seconds
of start).  ``--out`` writes the rows as JSON (experiments/running/README.md, "Muscle
capacity").  Usage::

    ./jg python experiments/running/capacity/saturation.py fblplus_push_run_1p8 fblplus_run_2p0 \
        wang_run_2p5 fbl_walk --variant G_SOL=1.1 --duration 10 --out FILE.json
"""

from __future__ import annotations

import argparse
import json

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import models, sim
from jaxgait.presets import load_preset
from jaxgait.world import envs


def variant_arg(s: str) -> dict[str, float]:
    out = {}
    for part in s.split(","):
        name, _, f = part.partition("=")
        if not name or not f:
            raise argparse.ArgumentTypeError(f"--variant wants NAME=F[,NAME=F...], got {s!r}")
        out[name] = float(f)
    return out


def phase_table(act, stance, alive, names, threshold):
    """{phase: {muscle: (fraction above threshold, max)}} of one leg's (T, M) activations."""
    rows = {}
    for phase, mask in (("swing", alive & ~stance), ("stance", alive & stance)):
        a = act[mask]
        rows[phase] = {
            n: {"above": float(np.mean(a[:, k] > threshold)), "max": float(a[:, k].max())}
            for k, n in enumerate(names)
        }
    return rows


def rollout(preset: str, scales: dict[str, float], duration: float):
    _, base, doc = load_preset(preset)
    mdl = models.get_model(doc["model"])
    p0 = dict(zip(mdl.table.names, np.asarray(base, float), strict=True))
    unknown = sorted(set(scales) - set(p0))
    if unknown:
        raise SystemExit(f"{doc['model']} has no parameters {unknown}")
    vec = mdl.table.pack({**p0, **{k: p0[k] * f for k, f in scales.items()}})
    mdl.table.check(vec, f"{preset} scaled by {scales}")
    cfg = sim.SimConfig(
        duration=duration,
        v0=doc.get("v0", sim.SimConfig.v0),
        pose=doc.get("pose", sim.SimConfig.pose),
        log_dt=0.002,
    )
    envb = envs.make_env_batch("flat", jax.random.PRNGKey(0)[None])
    trace, _, summary, _ = sim.make_rollout(mdl, cfg)(jnp.asarray(vec, jnp.float32)[None], envb)
    return mdl, jax.tree_util.tree_map(lambda x: np.asarray(x[0]), trace), summary


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("presets", nargs="+")
    ap.add_argument("--variant", type=variant_arg, action="append", default=[])
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--skip", type=float, default=2.0, help="start seconds left out [s]")
    ap.add_argument("--threshold", type=float, default=0.95)
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)

    cases = [(p, {}) for p in a.presets] + [(a.presets[0], v) for v in a.variant]
    rows = []
    for preset, scales in cases:
        mdl, tr, summ = rollout(preset, scales, a.duration)
        alive = tr.alive & (tr.t >= a.skip)
        names = mdl.muscles.names
        table = phase_table(tr.act[:, 0], tr.stance[:, 0], alive, names, a.threshold)
        dur = float(summ.duration[0])
        row = {
            "preset": preset,
            "scales": scales,
            "model": mdl.name,
            "duration_s": dur,
            "fell": bool(summ.fell[0]),
            "speed": float(tr.com_vel[alive, 0].mean()) if alive.any() else float("nan"),
            "threshold": a.threshold,
            **table,
        }
        rows.append(row)
        tag = f"{preset} {scales or ''}".strip()
        print(f"{tag}: {dur:.1f} s{' (fell)' if row['fell'] else ''}, {row['speed']:.2f} m/s")
        for phase in ("swing", "stance"):
            cells = [f"{n} {v['above']:.2f}" for n, v in table[phase].items()]
            print(f"  {phase:6s} above {a.threshold}: " + "  ".join(cells))
    if a.out:
        with open(a.out, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
