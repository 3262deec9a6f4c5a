"""Throughput and memory of the FBL model step (a benchmark, not a test).

For each batch size it measures, each case in its own subprocess (so peak memory is its own):

* ``full``: the whole jaxgait step (MJX multibody, Geyer contact and soft limits resolved
  linearly-implicitly, 14 muscle-tendon units, reflex controller with delay lines, metabolic
  energy), ``vmap`` over the batch, ``lax.scan`` over time, one ``jit``;
* ``mjx``: MJX physics alone on the same MJCF (``mjx.step``, constraint solver off);
* ``c``: MuJoCo's native C rollout (``mujoco.rollout``, one thread per core) of the same MJCF.

It prints env-steps/s, the real-time factor (simulated seconds per wall second, summed over
the batch) and the peak resident memory, then the ratios full/mjx and full/C measured in the
same run.  Usage::

    python benchmarks/throughput.py                   # batches 1 64 512 4096
    python benchmarks/throughput.py --batches 64 512 --steps 400
    python benchmarks/throughput.py --breakdown 512   # where the time goes, part by part
    python benchmarks/throughput.py --profile 512     # an XLA trace for TensorBoard/Perfetto
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import subprocess
import sys
import time


def _peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _setup(batch: int, dynamics: str = "mjx"):
    """(model, cfg, params, env, initial states) of ``batch`` FBL walkers on flat ground that
    never stop (no fall or time criterion ends the benchmark's rollouts); ``dynamics`` is
    :attr:`jaxgait.sim.SimConfig.dynamics`."""
    import jax
    import jax.numpy as jnp

    from jaxgait import models, sim
    from jaxgait.world import envs

    model = models.get_model("fbl")
    cfg = sim.SimConfig(duration=1e6, fall_hip_height=-1e3, fall_pitch=1e3, dynamics=dynamics)
    keys = jax.random.split(jax.random.PRNGKey(0), batch)
    env = envs.make_env_batch("flat", keys)
    params = jnp.broadcast_to(jnp.asarray(model.table.init, jnp.float32), (batch, model.table.size))
    s0 = jax.vmap(lambda p, e: sim.initial_state(model, p, e, cfg))(params, env)
    return model, cfg, params, env, s0


def _full_program(model, cfg, steps: int):
    """``steps`` full steps of a batch: (states, params, envs) -> states.  Parameters and
    environments are arguments, not constants folded into the program."""
    import jax

    from jaxgait import sim

    def run(a):
        s, p, e = a
        f = jax.vmap(lambda p, e, s: sim.step(model, cfg, p, e, s))
        return jax.lax.scan(lambda s, _: (f(p, e, s), None), s, None, length=steps)[0]

    return run


def _mjx_program(model, fn, steps: int):
    """``steps`` calls of an MJX function (``mjx.step``, ``mjx.forward``) on a batch of data."""
    import jax

    def run(d):
        f = jax.vmap(lambda d: fn(model.mjx_model, d))
        return jax.lax.scan(lambda d, _: (f(d), None), d, None, length=steps)[0]

    return run


def _mjx_data(model, s0):
    import jax

    return jax.vmap(lambda q, v: model._template.replace(qpos=q, qvel=v))(s0.qpos, s0.qvel)


def _best_seconds(run, arg, repeats: int) -> float:
    """Shortest of ``repeats`` timed calls of ``run(arg)`` (blocking until ready)."""
    import jax

    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(run(arg))
        best = min(best, time.perf_counter() - t0)
    return best


def run_case(kind: str, batch: int, steps: int, repeats: int) -> dict:
    import jax
    import numpy as np

    extra = {}
    if kind == "c":
        import mujoco
        from mujoco import rollout

        from jaxgait import models

        model = models.get_model("fbl")
        m = model.body.mj_model
        d = mujoco.MjData(m)
        nthread = os.cpu_count() or 1
        datas = [mujoco.MjData(m) for _ in range(nthread)]
        state = np.zeros((batch, mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
        d.qpos[1] = 0.1
        d.qvel[0] = 1.3
        mujoco.mj_getState(m, d, state[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
        state[:] = state[0]
        run, arg = (lambda st: rollout.rollout(m, datas, st, nstep=steps)), state
        extra["threads"] = nthread
    else:
        model, cfg, params, env, s0 = _setup(batch)
        if kind == "full":
            run, arg = _full_program(model, cfg, steps), (s0, params, env)
        elif kind == "mjx":
            from mujoco import mjx

            run, arg = _mjx_program(model, mjx.step, steps), _mjx_data(model, s0)
        else:
            raise ValueError(kind)
        run = jax.jit(run)
    t0 = time.perf_counter()
    jax.block_until_ready(run(arg))  # compiles (jax) or warms up the thread pool (C)
    extra["compile_s" if kind != "c" else "warmup_s"] = time.perf_counter() - t0
    best = _best_seconds(run, arg, repeats)
    return {
        "kind": kind,
        "batch": batch,
        "seconds": best,
        "steps": steps,
        "env_steps_per_s": batch * steps / best,
        "rtf": batch * steps * model.dt / best,
        "peak_mib": _peak_mib(),
        **extra,
    }


@contextlib.contextmanager
def _swapped(obj, attr, value):
    old = getattr(obj, attr)
    setattr(obj, attr, value)
    try:
        yield
    finally:
        setattr(obj, attr, old)


def breakdown(batch: int, steps: int, repeats: int) -> list[dict]:
    """Where the time goes: the full step next to variants with one part removed or alone.

    Ablations swap one function of the step (e.g. ``muscle.muscle_step``) while their variant
    is traced.  All variants run in this one process, interleaved, so their ratios are
    comparable.
    """
    import dataclasses
    from functools import partial

    import jax
    import jax.numpy as jnp
    from mujoco import mjx

    from jaxgait.muscles import energy
    from jaxgait.muscles import mtu as muscle

    model, cfg, params, env, s0 = _setup(batch)

    def scan_step(m, c=cfg):
        return _full_program(m, c, steps)

    def const_law(p, s):
        return jnp.full(s.shape[:-1] + (7,), 0.05, s.dtype)  # one row per (delayed) leg

    explicit = partial(muscle.muscle_step, implicit=False)
    compiled = {}

    def add(name, fn, arg, *swaps):
        """Compile one variant; ``swaps`` (module, attribute, value) hold while it is traced."""
        with contextlib.ExitStack() as stack:
            for obj, attr, value in swaps:
                stack.enter_context(_swapped(obj, attr, value))
            compiled[name] = (jax.jit(fn).lower(arg).compile(), arg)

    full = (s0, params, env)
    add("full step", scan_step(model), full)
    ctrl = model.controller
    const_ctrl = dataclasses.replace(
        ctrl, settings=dataclasses.replace(ctrl.settings, law=const_law)
    )
    add(
        "no reflex law (constant stim)",
        scan_step(dataclasses.replace(model, controller=const_ctrl)),
        full,
    )
    more = cfg.ce_solve_iters + 1
    add(
        f"full step, CE solve with {more} iterations (default {cfg.ce_solve_iters})",
        scan_step(model, dataclasses.replace(cfg, ce_solve_iters=more)),
        full,
    )
    add("full step, explicit CE", scan_step(model), full, (muscle, "muscle_step", explicit))
    add(
        "full step without metabolic energy",
        scan_step(model),
        full,
        (energy, "metabolic_rate", lambda table, stim, *a: jnp.zeros_like(stim)),
    )
    d0 = _mjx_data(model, s0)
    add("mjx.step alone", _mjx_program(model, mjx.step, steps), d0)
    add("mjx.forward alone", _mjx_program(model, mjx.forward, steps), d0)

    def mass_and_forces_only(a):
        def body(c, _):
            q, v = c
            M, f = jax.vmap(model.mass_and_forces)(q, v, jnp.zeros_like(v))
            return (q + 1e-6 * f, v + 1e-6 * M[:, 0]), None

        return jax.lax.scan(body, a, None, length=steps)[0]

    add("MJX M and bias forces alone (step's part)", mass_and_forces_only, (s0.qpos, s0.qvel))

    def muscles_alone(step_fn):
        def run(ms):
            lm = ms.l_ce + jnp.asarray(model.muscles.l_slack)

            def one(m):
                return step_fn(model.muscles, m, m.act * 0 + 0.3, lm[0], model.dt)[0]

            f = jax.vmap(one)
            return jax.lax.scan(lambda m, _: (f(m), None), ms, None, length=steps)[0]

        return run

    add("muscle_step alone (implicit)", muscles_alone(muscle.muscle_step), s0.muscle)
    add("muscle_step alone (explicit)", muscles_alone(explicit), s0.muscle)
    for f, a in compiled.values():
        jax.block_until_ready(f(a))
    best = {k: float("inf") for k in compiled}
    for _ in range(repeats):  # interleaved: one timed call of every variant per round
        for k, (f, a) in compiled.items():
            best[k] = min(best[k], _best_seconds(f, a, 1))
    full = best["full step"]
    rows = []
    for k, t in best.items():
        rows.append(
            {
                "variant": k,
                "us_per_env_step": 1e6 * t / (batch * steps),
                "fraction_of_full": t / full,
            }
        )
        print(f"{k:34s} {1e6 * t / (batch * steps):8.2f} us/env-step   {t / full:6.2f} x full")
    return rows


def profile(batch: int, steps: int, out: str) -> None:
    """Write an XLA/TensorBoard trace of the full step (open with tensorboard or perfetto)."""
    import jax

    run_case("full", batch, steps, 1)
    jax.profiler.start_trace(out)
    run_case("full", batch, steps, 1)
    jax.profiler.stop_trace()
    print(f"trace written to {out}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 64, 512, 4096])
    ap.add_argument("--steps", type=int, default=200, help="physics steps per timed run")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--kinds", nargs="+", default=["full", "mjx", "c"])
    ap.add_argument("--one", nargs=2, metavar=("KIND", "BATCH"), help=argparse.SUPPRESS)
    ap.add_argument("--profile", type=int, metavar="BATCH")
    ap.add_argument("--breakdown", type=int, metavar="BATCH", help="time per part of the step")
    ap.add_argument("--json", action="store_true")
    ap.add_argument(
        "--timeout", type=float, default=900.0, help="seconds allowed per case (default 900)"
    )
    a = ap.parse_args(argv)
    if a.one:
        print(json.dumps(run_case(a.one[0], int(a.one[1]), a.steps, a.repeats)))
        return
    if a.breakdown:
        breakdown(a.breakdown, a.steps, a.repeats)
        return
    if a.profile:
        profile(a.profile, a.steps, "benchmarks/profile")
        return
    rows = []
    for b in a.batches:
        for k in a.kinds:
            cmd = [sys.executable, __file__, "--one", k, str(b)]
            cmd += ["--steps", str(a.steps), "--repeats", str(a.repeats)]
            try:
                out = subprocess.run(cmd, capture_output=True, text=True, timeout=a.timeout)
            except subprocess.TimeoutExpired:
                rows.append({"kind": k, "batch": b, "error": [f"no result in {a.timeout} s"]})
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
                continue
            line = [x for x in out.stdout.splitlines() if x.startswith("{")]
            if out.returncode != 0 or not line:
                rows.append({"kind": k, "batch": b, "error": out.stderr.strip().splitlines()[-1:]})
            else:
                rows.append(json.loads(line[-1]))
            print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    if a.json:
        print(json.dumps(rows, indent=1))
        return
    print(f"{'batch':>6} {'case':>5} {'env-steps/s':>12} {'RTF':>10} {'peak MiB':>9}")
    by = {(r["kind"], r["batch"]): r for r in rows if "error" not in r}
    for r in rows:
        if "error" in r:
            print(f"{r['batch']:>6} {r['kind']:>5}  failed: {r['error']}")
            continue
        print(
            f"{r['batch']:>6} {r['kind']:>5} {r['env_steps_per_s']:>12,.0f} {r['rtf']:>10.1f} "
            f"{r['peak_mib']:>9.0f}"
        )
    print("\nratios (same run):")
    for b in a.batches:
        f, m, c = by.get(("full", b)), by.get(("mjx", b)), by.get(("c", b))
        parts = [f"batch {b:>5}:"]
        if f and m:
            parts.append(f"full/mjx = {f['env_steps_per_s'] / m['env_steps_per_s']:.2f}")
        if f and c:
            parts.append(f"full/C = {f['env_steps_per_s'] / c['env_steps_per_s']:.3f}")
        print("  ".join(parts))


if __name__ == "__main__":
    main()
