"""``python -m jaxgait.spinal``: the spinal-network experiments of thesis ch. 7.

Subcommands (each prints a table or JSON line, and writes its JSON and figures to ``--out``)::

    variability PRESET [PRESET ...] [--duration 30] [--out DIR]     # Fig. 7.1
    patterns PRESET_A PRESET_B [--out DIR]                           # Fig. 7.3
    build PRESET [--kinds fblminus,3fbl,3fbl_prime,fbl_net] [--prefix NAME_]
          [--rule walk|s] [--n-replace 5] [--s-max S] [--check-s 20] [--bas-ungated]
          [--tau-in S] [--tau-mn S] [--ff-after N] [--out-dir DIR]  # the model presets
    compare PRESET [PRESET ...] [--duration 60] [--out DIR]          # Fig. 7.2
    robust PRESET [PRESET ...] [--seeds 5] [--out DIR]               # Fig. 7.4
    search PRESET --x NAME:LO:HI:N --y NAME:LO:HI:N [--fixed NAME=V] [--hold 10]
          [--measure 4] [--out DIR]                                  # Fig. 7.6-7.10
    auto PRESET --name NAME [--gain NAME=V ...] [--out-dir DIR]      # automatic speed law
    track PRESET [--profile 1.0,1.5,0.7,1.3] [--segment 20] [--out DIR]
    tune PRESET --name NAME [--gains ...] [--v-range 0.9,1.5] [--slope S]   # CMA-ES law
    range PRESET [PRESET ...] [--targets 0.5:1.8:14] [--duration 30]        # speeds held
    climb PRESET [PRESET ...] [--seeds 3] [--duration 150]                 # Fig. 7.5
    maps PRESET [--n 7] [--omegas 6] [--out DIR]                           # Fig. 7.9-7.10
    walkrun PRESET [--drive NAME=WALK:RUN ...] [--phases 10,20,10,20,10]    # thesis 7.3.2

A built model preset is named ``<prefix><kind>_walk`` (``fblminus_walk``, ``3fbl_walk``,
``3fbl_prime_walk``, ``fblnet_walk`` with an empty prefix) and holds the FBL (or, built from
an FBL+ gait, FBL+) parameters of
the source gait plus the network.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from jaxgait.control.spinal import NETWORK_KINDS
from jaxgait.core.jsonio import json_safe
from jaxgait.presets import PresetError, load_preset, resolve_preset
from jaxgait.spinal.build import (
    N_REPLACE,
    OMEGA,
    build_network,
    model_preset,
    select,
    select_walking,
)
from jaxgait.spinal.cli_control import add_parsers, floats, label, write_json
from jaxgait.spinal.record import SpinalError, analyse, record

FILE_NAMES = {
    "fblminus": "fblminus",
    "3fbl": "3fbl",
    "3fbl_prime": "3fbl_prime",
    "fbl_net": "fblnet",
}


def _analysis(preset, duration, skip):
    rec = record(preset, duration=duration)
    if rec.fell:
        raise SpinalError(f"{preset}: fell after {rec.duration:.1f} s of {duration} s")
    return rec, analyse(rec, skip=skip)


def cmd_variability(a) -> dict:
    from jaxgait.spinal.figures import plot_variability

    res, ans = {}, {}
    for preset in a.presets:
        _, an = _analysis(preset, a.duration, a.skip)
        lab = label(preset)
        ans[lab] = an
        res[lab] = {"stride_s": an.stride_s, "n_cycles": an.n_cycles, "table": an.table()}
        print(f"\n{lab}: {an.n_cycles[0]} cycles per leg, stride {an.stride_s:.3f} s")
        print(f"{'IN_SEN':<20} {'s':>8} {'v_mu':>8} {'v_sigma':>8} {'mean':>8}")
        for r in sorted(res[lab]["table"], key=lambda r: r["s"]):
            vals = " ".join(f"{r[k]:8.4f}" for k in ("s", "v_mu", "v_sigma", "mean"))
            print(f"{r['name']:<20} {vals}")
    out = Path(a.out)
    res["figure"] = str(plot_variability(out / "fig7_1_variability.png", ans))
    res["json"] = str(write_json(out, "variability.json", res))
    return res


def cmd_patterns(a) -> dict:
    from jaxgait.analysis.variability import pattern_correlation
    from jaxgait.spinal.figures import plot_patterns

    (_, an_a), (_, an_b) = (_analysis(p, a.duration, a.skip) for p in (a.a, a.b))
    labels = (label(a.a), label(a.b))
    corr = {
        n: pattern_correlation(an_a.per_leg[n][0].pattern, an_b.per_leg[n][0].pattern)
        for n in an_a.per_leg
    }
    for n, r in corr.items():
        print(f"{n:<20} r = {r:+.2f}")
    out = Path(a.out)
    fig = plot_patterns(out / "fig7_3_patterns.png", an_a, an_b, labels)
    res = {"gaits": labels, "correlation": corr, "figure": str(fig)}
    res["json"] = str(write_json(out, "patterns.json", res))
    return res


def _name_values(items, flag: str) -> dict[str, float]:
    """NAME=VALUE arguments of a repeatable flag as a dict."""
    out = {}
    for item in items:
        k, _, v = item.partition("=")
        try:
            out[k] = float(v)
        except ValueError:
            raise SpinalError(f"{flag} takes NAME=VALUE, got {item!r}") from None
    return out


def _omega(text: str) -> float | None:
    if text == "stride":
        return None
    try:
        v = float(text)
    except ValueError:
        raise SpinalError(
            f"--omega must be a frequency [cycles/s] or 'stride', got {text!r}"
        ) from None
    if not v > 0:
        raise SpinalError(f"--omega must be positive, got {v}")
    return v


def cmd_build(a) -> dict:
    kinds = [k.strip() for k in a.kinds.split(",") if k.strip()]
    bad = sorted(set(kinds) - set(NETWORK_KINDS))
    if bad or not kinds:
        raise SpinalError(f"--kinds: unknown {bad}; valid: {', '.join(NETWORK_KINDS)}")
    from jaxgait import models

    rec, an = _analysis(a.preset, a.duration, a.skip)
    base = models.get_model(rec.model).controller.settings.network.base
    source = str(a.preset)
    settings = {
        "rule": a.rule,
        "n_replace": a.n_replace,
        "candidates": a.candidates,
        "omega": a.omega,
    }
    if a.rule == "walk":
        print(f"greedy selection with a {a.check_s:g} s walking check (least variable first):")
        replaced, tried = select_walking(
            an,
            rec.vec,
            source,
            a.n_replace,
            a.candidates,
            check_s=a.check_s,
            omega=_omega(a.omega),
            base=base,
            start=rec.start,
        )
        settings.update(check_s=a.check_s, tried=tried)
    else:
        replaced = select(an, a.n_replace, a.s_max, a.candidates)
        settings.update(s_max=a.s_max)
    print("replaced:", ", ".join(replaced) or "(none)")
    written = {}
    for kind in kinds:
        name = f"{a.prefix}{FILE_NAMES[kind]}_walk"
        desc = (
            f"{kind} (thesis 6.2.1) built from {label(source)} by `python -m jaxgait.spinal "
            f"build`: {len(replaced)} IN_SEN replaced ({', '.join(replaced) or 'none'})"
        )
        net = build_network(
            kind,
            an,
            replaced,
            name,
            bas_gated=not a.bas_ungated,
            tau_in=a.tau_in,
            tau_mn=a.tau_mn,
            omega=_omega(a.omega),
            ff_after=a.ff_after,
            description=desc,
            base=base,
        )
        doc = model_preset(net, kind, rec.vec, source, replaced, an, settings, rec.start)
        path = write_json(Path(a.out_dir), f"{name}.json", doc)
        written[kind] = str(path)
        print(f"wrote {path}")
    return {"replaced": replaced, "presets": written, "settings": settings}


def cmd_compare(a) -> dict:
    from jaxgait import evaluate
    from jaxgait.spinal.figures import plot_models

    runs, res = {}, {}
    for preset in a.presets:
        r = evaluate.run(preset, duration=a.duration)
        runs[label(preset)] = r
        keys = (
            "duration_s",
            "distance_m",
            "fell",
            "mean_speed_mps",
            "c_angles",
            "corr_hip",
            "corr_knee",
            "corr_ankle",
            "energy_J_per_m",
        )
        res[label(preset)] = {k: r.report.get(k) for k in keys}
        print(label(preset), json.dumps(json_safe(res[label(preset)])))
    out = Path(a.out)
    res["figure"] = str(plot_models(out / "fig7_2_models.png", runs))
    res["json"] = str(write_json(out, "compare.json", res))
    return res


def cmd_robust(a) -> dict:
    from jaxgait import evaluate, models
    from jaxgait.analysis.robustness import RobustnessConfig, robustness
    from jaxgait.spinal.figures import plot_robustness

    rows, res = {}, {}
    for preset in a.presets:
        name, vec, doc = load_preset(preset)
        lab = label(preset)
        rcfg = RobustnessConfig(seeds=a.seeds, seed=a.seed, v0=doc.get("v0"), pose=doc.get("pose"))
        rob = robustness(models.get_model(name), vec, rcfg)
        ev = evaluate.run(preset, duration=a.duration)
        res[lab] = {"robustness": rob, "c_angles": ev.report.get("c_angles")}
        rows[lab] = {
            "c_angles": (float(ev.report.get("c_angles") or 0.0), 0.0),
            "max_push_N": (
                float(rob.get("max_push_N", np.nan)),
                float(rob.get("max_push_N_sd", 0)),
            ),
            "max_slope_pct": (
                float(rob.get("max_slope_pct", np.nan)),
                float(rob.get("max_slope_pct_sd", 0)),
            ),
        }
        print(lab, json.dumps(json_safe(rows[lab])))
    out = Path(a.out)
    res["figure"] = str(plot_robustness(out / "fig7_4_robustness.png", rows))
    res["json"] = str(write_json(out, "robustness.json", res))
    return res


def _grid_arg(text: str) -> tuple[str, tuple[float, ...]]:
    """NAME:LO:HI:N (N evenly spaced values) or NAME=v1,v2,..."""
    name, sep, rest = text.partition("=" if "=" in text else ":")
    if sep and (sep == ":" or ":" not in rest):  # the comma form after "=" only
        try:
            return name, tuple(floats(rest, "a grid axis"))
        except SpinalError:
            pass
    raise SpinalError(f"a grid axis is NAME:LO:HI:N or NAME=v1,v2,..., got {text!r}")


def cmd_search(a) -> dict:
    from jaxgait.spinal.figures import plot_search
    from jaxgait.spinal.search import Search, fit_speed_law, run_search

    (xn, xv), (yn, yv) = _grid_arg(a.x), _grid_arg(a.y)
    fixed = _name_values(a.fixed, "--fixed")
    s = Search(xn, xv, yn, yv, fixed, a.hold, a.measure, a.warmup)
    res = run_search(a.preset, s)
    sp = res["grid"]["speed_mps"]
    walked = int(np.isfinite(sp).sum())
    lo, hi = (np.nanmin(sp), np.nanmax(sp)) if walked else (np.nan, np.nan)
    print(f"{res['model']}: {walked}/{sp.size} settings walked; speed {lo:.2f}-{hi:.2f} m/s")
    if walked >= 3:
        res["speed_law"] = fit_speed_law(xv, yv, sp)
        law = res["speed_law"]
        print(
            f"speed law S = {law['a1']:.3f} {xn} + {law['a2']:.3f} {yn} + {law['a3']:.3f} "
            f"(RMS {law['rms']:.3f} m/s over {law['n']} settings)"
        )
    out = Path(a.out)
    res["figure"] = str(plot_search(out / f"search_{xn}_{yn}.png", res))
    res["json"] = str(write_json(out, f"search_{xn}_{yn}.json", res))
    return res


def cmd_auto(a) -> dict:
    from jaxgait.spinal.auto import auto_preset

    doc = auto_preset(
        a.preset,
        a.name,
        _name_values(a.gain, "--gain"),
        network_in_table=a.network_in_table,
        target_rate=a.target_rate,
    )
    path = write_json(Path(a.out_dir), f"{a.name}.json", doc)
    print(f"wrote {path}")
    return {"presets": {"auto": str(path)}}


def cmd_anchors(a) -> dict:
    from jaxgait.spinal.auto import anchored_preset

    speeds = floats(a.speeds, "--speeds") if a.speeds else None
    grades = floats(a.grades, "--grades") if a.grades else None
    gains = _name_values(a.gain, "--gain")
    doc = anchored_preset(a.presets, a.name, speeds, a.grade_presets, grades, gains)
    path = write_json(Path(a.out_dir), f"{a.name}.json", doc)
    print(f"wrote {path}: anchors at {[x['v'] for x in doc['autopilot']['anchors']]} m/s")
    return {"presets": {"anchors": str(path)}}


def cmd_track(a) -> dict:
    from jaxgait.spinal.auto import track
    from jaxgait.spinal.figures import plot_tracking

    try:
        profile = [float(v) for v in a.profile.split(",")]
    except ValueError:
        raise SpinalError(f"--profile takes speeds v1,v2,... [m/s], got {a.profile!r}") from None
    r = track(a.preset, profile, a.segment, a.settle)
    for v, e in zip(profile, r["rms"], strict=True):
        print(f"target {v:.2f} m/s: RMS error after {a.settle:g} s = {e:.3f} m/s")
    out = Path(a.out)
    fig = plot_tracking(out / "tracking.png", r)
    keep = {
        k: r[k] for k in ("model", "profile", "segment_s", "settle_s", "rms", "fell", "duration_s")
    }
    res = {**keep, "figure": str(fig)}
    res["json"] = str(write_json(out, "tracking.json", res))
    return res


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m jaxgait.spinal", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)

    def common(q, out="runs/spinal"):
        q.add_argument("--duration", type=float, default=30.0, help="walk [s] (default 30)")
        q.add_argument("--skip", type=int, default=2, help="start cycles left out (default 2)")
        q.add_argument("--out", default=out, help=f"output folder (default {out})")

    q = sub.add_parser("variability", help="Fig. 7.1: variability of every IN_SEN")
    q.add_argument("presets", nargs="+")
    common(q)
    q = sub.add_parser("patterns", help="Fig. 7.3: nominal patterns of two gaits")
    q.add_argument("a")
    q.add_argument("b")
    common(q)
    q = sub.add_parser("build", help="build FBL-, 3FBL, 3FBL' (and FBL net) presets from a gait")
    q.add_argument("preset")
    common(q)
    q.add_argument("--kinds", default=",".join(NETWORK_KINDS))
    q.add_argument("--prefix", default="", help="name prefix of the written presets")
    q.add_argument(
        "--rule",
        choices=("walk", "s"),
        default="walk",
        help="walk: least variable first, kept if the models still walk (default); "
        "s: the n least variable by s (thesis)",
    )
    q.add_argument("--n-replace", type=int, default=N_REPLACE)
    q.add_argument("--s-max", type=float, default=None, help="(rule s) only IN with s below")
    q.add_argument("--candidates", choices=("muscle", "replaceable"), default="muscle")
    q.add_argument("--check-s", type=float, default=20.0, help="(rule walk) check walk [s]")
    q.add_argument("--bas-ungated", action="store_true", help="IN_BAS always on (cycle mean)")
    q.add_argument("--tau-in", type=float, default=0.0, help="SEN -> IN link [s] (default 0)")
    q.add_argument("--tau-mn", type=float, default=0.0, help="IN -> MN link [s] (default 0)")
    q.add_argument("--ff-after", type=int, default=3, help="feedforward from this right touchdown")
    q.add_argument(
        "--omega",
        default=str(OMEGA),
        help=f"CPG clock frequency [cycles/s] (default {OMEGA}, eq. 6.3) or 'stride' (the gait's)",
    )
    q.add_argument("--out-dir", default="runs/spinal/models")
    q = sub.add_parser("compare", help="Fig. 7.2: models on flat ground vs Winter")
    q.add_argument("presets", nargs="+")
    common(q)
    q.set_defaults(duration=60.0)
    q = sub.add_parser("robust", help="Fig. 7.4: C_angles, max push, max slope per model")
    q.add_argument("presets", nargs="+")
    common(q)
    q.add_argument("--seeds", type=int, default=5)
    q.add_argument("--seed", type=int, default=0)
    q = sub.add_parser("search", help="Fig. 7.6-7.10: a grid of two commands during walking")
    q.add_argument("preset")
    q.add_argument(
        "--x", required=True, help="NAME:LO:HI:N or NAME=v1,v2,... (changed in a column)"
    )
    q.add_argument("--y", required=True, help="NAME:LO:HI:N or NAME=v1,v2,... (one rollout each)")
    q.add_argument("--fixed", action="append", default=[], metavar="NAME=VALUE")
    q.add_argument("--hold", type=float, default=10.0, help="seconds per setting (default 10)")
    q.add_argument("--measure", type=float, default=4.0, help="measured last seconds (default 4)")
    q.add_argument("--warmup", type=float, default=10.0, help="seconds at the defaults first")
    q.add_argument("--out", default="runs/spinal")
    q = sub.add_parser("auto", help="write a network preset with the automatic speed law")
    q.add_argument("preset")
    q.add_argument("--name", required=True)
    q.add_argument("--gain", action="append", default=[], metavar="NAME=VALUE")
    q.add_argument(
        "--network-in-table",
        action="store_true",
        help="put the network's FBL parameters in the table (net_NAME) to train them with the law",
    )
    q.add_argument(
        "--target-rate",
        type=float,
        default=None,
        help="limit how fast the law's target follows v_target [m/s^2] (default: no limit)",
    )
    q.add_argument("--out-dir", default="runs/spinal/models")
    q = sub.add_parser(
        "anchors", help="one speed-controlled model from presets trained at constant targets"
    )
    q.add_argument("presets", nargs="+", help="network-in-table law presets (spinal tune)")
    q.add_argument("--name", required=True)
    q.add_argument("--speeds", default=None, help="v1,v2,... (default: each one's tuning target)")
    q.add_argument(
        "--grade-presets", nargs="+", default=[], help="presets trained on constant grades"
    )
    q.add_argument("--grades", default=None, help="g1,g2,... (default: each one's tuning grade)")
    q.add_argument(
        "--gain", action="append", default=[], metavar="NAME=VALUE", help="a law gain to set"
    )
    q.add_argument("--out-dir", default="runs/spinal/models")
    q = sub.add_parser("track", help="speed tracking of a target profile")
    q.add_argument("preset")
    q.add_argument("--profile", default="1.0,1.5,0.7,1.3", help="target speeds [m/s]")
    q.add_argument("--segment", type=float, default=20.0, help="seconds per target (20)")
    q.add_argument("--settle", type=float, default=5.0, help="seconds left out of the RMS (5)")
    q.add_argument("--out", default="runs/spinal/tracking")
    add_parsers(sub)  # tune, range, climb: each sets its own handler (``func``)
    return p


COMMANDS = {
    "variability": cmd_variability,
    "patterns": cmd_patterns,
    "build": cmd_build,
    "compare": cmd_compare,
    "anchors": cmd_anchors,
    "robust": cmd_robust,
    "search": cmd_search,
    "auto": cmd_auto,
    "track": cmd_track,
}


def main(argv=None) -> int:
    """CLI entry point: 0 on success, 2 on bad input."""
    try:
        a = _parser().parse_args(argv)
    except SystemExit as e:
        return int(e.code) if isinstance(e.code, int) else 2
    try:
        for p in getattr(a, "presets", []) + [
            getattr(a, x) for x in ("a", "b", "preset") if hasattr(a, x)
        ]:
            resolve_preset(p)
        res = (getattr(a, "func", None) or COMMANDS[a.cmd])(a)
    except (SpinalError, PresetError, ValueError) as e:
        print(f"jaxgait.spinal {a.cmd}: error: {e}", file=sys.stderr)
        return 2
    print(
        json.dumps(
            json_safe(
                {
                    "command": a.cmd,
                    **{
                        k: v
                        for k, v in res.items()
                        if k in ("json", "figure", "presets", "replaced", "speed_law", "held_out")
                    },
                }
            )
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
