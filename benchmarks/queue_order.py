"""Which order of the queue keeps the lanes busiest: a model of the scheduled evaluation
(:mod:`jaxgait.sim.lanes`) replayed on recorded generations.

It runs an experiment for a few iterations through :func:`jaxgait.train.train`, records per
generation each rollout's stage cap and duration, and replays every generation in a model of
the queue (one queue per device, the ordered rollouts dealt round-robin, ``lanes`` lanes in
chunks of ``chunk_s``, the tail drained to the evaluator's widths) under several orders:

* ``given``: the population's order;
* ``cap``: the evaluator's (highest stage cap first);
* ``cap+previous``: highest cap first, then the longest duration of the same particle in the
  previous generation (a PSO particle moves little from one iteration to the next);
* ``oracle``: the true durations, longest first (the bound no prediction beats).

The model's cost of a chunk at width w is ``a + b w`` seconds (``--chunk-cost A B``; the
default is the bare step on 2 devices: 0.059 s at w = 1, 0.132 at w = 12, benchmarks/README.md).
It prints each order's lane utilisation and modelled wall time, summed over the generations::

    ./jg python benchmarks/queue_order.py exp3 --iterations 12
    ./jg python benchmarks/queue_order.py --replay generations.npz     # no new run
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np


def simulate(durations, order, *, devices, lanes, drain, chunk_s, cost):
    """(busy lane-chunks, all lane-chunks, modelled seconds) of one generation."""
    chunks = np.maximum(np.ceil(np.asarray(durations) / chunk_s - 1e-6), 1).astype(int)
    busy_all = total_all = 0
    wall = 0.0
    for g in range(devices):
        queue = list(chunks[np.asarray(order)[g::devices]])
        width = lanes
        left = [0] * width  # chunks left per lane (0: idle)
        secs = 0.0
        widths = list(drain)
        while True:
            for i in range(width):  # refill at the chunk end
                if left[i] == 0 and queue:
                    left[i] = queue.pop(0)
            active = sum(1 for x in left if x > 0)
            if active == 0:
                break
            if not queue and widths and active <= widths[0]:
                width = widths.pop(0)
                left = sorted(left, reverse=True)[:width]
                continue
            busy_all += active
            total_all += width
            secs += cost[0] + cost[1] * width
            left = [max(x - 1, 0) for x in left]
        wall = max(wall, secs)
    return busy_all, total_all, wall


def orders(cap, dur, prev):
    n = len(cap)
    out = {"given": np.arange(n), "cap": np.argsort(-cap, kind="stable")}
    if prev is not None:
        out["cap+previous"] = np.lexsort((-prev, -cap))
    out["oracle"] = np.argsort(-dur, kind="stable")
    return out


def record(name: str, iterations: int, out: Path) -> Path:
    """Run ``name`` for ``iterations`` and save each generation's stage caps, durations [s]
    and the lane utilisation the scheduler itself counted (``out``, .npz)."""
    from jaxgait.train import evaluator as ev
    from jaxgait.train import train
    from jaxgait.train.experiments import resolve_experiment

    caps, durs, utils = [], [], []
    original = ev.PopulationEvaluator.lane_scores

    def recording(self, params, env_keys, max_stage):
        res = original(self, params, env_keys, max_stage)
        caps.append(np.asarray(max_stage).copy())
        durs.append(self.last_walk[1].copy())
        utils.append(float(self.last_stats.utilisation))
        return res

    ev.PopulationEvaluator.lane_scores = recording
    try:
        with tempfile.TemporaryDirectory() as tmp:
            exp = resolve_experiment(name, iterations=iterations)
            train(exp, Path(tmp) / "run", plots=False, video=False)
    finally:
        ev.PopulationEvaluator.lane_scores = original
    # the generations (not the end-of-run re-evaluations, of another size)
    n = max(c.size for c in caps)
    keep = [i for i, c in enumerate(caps) if c.size == n]
    np.savez(
        out,
        caps=np.stack([caps[i] for i in keep]),
        durs=np.stack([durs[i] for i in keep]),
        utils=np.array([utils[i] for i in keep]),
        drain=np.array(ev.drain_widths(ev.CPU_AUTO_LANES), dtype=int),
    )
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("experiment", nargs="?", default="exp3")
    ap.add_argument("--iterations", type=int, default=12)
    ap.add_argument("--replay", type=Path, help="an .npz written by an earlier run")
    ap.add_argument("--save", type=Path, default=Path("generations.npz"))
    ap.add_argument("--devices", type=int, default=2)
    ap.add_argument("--lanes", type=int, nargs="+", default=[12], help="lanes per device")
    ap.add_argument("--chunk-s", type=float, default=0.25)
    ap.add_argument("--chunk-cost", type=float, nargs=2, default=(0.0524, 0.00664))
    ap.add_argument(
        "--drain",
        nargs="+",
        help="drain widths to compare, each comma-separated (e.g. 3,1 6,3,1; 'none' for no "
        "drain); default the evaluator's own for each lane count",
    )
    a = ap.parse_args(argv)
    from jaxgait.core import host_devices

    host_devices.use_cpu_cores()  # as the training command, before anything makes an array
    path = a.replay or record(a.experiment, a.iterations, a.save)
    data = np.load(path)
    caps, durs = data["caps"], data["durs"]
    from jaxgait.train.evaluator import CPU_AUTO_LANES, drain_widths

    # the model against the scheduler's own count, generation by generation (files written
    # before the drain was recorded ran the evaluator's earlier (3, 1))
    recorded_drain = tuple(data["drain"].tolist()) if "drain" in data.files else (3, 1)
    if "utils" in data.files:
        model = [
            simulate(
                durs[i],
                np.argsort(-caps[i], kind="stable"),
                devices=a.devices,
                lanes=CPU_AUTO_LANES,
                drain=recorded_drain,
                chunk_s=a.chunk_s,
                cost=a.chunk_cost,
            )
            for i in range(len(caps))
        ]
        diff = np.abs(np.array([b / t for b, t, _ in model]) - data["utils"])
        print(
            f"model vs scheduler, utilisation per generation ({CPU_AUTO_LANES} lanes, cap "
            f"order): largest difference {diff.max():.4f} over {len(caps)} generations"
        )
    print(
        f"{len(caps) - 1} generations of {caps.shape[1]} rollouts, {a.devices} devices, "
        f"chunks of {a.chunk_s} s, chunk cost {a.chunk_cost[0]:g} + {a.chunk_cost[1]:g} w s "
        f"({path})"
    )
    base = None
    drains = [
        None if d is None else () if d == "none" else tuple(int(w) for w in d.split(","))
        for d in (a.drain or [None])
    ]
    cases = [(lanes, drain_widths(lanes) if d is None else d) for lanes in a.lanes for d in drains]
    for lanes, drain in cases:
        totals: dict[str, list[float]] = {}
        for i in range(1, len(caps)):  # from the second: each needs its previous generation
            for k, order in orders(caps[i], durs[i], durs[i - 1]).items():
                b, t, s = simulate(
                    durs[i],
                    order,
                    devices=a.devices,
                    lanes=lanes,
                    drain=drain,
                    chunk_s=a.chunk_s,
                    cost=a.chunk_cost,
                )
                acc = totals.setdefault(k, [0, 0, 0.0])
                acc[0] += b
                acc[1] += t
                acc[2] += s
        base = base or totals["cap"][2]
        for k, (b, t, s) in totals.items():
            print(
                f"{lanes:3d} lanes, drain {str(drain):10} {k:>13}: utilisation {b / t:.3f}, "
                f"modelled wall {s:7.1f} s ({s / base:.3f} x the first cap row)"
            )


if __name__ == "__main__":
    main()
