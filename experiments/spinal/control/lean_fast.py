"""A speed-controlled 3FBL with the lean speed regulator, asked to walk faster than it does.

Wraps the model of a spinal preset (default ``3fbl_auto_anchored``) with
:func:`jaxgait.control.speed_lean.speed_regulated` (v_reg = the target), holds the target
command at each of ``--targets`` and rolls each setting of (k_vp, k_vi) out for 30 s on flat
ground, printing how long it walked and its speed over the last 10 s
(experiments/spinal/README.md, "A speed regulator on the trunk lean").  Usage::

    ./jg python experiments/spinal/control/lean_fast.py [PRESET] --targets 1.7,1.8
"""

import argparse
import itertools

import jax
import jax.numpy as jnp
import numpy as np

from jaxgait import models, sim
from jaxgait.control import commands as cmd
from jaxgait.control.speed_lean import speed_regulated
from jaxgait.presets import load_preset
from jaxgait.world import envs


def floats(s):
    return [float(x) for x in s.split(",")]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("preset", nargs="?", default="3fbl_auto_anchored")
    ap.add_argument("--targets", type=floats, default=[1.7, 1.8])
    ap.add_argument("--k-vp", type=floats, default=[0.0, 0.05, 0.1])
    ap.add_argument("--k-vi", type=floats, default=[0.0, 0.02])
    ap.add_argument("--duration", type=float, default=30.0)
    a = ap.parse_args(argv)

    name, vec, doc = load_preset(a.preset)
    ctrl = speed_regulated(models.get_model(name).controller, name + "_sr")
    models.register(models.planar_spec(ctrl), replace=True)
    cfg = sim.SimConfig(duration=a.duration, v0=doc.get("v0") or sim.SimConfig.v0)
    env = envs.make_env("flat", jax.random.PRNGKey(0))
    f = sim.make_rollout(models.get_model(ctrl.name), cfg, batched=False)
    last = int(round(10.0 / cfg.log_dt))
    for target, kvp, kvi in itertools.product(a.targets, a.k_vp, a.k_vi):
        full = np.concatenate([np.asarray(vec, float), [target, kvp, kvi, 1.0, 2.0]])
        ctrl.table.check(full, f"target {target}, k_vp {kvp}, k_vi {kvi}")
        schedule = cmd.constant(ctrl.commands, v_target=target)
        trace, _, summary, _ = f(jnp.asarray(full, jnp.float32), env, schedule)
        n = int(np.asarray(trace.alive).sum())
        v = float(np.asarray(trace.com_vel[:, 0])[max(0, n - last) : n].mean())
        print(
            f"target {target} k_vp {kvp} k_vi {kvi}: walks {float(summary.duration):.1f} s, "
            f"{v:.3f} m/s over its last 10 s",
            flush=True,
        )


if __name__ == "__main__":
    main()
