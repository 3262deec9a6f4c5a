"""What the runners' stance peaks of 10-14 body weights are: the vertical GRF of each stance, at
the physics step and low-pass filtered as force-plate data are.

Each preset is rolled out on flat ground (``evaluation.run``, its own v0, dynamics and pose)
with the trace logged at every physics step (``--log-dt``, 0.5 ms); the right leg's stances
after ``--skip`` seconds are those of its filtered ground contact (the controller's stance).
Per stance: the largest force at the physics step and when it comes after touchdown, the width
of that peak (time above half of it), and the largest force after a zero-phase 4th-order
Butterworth low-pass at ``--cutoff`` Hz (scipy.signal; 50 Hz by default, a common cut-off for
running force plates), all in body weights (BW); and from the heights of the foot's heel and
ball, which of them lands first and when and how fast the other one reaches the ground.
``--out`` writes the rows as JSON (experiments/running/README.md, "The stance peaks are a foot
slap").  Usage::

    ./jg python experiments/running/landing/grf_slap.py wang_run_3p7 fblplus_run_2p0 \
        --duration 6 --out experiments/running/landing/grf_slap.json
"""

from __future__ import annotations

import argparse
import json

import jax
import numpy as np
from scipy import signal

from jaxgait import evaluation
from jaxgait.analysis.measures import G
from jaxgait.sim.model import CONTACT_SITES

#: columns of Model.points (and CONTACT_SITES) with the right foot's heel and ball
RIGHT_FOOT = [CONTACT_SITES.index("heel_r"), CONTACT_SITES.index("ball_r")]


def stances(stance: np.ndarray, dt: float, skip_s: float) -> list[tuple[int, int]]:
    """(start, end) step indices of the stances of one leg, from its filtered ground contact
    ``stance`` (T,) bool (the controller's, so a bounce of the foot within a stance does not
    split it), begun after ``skip_s`` and ended within the trace."""
    edges = np.flatnonzero(np.diff(stance.astype(np.int8)))
    out = []
    for i in edges:
        s = i + 1
        if stance[s] and s * dt >= skip_s:
            rest = np.flatnonzero(~stance[s:])
            if rest.size:
                out.append((s, s + int(rest[0])))
    return out


def stance_rows(
    fz: np.ndarray,
    stance: np.ndarray,
    heel_ball_z: np.ndarray,
    dt: float,
    skip_s: float,
    cutoff_hz: float,
) -> list[dict]:
    """Per stance of one leg (``stance`` (T,) bool) of ``fz`` (T,) [BW] at step ``dt`` [s]:
    raw and filtered peaks, the raw peak's delay after touchdown and its width (time above
    half of it) [ms], stance time [ms]; from the heights of the foot's heel and ball
    ``heel_ball_z`` (T, 2) [m]: which of them touched down first, when the other one reached
    the ground [ms after touchdown] and how fast it was falling then [m/s]."""
    b, a = signal.butter(4, cutoff_hz / (0.5 / dt))
    filt = signal.filtfilt(b, a, fz)
    rows = []
    for s, e in stances(stance, dt, skip_s):
        seg = fz[s:e]
        k = int(seg.argmax())
        half = seg >= 0.5 * seg[k]
        lo, hi = k, k
        while lo > 0 and half[lo - 1]:
            lo -= 1
        while hi < seg.size - 1 and half[hi + 1]:
            hi += 1
        z = heel_ball_z[s:e]
        first = int(z[0].argmin())  # 0 heel, 1 ball
        down = np.flatnonzero(z[:, 1 - first] <= 0.0)
        j = int(down[0]) if down.size else seg.size - 1
        fall = (z[j - 1, 1 - first] - z[j, 1 - first]) / dt if j > 0 else 0.0
        rows.append(
            {
                "touchdown_s": round(s * dt, 4),
                "first_point": ("heel", "ball")[first],
                "second_point_down_ms": round(j * dt * 1e3, 1),
                "second_point_speed_mps": round(float(fall), 2),
                "stance_ms": round((e - s) * dt * 1e3, 1),
                "peak_bw": round(float(seg[k]), 3),
                "peak_after_touchdown_ms": round(k * dt * 1e3, 1),
                "peak_width_ms": round((hi - lo + 1) * dt * 1e3, 1),
                "filtered_peak_bw": round(float(filt[s:e].max()), 3),
            }
        )
    return rows


def slap(r: evaluation.EvalRun, skip_s: float, cutoff_hz: float) -> dict:
    """``{"fell", "mean", "stances"}`` of one rollout ``r`` (logged at the physics step): the
    right leg's rows of :func:`stance_rows` after ``skip_s`` and their means (empty if none)."""
    dt = float(r.cfg.log_dt)
    fz = np.asarray(r.trace.grf)[:, 0, 1] / (r.report["mass_kg"] * G)
    pts = jax.vmap(r.model.points, in_axes=(0, None))(r.trace.qpos, 0.0)  # (T, 9, 2)
    heel_ball_z = np.asarray(pts)[:, RIGHT_FOOT, 1]
    rows = stance_rows(fz, np.asarray(r.trace.stance)[:, 0], heel_ball_z, dt, skip_s, cutoff_hz)
    mean = {
        k: round(float(np.mean([w[k] for w in rows])), 3)
        for k in (rows[0] if rows else ())
        if k not in ("first_point", "touchdown_s")
    }
    return {"fell": bool(r.report["fell"]), "mean": mean, "stances": rows}


def describe(res: dict, cutoff_hz: float) -> str:
    """One line of :func:`slap`'s result."""
    rows, mean = res["stances"], res["mean"]
    if not rows:
        return "no complete right stance"
    firsts = sorted({w["first_point"] for w in rows})
    return (
        f"{len(rows)} stances, landing on the {'/'.join(firsts)}; the other point "
        f"down {mean['second_point_down_ms']:.1f} ms later at "
        f"{mean['second_point_speed_mps']:.2f} m/s; peak {mean['peak_bw']:.2f} BW at "
        f"{mean['peak_after_touchdown_ms']:.1f} ms after touchdown, "
        f"{mean['peak_width_ms']:.1f} ms wide; low-passed at {cutoff_hz:g} Hz: "
        f"{mean['filtered_peak_bw']:.2f} BW; stance {mean['stance_ms']:.0f} ms"
    )


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("presets", nargs="+")
    p.add_argument("--duration", type=float, default=6.0)
    p.add_argument("--skip", type=float, default=2.0, help="seconds of start left out")
    p.add_argument("--cutoff", type=float, default=50.0, help="low-pass cut-off [Hz]")
    p.add_argument(
        "--log-dt", type=float, default=0.0005, help="trace interval [s]: the physics step"
    )
    p.add_argument("--out")
    a = p.parse_args(argv)
    if a.skip >= a.duration:
        p.error(f"--skip ({a.skip} s) must be shorter than --duration ({a.duration} s)")
    out = {}
    for name in a.presets:
        r = evaluation.run(name, duration=a.duration, log_dt=a.log_dt, reference="running")
        out[name] = slap(r, a.skip, a.cutoff)
        if not out[name]["stances"]:
            raise SystemExit(f"{name}: no complete right stance after {a.skip} s")
        print(f"{name}: {describe(out[name], a.cutoff)}")
    if a.out:
        with open(a.out, "w") as f:
            json.dump({"cutoff_hz": a.cutoff, "skip_s": a.skip, "presets": out}, f, indent=1)


if __name__ == "__main__":
    main()
