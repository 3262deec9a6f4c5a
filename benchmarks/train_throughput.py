"""Training throughput: what a generation realises of the step's own speed, and the wall time
of the thesis experiments at full size.

For an experiment (default ``exp3``, 60 particles) it runs a few iterations through
:func:`jaxgait.train.train` and prints, per iteration after the first (which compiles):
wall time, rollouts/s, lane utilisation (busy lane-steps / all lane-steps of the scheduled
evaluation, :mod:`jaxgait.sim.lanes`) and the realised env-steps/s (busy lane-steps / wall
time).  Next to them it times the bare step at the same lane count (``steps`` steps of a
batch of walkers that never stop), and extrapolates the wall time of the full run
(``--full-iterations``, 150 by default) from the mean iteration time::

    ./jg python benchmarks/train_throughput.py exp3 --iterations 4
    ./jg python benchmarks/train_throughput.py exp3 --iterations 4 --lanes 16   # queued
    ./jg python benchmarks/train_throughput.py exp3 --compare-queue 60 20 12   # direct vs queued
    ./jg python benchmarks/train_throughput.py exp3 --compare-queue 12 --chunk-s 1 0.25

    ./jg python benchmarks/train_throughput.py exp3 --compare-devices 1 2     # host devices

    ./jg python benchmarks/train_throughput.py --history runs/full/exp3/history.csv --lanes 16

The extrapolation is an estimate (later iterations of a stage search walk further, so they
take longer than the first ones); a full run measures the real figure.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path


def step_throughput(
    lanes: int, steps: int = 200, repeats: int = 3, dynamics: str = "planar"
) -> float:
    """env-steps/s of the bare FBL step at ``lanes`` per device on every device of this
    process (best of ``repeats``; ``shard_map`` over the devices), measured with the setup
    and program of ``benchmarks/throughput.py``, with the training's ``dynamics``."""
    import jax
    import numpy as np
    from jax.sharding import Mesh, NamedSharding, PartitionSpec
    from throughput import _best_seconds, _full_program, _setup

    devices = jax.devices()
    n = lanes * len(devices)
    model, cfg, params, env, s0 = _setup(n, dynamics)
    program = _full_program(model, cfg, steps)
    arg = (s0, params, env)
    if len(devices) > 1:
        mesh = Mesh(np.array(devices), ("pop",))
        spec = PartitionSpec("pop")
        program = jax.shard_map(
            program, mesh=mesh, in_specs=(spec,), out_specs=spec, check_vma=False
        )
        arg = jax.device_put(arg, NamedSharding(mesh, spec))
    f = jax.jit(program)
    jax.block_until_ready(f(arg))
    return n * steps / _best_seconds(f, arg, repeats)


