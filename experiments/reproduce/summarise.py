"""Summarise reproduction runs of ``python -m jaxgait.train``: the table of experiments/README.md.

For each results folder given it reads ``config.json`` and ``history.csv`` (size, wall time,
rollouts/s, stage counts), re-evaluates the best parameter set for 60 s on flat ground with
``python -m jaxgait.evaluate``, measures how many of 16 copies perturbed by 1e-6 (relative)
still walk 30 s, and, with ``--robustness``, runs ``python -m jaxgait.robustness``
on it.  It writes ``summary.json`` into each folder, copies the small artefacts (config, best
preset, parameter table, history, summary) to ``--copy-to``/NAME, and prints a Markdown table.

    python experiments/reproduce/summarise.py runs/exp1 runs/exp2 --copy-to experiments/reproduce
    python experiments/reproduce/summarise.py runs/exp7a --robustness --seeds 3
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

SMALL = ("config.json", "best.json", "best_params.txt", "history.csv", "summary.json")


def _json_cmd(args: list[str]) -> dict:
    out = subprocess.run(
        [sys.executable, "-m", *args, "--json"], capture_output=True, text=True, check=True
    )
    # the JSON document is the last line (MJX's import may print notices before it)
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    return json.loads(lines[-1])


def perturbation_survival(folder: Path, n: int = 16, rel: float = 1e-6, duration: float = 30.0):
    """Fraction of ``n`` copies of the best parameters, each scaled by (1 + rel N(0, 1)),
    that walk ``duration`` s on flat ground without falling (a gait that only survives its
    own rounding errors scores low)."""
    import jax
    import jax.numpy as jnp

    from jaxgait import models, sim
    from jaxgait.train import perturbed_copies
    from jaxgait.world import envs

    doc = json.loads((folder / "best.json").read_text())
    model = models.get_model(doc.get("model", "fbl"))
    vec = jnp.asarray([doc["params"][k] for k in model.table.names], jnp.float32)
    pert = perturbed_copies(vec, jax.random.PRNGKey(1), n, rel)
    env = envs.make_env_batch("flat", jax.random.split(jax.random.PRNGKey(0), n))
    v0 = float(doc.get("v0", sim.SimConfig.v0))
    roll = sim.make_rollout(model, sim.SimConfig(duration=duration, v0=v0), batched=True)
    summ = roll(pert, env)[2]
    return float(1.0 - jnp.mean(summ.fell.astype(jnp.float32)))


def summarise(folder: Path, duration: float, robustness: bool, seeds: int) -> dict:
    cfg = json.loads((folder / "config.json").read_text())["experiment"]
    with open(folder / "history.csv") as f:
        hist = list(csv.DictReader(f))
    if not hist:
        raise SystemExit(f"{folder}: history.csv has no iterations yet")
    seconds = sum(float(r["seconds"]) for r in hist)
    rollouts = sum(int(r["rollouts"]) for r in hist)
    last = hist[-1]
    stages = {k: int(v) for k, v in last.items() if k.startswith("stage_")}
    ev = _json_cmd(["jaxgait.evaluate", str(folder), "--duration", str(duration)])
    rep = {
        "experiment": cfg.get("name"),
        "particles": cfg.get("particles"),
        "iterations_done": len(hist),
        "iterations_planned": cfg.get("iterations"),
        "wall_s": seconds,
        "rollouts": rollouts,
        "rollouts_per_s": rollouts / seconds if seconds > 0 else float("nan"),
        "best_stage": int(last["best_stage"]),
        "best_value": float(last["best_value"]),
        "final_stage_counts": stages,
        "eval_duration_s": duration,
        "eval": {
            k: ev.get(k)
            for k in (
                "distance_m",
                "duration_s",
                "fell",
                "mean_speed_mps",
                "energy_J_per_m",
                "cost_of_transport",
                "c_angles",
                "corr_hip",
                "corr_knee",
                "corr_ankle",
                "step_length_snr",
                "step_length_mean_m",
                "n_steps",
                "mean_trunk_lean_deg",
            )
        },
    }
    rep["survival_1e-6_perturbed_30s"] = perturbation_survival(folder)
    if robustness:
        rep["robustness"] = _json_cmd(["jaxgait.robustness", str(folder), "--seeds", str(seeds)])
    (folder / "summary.json").write_text(json.dumps(rep, indent=2) + "\n")
    return rep


def row(rep: dict) -> str:
    e = rep["eval"]
    fell = "fell" if e["fell"] else "no fall"
    return (
        f"| {rep['experiment']} | {rep['particles']} x {rep['iterations_done']} "
        f"| {rep['wall_s'] / 60:.0f} min, {rep['rollouts_per_s']:.2f} rollouts/s "
        f"| {e['distance_m']:.1f} m in {e['duration_s']:.0f} s, {fell} "
        f"| {e['mean_speed_mps']:.2f} | {e['energy_J_per_m']:.0f} | {e['step_length_snr']:.1f} "
        f"| {e['c_angles']:.2f} ({e['corr_hip']:.2f}/{e['corr_knee']:.2f}/{e['corr_ankle']:.2f}) "
        f"| {rep['survival_1e-6_perturbed_30s']:.2f} |"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--duration", type=float, default=60.0, help="evaluation time [s] (60)")
    ap.add_argument("--robustness", action="store_true", help="also run jaxgait.robustness")
    ap.add_argument("--seeds", type=int, default=3, help="robustness environment draws (3)")
    ap.add_argument("--copy-to", type=Path, default=None, help="copy small artefacts here")
    a = ap.parse_args(argv)
    print(
        "| experiment | size | wall time | 60 s re-evaluation | speed [m/s] | energy [J/m] "
        "| step SNR | C_angles (hip/knee/ankle) | survives 1e-6 perturbation |"
    )
    print("| --- | --- | --- | --- | ---: | ---: | ---: | --- | ---: |")
    for folder in a.folders:
        rep = summarise(folder, a.duration, a.robustness, a.seeds)
        print(row(rep), flush=True)
        if a.copy_to is not None:
            dst = a.copy_to / folder.name
            dst.mkdir(parents=True, exist_ok=True)
            for name in SMALL:
                if (folder / name).exists():
                    shutil.copy2(folder / name, dst / name)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
