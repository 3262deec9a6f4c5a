"""Does a 1 ms physics step keep the gait of the 0.5 ms default?  (issue: the time step)

For each preset it rolls the gait out on flat ground at dt = 1, 0.5 and 0.25 ms (each from the
same initial state, the model rebuilt with that MJCF time step) and compares the gait
measures against the 0.25 ms reference with the tolerance of ``tests/test_walk.py``'s
convergence test: mean speed, mean step length, cycle frequency and energy per metre within
5 % relative, double-stance fraction within 0.03 absolute.  It also times the rollout at each
step.  Writes ``results.json`` beside this file::

    ./jg python experiments/timestep/study.py                       # fbl_walk, fblplus_walk
    ./jg python experiments/timestep/study.py --presets runs/exp5 --duration 20
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

REL = ("mean_speed_mps", "step_length_mean_m", "cycle_frequency_hz", "energy_J_per_m")
ABS = {"double_stance_fraction": 0.03}
KEEP = REL + tuple(ABS) + ("distance_m", "duration_s", "fell", "n_steps", "c_angles")


def walk(model_name: str, vec, duration: float, dt: float | None) -> tuple[dict, float]:
    import jax
    import jax.numpy as jnp

    from jaxgait import models, sim
    from jaxgait.analysis.measures import compute_measures
    from jaxgait.world import envs

    model = models.get_model(model_name, dt)
    cfg = sim.SimConfig(duration=duration, chunk_s=1.0)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    f = sim.make_rollout(model, cfg, batched=False)
    p = jnp.asarray(vec, jnp.float32)
    jax.block_until_ready(f(p, env))
    t = time.perf_counter()
    tr, ev, sm, _ = jax.block_until_ready(f(p, env))
    secs = time.perf_counter() - t
    m = compute_measures(tr, ev, sm, skip=2)
    return {k: float(v) for k, v in m.items() if getattr(v, "ndim", 1) == 0}, secs


def divergence(name: str, steps, times=(0.05, 0.1, 0.2, 0.3, 0.5, 1.0, 1.5, 2.0)) -> dict:
    """Largest joint-angle difference [rad] of each step against the finest, logged every
    1 ms over the first 2.5 s, and the vertical GRF's roughness (mean |second difference|
    over the first second, N) of each step."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxgait import models, sim
    from jaxgait.presets import load_preset
    from jaxgait.world import envs

    model_name, vec, _ = load_preset(name)
    traces = {}
    for dt in steps:
        model = models.get_model(model_name, dt)
        cfg = sim.SimConfig(duration=2.5, chunk_s=0.5, log_dt=0.001)
        env = envs.make_env("flat", jax.random.PRNGKey(0))
        f = sim.make_rollout(model, cfg, batched=False)
        traces[dt] = jax.tree.map(np.asarray, f(jnp.asarray(vec, jnp.float32), env)[0])
    ref = traces[min(steps)]
    out = {}
    for dt, tr in traces.items():
        g = tr.grf.reshape(tr.grf.shape[0], -1)[:1000]
        row = {"grf_roughness_N": float(np.abs(np.diff(g, 2, axis=0)).mean())}
        if dt != min(steps):
            for t in times:
                i = int(round(t / 0.001)) - 1
                row[f"max_qpos_diff_at_{t:g}s"] = float(np.abs(tr.qpos[i] - ref.qpos[i]).max())
        out[f"{dt * 1e3:g} ms"] = row
        print(f"{name} {dt * 1e3:g} ms: " + ", ".join(f"{k} {v:.3f}" for k, v in row.items()))
    return out


def main(argv=None) -> int:
    from jaxgait.presets import load_preset

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=["fbl_walk", "fblplus_walk"])
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--steps", nargs="+", type=float, default=[0.001, 0.0005, 0.00025])
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("results.json"))
    a = ap.parse_args(argv)
    report = {"duration_s": a.duration, "tolerance": {"relative": 0.05, **ABS}, "presets": {}}
    ok_all = True
    for name in a.presets:
        model, vec, _ = load_preset(name)
        runs = {}
        for dt in a.steps:
            m, secs = walk(model, vec, a.duration, dt)
            runs[dt] = {**{k: m.get(k) for k in KEEP if k in m}, "wall_s": round(secs, 2)}
            print(
                f"{name} dt {dt * 1e3:g} ms: "
                + ", ".join(f"{k} {m[k]:.4g}" for k in KEEP if k in m)
                + f", {secs:.1f} s wall",
                flush=True,
            )
        ref = runs[min(a.steps)]
        verdict = {}
        for dt, r in runs.items():
            if dt == min(a.steps):
                continue
            dev = {k: abs(r[k] - ref[k]) / max(abs(ref[k]), 1e-12) for k in REL}
            dev.update({k: abs(r[k] - ref[k]) for k in ABS})
            within = (
                not r["fell"]
                and not ref["fell"]
                and all(dev[k] <= 0.05 for k in REL)
                and all(dev[k] <= ABS[k] for k in ABS)
            )
            verdict[dt] = {"within_tolerance": within, "deviation": dev}
            ok_all &= within or dt != 0.001
            print(
                f"  {dt * 1e3:g} ms vs {min(a.steps) * 1e3:g} ms: "
                f"{'within' if within else 'OUTSIDE'} tolerance; "
                + ", ".join(f"{k} {v:.3g}" for k, v in dev.items()),
                flush=True,
            )
        report["presets"][name] = {
            "model": model,
            "runs": {f"{k * 1e3:g} ms": v for k, v in runs.items()},
            "against_finest": {f"{k * 1e3:g} ms": v for k, v in verdict.items()},
        }
    report["divergence"] = {a.presets[0]: divergence(a.presets[0], a.steps)}
    a.out.write_text(json.dumps(report, indent=2) + "\n")
    print(f"1 ms within tolerance for every preset: {ok_all}; written {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
