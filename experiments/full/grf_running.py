"""Vertical GRF per stance of a running candidate against Fukuchi et al. 2017 (3.5 m/s).

    ./jg python experiments/full/grf_running.py experiments/full/exp5 [--duration 20]

Writes ``grf_vs_fukuchi.png`` into the folder and prints the double-stance and flight
fractions of the gait cycle (a run has flight phases and no double stance).
"""

import argparse
import json
from pathlib import Path

import numpy as np

from jaxgait import evaluate
from jaxgait.analysis import plots, refdata


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("folder", type=Path)
    ap.add_argument("--duration", type=float, default=20.0)
    a = ap.parse_args(argv)
    r = evaluate.run(a.folder, duration=a.duration)
    st = np.asarray(r.trace.stance)[np.asarray(r.trace.alive)]
    half = st.shape[0] // 2  # the settled second half
    flight = float(np.mean(~st[half:, 0] & ~st[half:, 1]))
    double = float(np.mean(st[half:, 0] & st[half:, 1]))
    out = plots.plot_grf(
        a.folder / "grf_vs_fukuchi.png",
        r.trace,
        r.events,
        float(r.summary.mass),
        reference=refdata.running_grf(),
    )
    rep = {
        "speed_mps": r.report["mean_speed_mps"],
        "flight_fraction": flight,
        "double_stance_fraction": double,
        "figure": str(out),
    }
    print(json.dumps(rep))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
