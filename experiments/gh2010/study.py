"""Geyer's model as Geyer ran it: do the Geyer-Herr "G" gains walk unoptimised in jaxgait?

Rolls the parameter table's initial values (Geyer's own gains, geyer_reference.md 2c) out
from Geyer's start (pose "geyer", 1.3 m/s; section 4) on flat ground under a sequence of
configurations that bring jaxgait closer to Geyer's Simulink model one difference at a time,
and prints / writes how long each walks:

  ./jg python experiments/gh2010/study.py [--duration 20] [--out experiments/gh2010]

It also writes the preset ``fbl_gh2010`` (``experiments/presets/fbl_gh2010.json``): the
faithful configuration's model with the G gains (``--write-preset``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp

from jaxgait import sim
from jaxgait.analysis.measures import compute_measures
from jaxgait.control.fbl import FBL, FBL_CONTROLLER
from jaxgait.control.gait import GaitConfig
from jaxgait.control.gh2010 import GH2010_CONTROLLER, GH2010_PARAMS
from jaxgait.world import envs

SHEET = GaitConfig(load_signal="thigh_sheet")
CONTACT = GaitConfig(load_signal="thigh_sheet", stance_on=0.001, stance_off=0.0005)
#: the values where the SCONE/A family differs from G (geyer_reference.md 2c, "Reading")
S_GAINS = {
    "G_VAS": 1.15, "G_TA_SOL": 0.3, "G_HFL": 0.35, "loff_HFL": 0.6, "G_GLU": 0.4,
    "S0_VAS": 0.09, "loff_TA": 0.71, "k_d": 0.25,
}  # fmt: skip

#: (name, what changes against the previous row, controller, gait config, k_bw, time step)
CONFIGS = (
    ("fbl", "jaxgait's FBL (Table 2.4 law, k_bw 1.2 x filtered GRF)", FBL_CONTROLLER,
     GaitConfig(), 1.2, None),
    ("fbl+balance", "Geyer's stance balance block (S0 gated by load, GLU = 0.7 HAM)",
     GH2010_CONTROLLER, GaitConfig(), 1.2, None),
    ("fbl+sheet", "FBL's law on the thigh pressure-sheet load (k_bw 1)", FBL_CONTROLLER,
     SHEET, 1.0, None),
    ("gh2010", "both: the GH2010-faithful configuration (model fbl_gh2010)",
     GH2010_CONTROLLER, SHEET, 1.0, None),
    ("gh2010 dt 0.25 ms", "the same at half the time step", GH2010_CONTROLLER, SHEET, 1.0,
     0.00025),
    ("gh2010 dt 0.1 ms", "the same at a fifth of the time step", GH2010_CONTROLLER, SHEET, 1.0,
     0.0001),
    ("fbl dt 0.1 ms", "jaxgait's FBL at a fifth of the time step", FBL_CONTROLLER,
     GaitConfig(), 1.2, 0.0001),
    ("gh2010 contact", "stance on any ground contact (thresholds 0.001/0.0005 BW, not 0.05/0.01)",
     GH2010_CONTROLLER, CONTACT, 1.0, None),
    ("gh2010 S gains", "the other gain family (SCONE/A, geyer_reference.md 2c)",
     GH2010_CONTROLLER, SHEET, 1.0, None, S_GAINS),
    ("gh2010 swing hip 150", "Thatte's start: swing hip 150 deg, not 140 (section 4)",
     GH2010_CONTROLLER, SHEET, 1.0, None, {}, "thatte"),
    ("gh2010 reflex start", "muscles start at the controller's stimulation (a fixed point), not "
     "at 0.01", GH2010_CONTROLLER, SHEET, 1.0, None, {}, "geyer", {"start_activation": "reflex"}),
    ("gh2010 zero delays", "delay lines start at 0 (Simulink transport delays), not at the "
     "start's sensors", GH2010_CONTROLLER, SHEET, 1.0, None, {}, "geyer",
     {"start_delays": "zero"}),
)  # fmt: skip


def run(controller, gait, k_bw, timestep, duration, gains=None, pose="geyer", start=None, v0=1.3):
    model = sim.planar_model(controller, timestep, gait=gait)
    params = dict(GH2010_PARAMS, k_bw=k_bw, **(gains or {}))
    vec = jnp.asarray([params[n] for n in FBL.names], jnp.float32)
    cfg = sim.SimConfig(duration=duration, chunk_s=1.0, v0=v0, pose=pose, **(start or {}))
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    tr, ev, sm, _ = sim.make_rollout(model, cfg, batched=False)(vec, env)
    m = compute_measures(tr, ev, sm, skip=0)
    keys = ("fell", "duration_s", "distance_m", "mean_speed_mps", "n_steps")
    return {k: (bool(m[k]) if k == "fell" else float(m[k])) for k in keys}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--out", type=Path, default=Path("experiments/gh2010"))
    ap.add_argument("--write-preset", action="store_true")
    a = ap.parse_args(argv)
    rows = []
    for name, what, ctrl, gait, k_bw, dt, *rest in CONFIGS:
        r = run(ctrl, gait, k_bw, dt, a.duration, *rest)
        r.update(config=name, change=what, timestep_s=dt or 0.0005, k_bw=k_bw)
        rows.append(r)
        state = "falls" if r["fell"] else "walks on"
        print(
            f"{name:18s} {state} at {r['duration_s']:6.2f} s: {r['distance_m']:6.2f} m at "
            f"{r['mean_speed_mps']:.2f} m/s, {r['n_steps']:.0f} steps  ({what})",
            flush=True,
        )
    a.out.mkdir(parents=True, exist_ok=True)
    doc = {"duration_s": a.duration, "gains": "table initial values (G family)", "rows": rows}
    (a.out / "results.json").write_text(json.dumps(doc, indent=2) + "\n")
    if a.write_preset:
        preset = {
            "model": "fbl_gh2010",
            "table": "fbl",
            "description": (
                "Geyer's own gains (G family, geyer_reference.md 2c) on the GH2010-faithful "
                "configuration: Geyer's stance balance block and thigh pressure-sheet load "
                "signal (k_bw 1), unoptimised; see experiments/gh2010/README.md"
            ),
            "params": {n: float(GH2010_PARAMS[n]) for n in FBL.names},
        }
        path = Path("experiments/presets/fbl_gh2010.json")
        path.write_text(json.dumps(preset, indent=2) + "\n")
        print(f"preset written: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
