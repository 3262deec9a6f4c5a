"""Sub-commands of ``python -m jaxgait.spinal`` for online control (thesis 7.3, 8.2):

* ``tune PRESET --name NAME``: train the command law's gains with CMA-ES
  (:func:`jaxgait.spinal.tune.tune`), write the trained preset, its history and held-out
  scores;
* ``range PRESET...``: the slowest and fastest constant target speed each model holds
  (:func:`jaxgait.spinal.auto.speed_range`);
* ``climb PRESET...``: distance and steepest grade on the increasing slope, seeds as
  mean +- SD (thesis Fig. 7.5; :func:`jaxgait.analysis.robustness.walk_tests`);
* ``maps PRESET``: the systematic searches of thesis Fig. 7.9-7.10, the commands of Fig. 7.8
  two by two over its ranges (n x n values) for each of several omega values;
* ``walkrun PRESET [--drive NAME=WALK:RUN ...]``: the commands ramped from walking to
  running values and back in one rollout (thesis 7.3.2; :mod:`jaxgait.spinal.walkrun`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from jaxgait.core.jsonio import json_safe
from jaxgait.presets import load_preset
from jaxgait.spinal.record import SpinalError


def label(preset: str) -> str:
    """A short name of a preset argument (file stem or folder name)."""
    return Path(str(preset)).stem if str(preset).endswith(".json") else Path(str(preset)).name


def write_json(out: Path, name: str, doc) -> Path:
    """``out/name`` with ``doc`` as strict JSON (NaN as null)."""
    out.mkdir(parents=True, exist_ok=True)
    p = out / name
    p.write_text(json.dumps(json_safe(doc), indent=1, allow_nan=False) + "\n")
    return p


def floats(text: str, flag: str) -> list[float]:
    """v1,v2,... or LO:HI:N."""
    try:
        if ":" in text:
            lo, hi, n = text.split(":")
            return [float(v) for v in np.linspace(float(lo), float(hi), int(n))]
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise SpinalError(f"{flag} takes v1,v2,... or LO:HI:N, got {text!r}") from None


def cmd_tune(a) -> dict:
    from jaxgait.spinal.figures import plot_tuning
    from jaxgait.spinal.tune import Tuning, evaluate_law, tune

    vr = floats(a.v_range, "--v-range")
    if len(vr) != 2:
        raise SpinalError(f"--v-range takes LO,HI, got {a.v_range!r}")
    tcfg = Tuning(
        tune=tuple(n.strip() for n in a.gains.split(",") if n.strip()),
        v_range=(vr[0], vr[1]),
        segments=a.segments,
        segment_s=a.segment,
        settle_s=a.settle,
        profiles=a.profiles,
        slope_s=a.slope,
        slope_target=a.slope_target,
        grade=a.grade,
        grade_ramp_m=a.grade_ramp,
        popsize=a.popsize,
        generations=a.generations,
        sigma=a.sigma,
        seed=a.seed,
    )
    res = tune(a.preset, tcfg)
    doc = dict(res["preset"], model=a.name)
    doc["description"] = f"{doc.get('description', '')}; gains trained with CMA-ES".lstrip("; ")
    path = write_json(Path(a.out_dir), f"{a.name}.json", doc)
    held_out = {
        "start": evaluate_law(a.preset, tcfg, a.held_out, seed=1000 + a.seed),
        "trained": evaluate_law(path, tcfg, a.held_out, seed=1000 + a.seed),
    }
    for k, v in held_out.items():
        print(
            f"held-out ({a.held_out} profiles): {k} RMS {v['rms_mean_mps']:.3f} m/s, "
            f"fitness {v['fitness']:.4f}"
            + (f", slope {v['slope_distance_m']:.1f} m" if "slope_distance_m" in v else "")
        )
    out = Path(a.out)
    fig = plot_tuning(out / f"tuning_{a.name}.png", res["history"])
    rep = {
        "preset": str(path),
        "tuned": res["tuned"],
        "gains": res["gains"],
        "history": res["history"],
        "held_out": held_out,
        "figure": str(fig),
    }
    rep["json"] = str(write_json(out, f"tuning_{a.name}.json", rep))
    summary = {
        k: {m: v[m] for m in ("rms_mean_mps", "fitness", "slope_distance_m") if m in v}
        for k, v in held_out.items()
    }
    return {
        "json": rep["json"],
        "figure": str(fig),
        "held_out": summary,
        "presets": {"tuned": str(path)},
    }


def cmd_range(a) -> dict:
    from jaxgait.spinal.auto import speed_range
    from jaxgait.spinal.figures import plot_speed_range

    targets = floats(a.targets, "--targets")
    results = {}
    for preset in a.presets:
        r = speed_range(preset, targets, a.duration, a.measure, a.tol)
        results[label(preset)] = r
        print(
            f"{label(preset)}: held {sum(r['held'])}/{len(targets)} targets; slowest "
            f"{r['slowest_held_mps']} fastest {r['fastest_held_mps']} m/s "
            f"(every target between held: {r['all_between_held']})"
        )
    out = Path(a.out)
    res = {"models": results, "figure": str(plot_speed_range(out / "speed_range.png", results))}
    res["json"] = str(write_json(out, "speed_range.json", res))
    return res


def cmd_climb(a) -> dict:
    from jaxgait import models
    from jaxgait.analysis.robustness import RobustnessConfig, walk_tests
    from jaxgait.spinal.figures import plot_climb

    rows, res = {}, {}
    for preset in a.presets:
        name, vec, doc = load_preset(preset)
        rcfg = RobustnessConfig(
            seeds=a.seeds,
            seed=a.seed,
            duration=a.duration,
            v0=doc.get("v0"),
            pose=doc.get("pose"),
        )
        r = walk_tests(models.get_model(name), vec, rcfg, tests=("slope",))
        lab = label(preset)
        res[lab] = r
        rows[lab] = {
            "distance_m": (float(r["slope_distance_m"]), float(r["slope_distance_m_sd"])),
            "grade_pct": (float(r["slope_max_grade_pct"]), float(r["slope_max_grade_pct_sd"])),
        }
        print(
            f"{lab}: {rows[lab]['distance_m'][0]:.1f} +- {rows[lab]['distance_m'][1]:.1f} m, "
            f"grade {rows[lab]['grade_pct'][0]:.1f} +- {rows[lab]['grade_pct'][1]:.1f} %"
        )
    out = Path(a.out)
    res["figure"] = str(plot_climb(out / "fig7_5_climb.png", rows))
    res["json"] = str(write_json(out, "climb.json", res))
    return res


#: thesis Fig. 7.8: the searched commands and their ranges (omega the row of each map)
FIG_7_8 = {
    "O_INBAS": (-0.01, 0.01),
    "O_INCPG": (-0.01, 0.01),
    "A_INBAS": (0.7, 1.6),
    "A_INCPG": (0.7, 1.6),
    "omega": (0.65, 1.8),
}


#: the sensory group's commands, for maps of models without feedforward IN (FBL, FBL-);
#: the same ranges as the basal group's in Fig. 7.8
MAP_RANGES = {**FIG_7_8, "O_INSEN": (-0.01, 0.01), "A_INSEN": (0.7, 1.6)}


def map_commands(have, requested: str | None = None) -> list[str]:
    """The commands a map varies two by two: ``requested`` (comma separated, each in
    :data:`MAP_RANGES` and in the model's control vector ``have``), else Fig. 7.8's four that
    the model has, else (no IN_BAS, IN_CPG: FBL) the sensory group's pair."""
    if requested:
        names = [n.strip() for n in requested.split(",") if n.strip()]
        bad = [n for n in names if n not in MAP_RANGES or n == "omega"]
        if bad:
            valid = ", ".join(n for n in MAP_RANGES if n != "omega")
            raise SpinalError(f"--commands: {', '.join(bad)} not mappable; valid: {valid}")
        missing = [n for n in names if n not in have]
        if missing:
            raise SpinalError(
                f"--commands: the model has no {', '.join(missing)}; its commands: "
                + ", ".join(sorted(have))
            )
    else:
        names = [n for n in FIG_7_8 if n != "omega" and n in have]
        if len(names) < 2:
            names = [n for n in ("O_INSEN", "A_INSEN") if n in have]
    if len(names) < 2 or len(set(names)) != len(names):
        raise SpinalError(f"a map needs at least two different commands, got {names}")
    return names


def cmd_maps(a) -> dict:
    from itertools import combinations

    from jaxgait import models
    from jaxgait.spinal.figures import plot_maps
    from jaxgait.spinal.search import MEASURES, Search, run_search

    have = {c.name for c in models.get_model(load_preset(a.preset)[0]).controller.commands}
    names = map_commands(have, a.commands)
    with_z = "omega" in have and a.omegas > 0
    lo, hi = FIG_7_8["omega"]
    zs = tuple(float(v) for v in np.linspace(lo, hi, a.omegas)) if with_z else ()
    pairs = []
    for x, y in combinations(names, 2):
        xv = tuple(float(v) for v in np.linspace(*MAP_RANGES[x], a.n))
        yv = tuple(float(v) for v in np.linspace(*MAP_RANGES[y], a.n))
        z = "omega" if with_z else None
        s = Search(x, xv, y, yv, {}, a.hold, a.measure, a.warmup, z=z, z_values=zs)
        r = run_search(a.preset, s)
        sp = r["grid"]["speed_mps"]
        ok = np.isfinite(sp)
        print(
            f"{x} x {y}: {int(ok.sum())}/{sp.size} settings walked"
            + (f", speed {np.nanmin(sp):.2f}-{np.nanmax(sp):.2f} m/s" if ok.any() else "")
        )
        pairs.append(r)
    out = Path(a.out)
    figs = {m: str(plot_maps(out / f"maps_{m}.png", pairs, m)) for m in MEASURES}
    allsp = np.concatenate([np.ravel(r["grid"]["speed_mps"]) for r in pairs])
    walked = allsp[np.isfinite(allsp)]
    res = {
        "model": pairs[0]["model"],
        "ranges": {n: MAP_RANGES[n] for n in names + (["omega"] if with_z else [])},
        "pairs": pairs,
        "walked": int(walked.size),
        "settings": int(allsp.size),
        "speed_range_mps": [float(walked.min()), float(walked.max())] if walked.size else None,
        "figures": figs,
    }
    print(
        f"{res['model']}: {res['walked']}/{res['settings']} walked; speed {res['speed_range_mps']}"
    )
    res["figure"] = figs["speed_mps"]
    res["json"] = str(write_json(out, "maps.json", res))
    return res


def cmd_walkrun(a) -> dict:
    from jaxgait.spinal.figures import plot_walkrun
    from jaxgait.spinal.walkrun import WalkRun, run_walkrun

    drive = {}
    for item in a.drive:
        name, _, rng = item.partition("=")
        try:
            vals = [float(v) for v in rng.split(":")]
        except ValueError:
            vals = []
        if not name.strip() or len(vals) != 2:
            raise SpinalError(f"--drive takes NAME=WALK:RUN, got {item!r}")
        drive[name.strip()] = (vals[0], vals[1])
    ph = floats(a.phases, "--phases")
    if len(ph) != 5:
        raise SpinalError(f"--phases takes 5 durations [s], got {a.phases!r}")
    wr = WalkRun(drive or WalkRun().drive, *ph, window_s=a.window)
    r = run_walkrun(a.preset, wr, env=a.env, seed=a.seed)
    w = r["windows"]
    for ph_name in dict.fromkeys(w["phase"]):
        rows = [j for j, p in enumerate(w["phase"]) if p == ph_name]
        sel = lambda k, rows=rows: np.asarray(w[k], float)[rows]
        if np.all(np.isnan(sel("speed_mps"))):
            continue
        print(
            f"{ph_name:<11} speed {np.nanmin(sel('speed_mps')):.2f}-"
            f"{np.nanmax(sel('speed_mps')):.2f} m/s, double stance min "
            f"{np.nanmin(sel('double_stance_fraction')):.3f}, flight max "
            f"{np.nanmax(sel('flight_fraction')):.3f}"
        )
    print(f"fell at {r['fell_at_s']:.1f} s ({r['fell_in']})" if r["fell"] else "no fall")
    out = Path(a.out)
    stem = f"walkrun_{label(a.preset)}"
    r["figure"] = str(plot_walkrun(out / f"{stem}.png", r))
    r["json"] = str(write_json(out, f"{stem}.json", r))
    return {"json": r["json"], "figure": r["figure"], "fell": r["fell"]}


def add_parsers(sub) -> None:
    """Add the control sub-commands to ``sub``, each with its handler as ``func``."""
    q = sub.add_parser("tune", help="train the command law's gains with CMA-ES")
    q.add_argument("preset", help="a preset whose model has a v_target command")
    q.add_argument("--name", required=True, help="name of the trained preset")
    q.add_argument(
        "--gains", default="v_ref,k_ff,k_p,k_i,k_w,tau_v", help="comma list of gains to train"
    )
    q.add_argument("--v-range", default="0.9,1.5", help="targets drawn in LO,HI [m/s]")
    q.add_argument("--segments", type=int, default=3, help="targets per profile (3)")
    q.add_argument("--segment", type=float, default=15.0, help="seconds per target (15)")
    q.add_argument("--settle", type=float, default=5.0, help="seconds left out per target (5)")
    q.add_argument("--profiles", type=int, default=3, help="profiles per generation (3)")
    q.add_argument("--slope", type=float, default=0.0, help="increasing-slope walk [s] (0: none)")
    q.add_argument("--slope-target", type=float, default=1.2, help="its target speed [m/s]")
    q.add_argument(
        "--grade", type=float, default=0.0, help="track on this constant grade, rise/run (0: flat)"
    )
    q.add_argument("--grade-ramp", type=float, default=10.0, help="level to --grade over [m] (10)")
    q.add_argument("--popsize", type=int, default=8)
    q.add_argument("--generations", type=int, default=10)
    q.add_argument("--sigma", type=float, default=0.1, help="CMA-ES step, fraction of ranges")
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--held-out", type=int, default=6, help="held-out profiles scored (6)")
    q.add_argument("--out-dir", default="runs/spinal/models")
    q.add_argument("--out", default="runs/spinal/tuning")
    q.set_defaults(func=cmd_tune)
    q = sub.add_parser("range", help="slowest and fastest constant target speed held")
    q.add_argument("presets", nargs="+")
    q.add_argument("--targets", default="0.5:1.8:14", help="LO:HI:N or v1,v2,... [m/s]")
    q.add_argument("--duration", type=float, default=30.0, help="walk per target [s] (30)")
    q.add_argument("--measure", type=float, default=10.0, help="speed over the last [s] (10)")
    q.add_argument("--tol", type=float, default=0.1, help="held within this [m/s] (0.1)")
    q.add_argument("--out", default="runs/spinal/range")
    q.set_defaults(func=cmd_range)
    q = sub.add_parser("climb", help="Fig. 7.5: distance and grade on the increasing slope")
    q.add_argument("presets", nargs="+")
    q.add_argument("--seeds", type=int, default=3)
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--duration", type=float, default=150.0, help="max. walk [s] (150)")
    q.add_argument("--out", default="runs/spinal/climb")
    q.set_defaults(func=cmd_climb)
    q = sub.add_parser("maps", help="Fig. 7.9-7.10: the commands of Fig. 7.8 two by two")
    q.add_argument("preset")
    q.add_argument("--n", type=int, default=7, help="values per command (7)")
    q.add_argument(
        "--commands",
        default=None,
        help="commands mapped two by two, comma separated (default: Fig. 7.8's that the "
        "model has, else O_INSEN,A_INSEN)",
    )
    q.add_argument(
        "--omegas", type=int, default=6, help="omega values, one map row each (6; 0: none)"
    )
    q.add_argument("--hold", type=float, default=10.0, help="seconds per setting (10)")
    q.add_argument("--measure", type=float, default=4.0, help="measured last seconds (4)")
    q.add_argument("--warmup", type=float, default=10.0, help="seconds at the defaults first")
    q.add_argument("--out", default="runs/spinal/maps")
    q.set_defaults(func=cmd_maps)
    q = sub.add_parser("walkrun", help="thesis 7.3.2: commands driven to running and back")
    q.add_argument("preset")
    q.add_argument(
        "--drive",
        action="append",
        default=[],
        help="NAME=WALK:RUN, repeatable (default A_INBAS=1:1.6 and A_INCPG=1:1.6)",
    )
    q.add_argument(
        "--phases", default="10,20,10,20,10", help="walk, ramp up, hold, ramp down, walk [s]"
    )
    q.add_argument("--window", type=float, default=2.0, help="measuring window [s] (2)")
    q.add_argument("--env", default="flat")
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--out", default="runs/spinal/walkrun")
    q.set_defaults(func=cmd_walkrun)