def _perturbed_generation(exp, table):
    """(population, keys) of one generation of ``exp``: ``fbl_walk`` perturbed by up to 5 %
    per parameter (seed 0), clipped to ``table``'s ranges, and fresh environment keys."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxgait import presets

    _, vec, _ = presets.load_preset("fbl_walk")
    n = exp.particles * exp.worst_of_k
    pop = vec * (1 + 0.05 * np.random.default_rng(0).uniform(-1, 1, (n, vec.size)))
    pop = jnp.asarray(np.clip(pop, table.lower, table.upper), jnp.float32)
    return pop, jax.random.split(jax.random.PRNGKey(1), n)


def compare_queue(
    name: str, particles: int | None, lane_counts, drains=None, chunks=None, repeats: int = 2
) -> int:
    """Direct calls against the queue over each lane count on one generation: wall time (the
    fastest of the ``repeats - 1`` calls after the first, which compiles),
    lane counts, and the candidates whose stage differs from the direct call's.  ``drains``:
    drain widths to compare for each lane count (e.g. ``[(), (4, 1)]``; default the
    evaluator's own); ``chunks``: the queue's chunk lengths [s] to compare (default
    :data:`~jaxgait.train.evaluator.QUEUE_CHUNK_S`)."""
    from jaxgait.train import PopulationEvaluator, get_experiment
    from jaxgait.train import evaluator as evaluator_mod

    exp = get_experiment(name, **({} if particles is None else {"particles": particles}))
    n = exp.particles * exp.worst_of_k
    pop, keys = _perturbed_generation(exp, PopulationEvaluator(exp).model.table)
    direct = None
    own, own_chunk = evaluator_mod.drain_widths, evaluator_mod.QUEUE_CHUNK_S
    cases = [("direct", exp.replace(lanes=0), None, own_chunk)]
    for k in lane_counts:
        for d in drains or [None]:
            widths = own(k) if d is None else tuple(w for w in d if w < k)
            label = f"queued over {k} lanes" + (f", drain {widths}" if widths else "")
            for c in chunks or [own_chunk]:
                text = label + (f", chunks {c:g} s" if chunks else "")
                cases.append((text, exp.replace(lanes=k), widths, c))
    for label, e, widths, c in cases:
        evaluator_mod.drain_widths = own if widths is None else (lambda lanes, w=widths: w)
        evaluator_mod.QUEUE_CHUNK_S = c
        try:
            ev = PopulationEvaluator(e)
        finally:
            evaluator_mod.drain_widths, evaluator_mod.QUEUE_CHUNK_S = own, own_chunk
        times = []
        for _ in range(max(repeats, 2)):  # the first call compiles
            t = time.perf_counter()
            stage, value, _ = ev.scores(pop, keys)
            times.append(time.perf_counter() - t)
        first, secs = times[0], min(times[1:])
        st = ev.last_stats
        direct = stage if direct is None else direct
        print(
            f"{label:52s} {secs:7.1f} s (first call {first:.1f} s)  "
            f"utilisation {float(st.utilisation):.3f}  "
            f"busy {int(st.busy):,}  total {int(st.total):,} lane-steps  "
            f"{int(st.busy) / secs:,.0f} busy lane-steps/s  "
            f"stage differs from direct: {int((stage != direct).sum())} of {n}",
            flush=True,
        )
    return 0


def one_generation(name: str, lanes: int | None, repeats: int = 3) -> None:
    """Time one generation of 5 %-perturbed ``fbl_walk`` candidates through the population
    evaluator of this process (its devices; ``lanes`` per device, default automatic), the
    first call (with compilation) and ``repeats - 1`` more."""
    import numpy as np

    from jaxgait.train import PopulationEvaluator, get_experiment

    exp = get_experiment(name, **({} if lanes is None else {"lanes": lanes}))
    ev = PopulationEvaluator(exp)
    pop, keys = _perturbed_generation(exp, ev.model.table)
    for r in range(repeats):
        t = time.perf_counter()
        stage, _, _ = ev.scores(pop, keys)
        secs = time.perf_counter() - t
        st = ev.last_stats
        print(
            f"{ev.n_devices} device(s) x {ev.lanes or ev.rows // ev.n_devices} lanes"
            f"{' (direct)' if ev.lanes is None else f', drain {ev.drain}'}: "
            f"{'compile + ' if r == 0 else ''}generation {secs:6.1f} s, utilisation "
            f"{float(st.utilisation):.3f}, {int(st.busy) / secs:,.0f} busy lane-steps/s, "
            f"stages {np.bincount(stage).tolist()}",
            flush=True,
        )


def compare_devices(name: str, counts, lanes: int | None) -> int:
    """:func:`one_generation` in one subprocess per host device count (XLA's flag must be
    set before JAX starts), one after the other."""
    import os
    import subprocess
    import sys

    for n in counts:
        env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={n}")
        cmd = [sys.executable, __file__, name, "--one-generation"]
        cmd += [] if lanes is None else ["--lanes", str(lanes)]
        subprocess.run(cmd, env=env, check=True)
    return 0


#: Full-size targets of the thesis experiments on this 2-core CPU [min] (issue 13).
TARGETS_MIN = {"exp3": 20.0, "exp7a": 120.0}


def from_history(path: Path, lanes: int | None, bare_rounds: int = 3) -> int:
    """The figures of a finished (or running) run from its ``history.csv``: total wall time
    against the target, lane utilisation, and the realised env-steps/s against the bare step
    at the run's lane count (``bare_rounds`` rounds, best of 3 calls each)."""
    import csv
    import json

    rows = list(csv.DictReader(open(path)))
    if not rows:
        print(f"{path}: no iterations yet")
        return 1
    cfg = json.loads((path.parent / "config.json").read_text())["experiment"]
    name = cfg["name"]
    secs = [float(r["seconds"]) for r in rows]
    busy = [float(r["env_steps_per_s"]) * float(r["seconds"]) for r in rows]
    util = [float(r["lane_utilisation"]) for r in rows]
    total = sum(secs)
    n, full = len(rows), int(cfg["iterations"])
    print(f"{name}: {n}/{full} iterations of {cfg['particles']} x {cfg['worst_of_k']} rollouts")
    print(f"  wall time {total / 60:.1f} min (first iteration, with compilation, {secs[0]:.0f} s)")
    if n < full:
        est = total + (full - n) * sum(secs[1:] or secs) / max(len(secs) - 1, 1)
        print(f"  full run ~ {est / 60:.1f} min (extrapolated from the mean iteration)")
    else:
        est = total
    target = TARGETS_MIN.get(name)
    if target is not None:
        verdict = "met" if est / 60 <= target else f"missed by {est / 60 / target:.1f}x"
        print(f"  target {target:g} min: {verdict}")
    # utilisation over the run: busy lane-steps / all lane-steps (each row's busy / utilisation)
    u = sum(busy) / sum(b / max(x, 1e-9) for b, x in zip(busy, util, strict=True))
    print(f"  lane utilisation {100 * u:.1f} % of lane-steps (target 85 %)")
    realised = sum(busy[1:] or busy) / sum(secs[1:] or secs)
    print(f"  realised {realised:,.0f} env-steps/s (iterations after the first)")
    if lanes:
        import jax

        from jaxgait.presets import preset_dynamics

        dynamics = preset_dynamics(cfg)  # as the run's rollouts
        # the bare figure varies by 10-20 % from call to call on a shared machine: several
        # rounds, the ratio against the fastest (the step's own throughput) and the slowest
        rounds = [step_throughput(lanes, dynamics=dynamics) for _ in range(bare_rounds)]
        step = max(rounds)
        print(
            f"  bare step ({dynamics}) at {jax.device_count()} device(s) x {lanes} lanes, "
            f"{bare_rounds} round(s) of best of 3: "
            + " / ".join(f"{r:,.0f}" for r in rounds)
            + f" env-steps/s; realised / bare {realised / step:.2f} against the fastest"
            + (f", {realised / min(rounds):.2f} against the slowest" if bare_rounds > 1 else "")
            + " (target 0.80)"
        )
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("experiment", nargs="?", default="exp3")
    ap.add_argument("--iterations", type=int, default=4, help="iterations run (first compiles)")
    ap.add_argument("--particles", type=int, default=None, help="default: the experiment's")
    ap.add_argument("--lanes", type=int, default=None, help="queue over this many lanes per device")
    ap.add_argument("--full-iterations", type=int, default=150)
    ap.add_argument(
        "--compare-queue",
        type=int,
        nargs="+",
        metavar="LANES",
        help="instead: time one generation of perturbed fbl_walk candidates in direct calls "
        "and queued over each LANES count (the fastest call after the first of each; --repeats)",
    )
    ap.add_argument(
        "--history",
        type=Path,
        metavar="CSV",
        help="instead: the figures of a run from its history.csv (e.g. "
        "runs/full/exp3/history.csv) against the full-size targets; with --lanes also the "
        "bare step at that lane count",
    )
    ap.add_argument(
        "--drain",
        nargs="+",
        metavar="WIDTHS",
        help="with --compare-queue: drain widths to compare, comma-separated per case "
        "('none' for no drain), e.g. --drain none 4,1 8,4,2,1",
    )
    ap.add_argument(
        "--chunk-s",
        type=float,
        nargs="+",
        metavar="S",
        help="with --compare-queue: the queue's chunk lengths [s] to compare, e.g. "
        "--chunk-s 1 0.5 0.25",
    )
    ap.add_argument(
        "--compare-devices",
        type=int,
        nargs="+",
        metavar="N",
        help="instead: one generation of perturbed fbl_walk candidates with the host as N "
        "XLA devices (one subprocess each; --lanes per device, default automatic)",
    )
    ap.add_argument(
        "--bare-rounds",
        type=int,
        default=3,
        help="with --history and --lanes: rounds of timing the bare step (each best of 3)",
    )
    ap.add_argument(
        "--repeats",
        type=int,
        default=2,
        help="with --compare-queue: calls per case (the first compiles; the fastest of the "
        "others is printed)",
    )
    ap.add_argument("--one-generation", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if not a.one_generation:  # as the training command: one host device per core
        from jaxgait.core import host_devices

        host_devices.use_cpu_cores()
    if a.one_generation:
        one_generation(a.experiment, a.lanes)
        return 0
    if a.compare_devices:
        return compare_devices(a.experiment, a.compare_devices, a.lanes)
    if a.history:
        return from_history(a.history, a.lanes, a.bare_rounds)
    if a.compare_queue:
        drains = None
        if a.drain:
            drains = [() if d == "none" else tuple(int(w) for w in d.split(",")) for d in a.drain]
        return compare_queue(
            a.experiment, a.particles, a.compare_queue, drains, a.chunk_s, a.repeats
        )

    from jaxgait.train import get_experiment, train
    from jaxgait.train.evaluator import PopulationEvaluator

    over = {"iterations": max(a.iterations, 2)}
    if a.particles is not None:
        over["particles"] = a.particles
    if a.lanes is not None:
        over["lanes"] = a.lanes
    exp = get_experiment(a.experiment, **over)
    ev = PopulationEvaluator(exp)
    lanes = ev.lanes if ev.lanes is not None else ev.rows // ev.n_devices
    mode = "queued" if ev.lanes is not None else "direct calls"
    with tempfile.TemporaryDirectory() as tmp:
        res = train(exp, Path(tmp) / "run", progress=print, plots=False)
    rows = res.history[1:]  # the first iteration compiles
    print(
        f"\n{exp.name}: {exp.particles} x {exp.worst_of_k} rollouts of <= {exp.duration:g} s, "
        f"{lanes} lanes per device ({mode})"
    )
    print("iteration   wall s   rollouts/s   utilisation   realised env-steps/s")
    for r in rows:
        print(
            f"{r['iteration']:9d} {r['seconds']:8.1f} {r['rollouts_per_s']:12.2f} "
            f"{100 * r['lane_utilisation']:12.1f}% {r['env_steps_per_s']:16,.0f}"
        )
    mean = sum(r["seconds"] for r in rows) / len(rows)
    realised = sum(r["env_steps_per_s"] * r["seconds"] for r in rows) / (mean * len(rows))
    step = step_throughput(lanes, dynamics=exp.dynamics)
    print(
        f"\nbare step ({exp.dynamics}) at {ev.n_devices} device(s) x {lanes} lanes: "
        f"{step:,.0f} env-steps/s"
    )
    print(f"realised / bare step: {realised / step:.2f}")
    print(
        f"mean iteration {mean:.1f} s -> {a.full_iterations} iterations ~ "
        f"{mean * a.full_iterations / 60:.1f} min (extrapolated from {len(rows)} iterations)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
